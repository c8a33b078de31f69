"""Shot sampling has the statistics of measuring the circuit."""

from __future__ import annotations

import numpy as np
import pytest

from qdcnn.errors import ParameterError
from qdcnn.quantum import sampling
from qdcnn.quantum.circuits import uu_dagger_circuit, vqc_circuit
from qdcnn.quantum.execute import run_probabilities
from qdcnn.quantum.sampling import (
    MAX_TABLE_SHOTS,
    binomial_at_most,
    binomial_counts,
    inverse_binomial,
    sample_counts,
)
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


# --- binomial_counts: the faster one-qubit sampler of the shadow detector ---------------------
#
# Each chi-square test below is deterministic (fixed seeds); it passes at a significance level
# of 1e-4, so a correct sampler fails one of them with probability of order 1e-4 per seed.

ALPHA = 1e-4


def _pooled(observed: np.ndarray, expected: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cells with an expected count of at least 5, the rest pooled into one cell."""
    keep = expected >= 5
    obs = np.append(observed[keep], observed[~keep].sum())
    exp = np.append(expected[keep], expected[~keep].sum())
    if exp[-1] < 5:  # fold a thin pooled tail into the largest cell
        big = int(np.argmax(exp[:-1]))
        obs[big] += obs[-1]
        exp[big] += exp[-1]
        obs, exp = obs[:-1], exp[:-1]
    return obs, exp * (obs.sum() / exp.sum())


@pytest.mark.parametrize("p", [2e-4, 0.004, 0.03, 0.2, 0.37, 0.4999, 0.5, 0.81, 0.9993])
def test_binomial_counts_follow_the_binomial_distribution(p: float) -> None:
    from scipy.stats import binom, chisquare

    n = 200_000
    counts = binomial_counts(np.full(n, p), 1024, 11)
    expected = binom.pmf(np.arange(1025), 1024, p) * n
    obs, exp = _pooled(np.bincount(counts, minlength=1025).astype(float), expected)
    assert chisquare(obs, exp).pvalue > ALPHA


def test_binomial_counts_agree_with_numpy_binomial(rng: np.random.Generator) -> None:
    from scipy.stats import chi2_contingency

    p = rng.uniform(0, 1, 50)  # a spread of probabilities, as in one frame's blocks
    ours = binomial_counts(np.repeat(p, 2000), 1024, 5).reshape(50, 2000)
    theirs = np.random.default_rng(6).binomial(1024, np.repeat(p, 2000)).reshape(50, 2000)
    for a, b in zip(ours, theirs, strict=True):
        lo, hi = min(a.min(), b.min()), max(a.max(), b.max())
        edges = np.unique(np.quantile(np.concatenate([a, b]), np.linspace(0, 1, 16)))
        if edges.size < 3:
            edges = np.arange(lo, hi + 2)
        table = np.stack([np.histogram(a, edges)[0], np.histogram(b, edges)[0]])
        table = table[:, table.sum(axis=0) > 0]
        assert chi2_contingency(table).pvalue > ALPHA / 50  # Bonferroni over the 50 rows
    # and the totals over all circuits: mean and variance of the standardised counts
    z = (ours.mean(axis=1) - 1024 * p) / np.sqrt(1024 * p * (1 - p) / 2000)
    assert (np.abs(z) < 5).all()


def test_binomial_counts_agree_with_aer_counts() -> None:
    """Aer measures one UU-dagger circuit 1024 x 500 times (its shot memory cut into 500
    runs of 1024 shots); the counts of outcome 1 have the distribution of ours."""
    aer = pytest.importorskip("qiskit_aer")
    from scipy.stats import chi2_contingency

    from qdcnn.quantum.qiskit_bridge import to_qiskit

    runs = 500
    for theta_x, seed in ((0.9, 1), (2.2, 2)):
        circuit = uu_dagger_circuit(1.3, np.array([theta_x]))
        p1 = probabilities(circuit)[0, 1]
        qc = to_qiskit(circuit, 0)
        qc.measure_all()
        job = aer.AerSimulator().run(qc, shots=1024 * runs, memory=True, seed_simulator=seed)
        ones = np.array([bit[-1] == "1" for bit in job.result().get_memory()])
        theirs = ones.reshape(runs, 1024).sum(axis=1)
        ours = binomial_counts(np.full(runs, p1), 1024, seed)
        edges = np.unique(np.quantile(np.concatenate([theirs, ours]), np.linspace(0, 1, 9)))
        table = np.stack([np.histogram(theirs, edges)[0], np.histogram(ours, edges)[0]])
        assert chi2_contingency(table[:, table.sum(axis=0) > 0]).pvalue > ALPHA


def test_binomial_counts_edges_and_reproducibility() -> None:
    p = np.array([0.0, 1.0, 0.5, 1e-9, 1 - 1e-9])
    counts = binomial_counts(p, 1024, 3)
    assert counts[0] == 0 and counts[1] == 1024
    assert counts.dtype == np.int64 and ((counts >= 0) & (counts <= 1024)).all()
    np.testing.assert_array_equal(counts, binomial_counts(p, 1024, 3))
    assert binomial_counts(np.array([0.3]), 1, 0)[0] in (0, 1)
    big = binomial_counts(np.full(20_000, 0.25), MAX_TABLE_SHOTS + 1, 0)  # numpy's sampler
    assert abs(big.mean() / (MAX_TABLE_SHOTS + 1) - 0.25) < 0.002
    with pytest.raises(ParameterError, match="shots"):
        binomial_counts(p, 0, 0)


def test_alias_tables_hold_the_binomial_probabilities() -> None:
    """Each row's alias table gives every count of its window the binomial probability."""
    from scipy.stats import binom

    shots = 64
    start, width, shift, table = sampling._alias_tables(shots)
    for j in (0, 1, 7, 100, sampling._GRID // 4, sampling._GRID // 2):
        lo, w = int(start[j]), int(width[j])
        cells = np.arange(lo, lo + w)
        alias = np.floor(table[cells]).astype(np.intp)
        keep = table[cells] - alias
        assert ((keep >= 0) & (keep < 1)).all()
        prob = np.zeros(shots + 1)
        np.add.at(prob, cells + shift[j], keep / w)
        np.add.at(prob, alias, (1.0 - keep) / w)
        np.testing.assert_allclose(
            prob, binom.pmf(np.arange(shots + 1), shots, j / sampling._GRID), atol=1e-12
        )


# --- inverse-CDF sampling: one uniform per circuit, decisions without the counts -----------


def test_binomial_at_most_is_u_below_the_binomial_cdf(rng: np.random.Generator) -> None:
    from scipy.special import bdtr

    p = np.concatenate([rng.uniform(0, 0.1, 100_000), rng.uniform(0, 1, 20_000), [0.0, 1.0]])
    u = rng.random(p.size)
    for limit in (0, 30, 500, 1023):
        np.testing.assert_array_equal(
            binomial_at_most(p, 1024, limit, u), u <= bdtr(limit, 1024, p)
        )
    assert not binomial_at_most(p, 1024, -1, u).any()
    assert binomial_at_most(p, 1024, 1024, u).all()


def test_settling_decides_by_the_cdf_and_says_whether_a_decision_changed(
    rng: np.random.Generator,
) -> None:
    """The circuits between the brackets get ``u <= F(limit; p)`` (``p`` clipped to
    ``[0, 1]``, as a score a rounding above 1 gives); the answer is whether any of their
    decisions in ``passed`` changed, and the others are left alone."""
    from scipy.special import bdtr

    p = np.concatenate([rng.uniform(0.0, 0.06, 20), [-1e-16, 1.0 + 1e-16]])
    u = rng.random(p.size)
    truth = u <= bdtr(40, 1024, np.clip(p, 0.0, 1.0))
    unsure = np.array([0, 3, 7, 20, 21])
    others = np.setdiff1d(np.arange(p.size), unsure)
    for start in (truth.copy(), ~truth):
        passed = start.copy()
        changed = sampling.settle_between_brackets(passed, unsure, p, u, 1024, 40)
        np.testing.assert_array_equal(passed[unsure], truth[unsure])
        np.testing.assert_array_equal(passed[others], start[others])
        assert isinstance(changed, bool)
        assert changed == (not np.array_equal(start[unsure], truth[unsure]))
    assert sampling.settle_between_brackets(passed, unsure[:0], p, u, 1024, 40) is False


@pytest.mark.parametrize("p", [0.0, 2e-4, 0.03, 0.37, 0.5, 0.9993, 1.0])
def test_inverse_binomial_follows_the_binomial_distribution(p: float) -> None:
    from scipy.stats import binom, chisquare

    n = 100_000
    counts = inverse_binomial(np.full(n, p), 1024, np.random.default_rng(8).random(n))
    if p in (0.0, 1.0):
        assert (counts == 1024 * p).all()
        return
    expected = binom.pmf(np.arange(1025), 1024, p) * n
    obs, exp = _pooled(np.bincount(counts, minlength=1025).astype(float), expected)
    assert chisquare(obs, exp).pvalue > ALPHA


def test_inverse_binomial_is_the_count_binomial_at_most_decides(rng: np.random.Generator) -> None:
    p = rng.uniform(0, 0.1, 20_000)
    u = rng.random(p.size)
    counts = inverse_binomial(p, 1024, u)
    for limit in (10, 30, 60):
        np.testing.assert_array_equal(counts <= limit, binomial_at_most(p, 1024, limit, u))
    assert inverse_binomial(np.array([0.3]), 1024, np.array([0.0]))[0] == 0
