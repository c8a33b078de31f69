"""Shot sampling has the statistics of measuring the circuit."""

from __future__ import annotations

import numpy as np
import pytest

from qdcnn.errors import ParameterError
from qdcnn.quantum.circuits import uu_dagger_circuit, vqc_circuit
from qdcnn.quantum.execute import run_probabilities
from qdcnn.quantum.sampling import sample_counts
from qdcnn.quantum.simulator import probabilities


def z_scores(freq: np.ndarray, p: np.ndarray, shots: int) -> np.ndarray:
    """Standardised errors where the normal approximation holds (n p (1 - p) >= 5)."""
    var = p * (1 - p) / shots
    ok = var * shots * shots >= 5
    return (freq[ok] - p[ok]) / np.sqrt(var[ok])


def test_one_qubit_frequencies_within_4_sigma_and_binomial_variance(
    rng: np.random.Generator,
) -> None:
    p = probabilities(uu_dagger_circuit(1.1, rng.uniform(0, np.pi, 4000)))
    counts = sample_counts(p, 1024, rng)
    assert (counts.sum(axis=1) == 1024).all()
    z = z_scores(counts[:, 0] / 1024, p[:, 0], 1024)
    assert z.size > 3000
    assert (np.abs(z) < 4).all()
    # binomial statistics: standardised errors have mean 0 and variance 1
    assert abs(z.mean()) < 0.1
    assert 0.9 < z.var() < 1.1


def test_two_qubit_frequencies_multinomial(rng: np.random.Generator) -> None:
    p = probabilities(vqc_circuit(rng.uniform(0, 3, (1000, 2)), rng.uniform(-3, 3, 4)))
    counts = sample_counts(p, 1024, rng)
    assert (counts.sum(axis=1) == 1024).all()
    z = z_scores(counts / 1024, p, 1024)
    assert (np.abs(z) < 4).all()
    assert 0.9 < z.var() < 1.1
    # rare outcomes (n p < 5): total counts agree with the expectation within 4 Poisson sigma
    rare = 1024 * p < 5
    expected_rare = 1024 * p[rare].sum()
    assert abs(counts[rare].sum() - expected_rare) < 4 * np.sqrt(expected_rare) + 1
    # multinomial: outcome counts are negatively correlated, cov = -n p_i p_j
    cov = np.mean((counts[:, 0] - 1024 * p[:, 0]) * (counts[:, 1] - 1024 * p[:, 1]))
    expected = np.mean(-1024 * p[:, 0] * p[:, 1])
    assert abs(cov - expected) < 0.15 * abs(expected)


def test_seeded_sampling_is_reproducible() -> None:
    p = probabilities(uu_dagger_circuit(0.3, np.linspace(0, 3, 50)))
    np.testing.assert_array_equal(sample_counts(p, 100, 7), sample_counts(p, 100, 7))


@pytest.mark.parametrize("shots", [0, -5, 1.5, True])
def test_bad_shots(shots: object) -> None:
    with pytest.raises(ParameterError, match="shots"):
        sample_counts(np.array([[0.5, 0.5]]), shots, 0)  # type: ignore[arg-type]


def test_aer_shots_within_4_sigma(rng: np.random.Generator) -> None:
    pytest.importorskip("qiskit_aer")
    circ = vqc_circuit(rng.uniform(0, 3, (40, 2)), rng.uniform(-3, 3, 4))
    exact = run_probabilities(circ)
    est = run_probabilities(circ, shots=2048, backend="aer", rng=3)
    z = z_scores(est, exact, 2048)
    assert (np.abs(z) < 4).all()


def test_numpy_and_aer_shot_estimates_agree(rng: np.random.Generator) -> None:
    pytest.importorskip("qiskit_aer")
    circ = uu_dagger_circuit(0.8, rng.uniform(0, np.pi, 30))
    a = run_probabilities(circ, shots=4096, backend="numpy", rng=1)
    b = run_probabilities(circ, shots=4096, backend="aer", rng=2)
    p = run_probabilities(circ)
    sigma = np.sqrt(2 * p * (1 - p) / 4096) + 1e-12
    assert (np.abs(a - b) < 4 * sigma + 1e-9).all()
