"""Noise channels are CPTP and the noisy simulator equals Qiskit Aer's density-matrix method."""

from __future__ import annotations

import numpy as np
import pytest

from qdcnn.errors import ParameterError
from qdcnn.quantum.circuits import uu_dagger_circuit, vqc_circuit
from qdcnn.quantum.gates import Z
from qdcnn.quantum.noise import CHANNELS, NoiseSpec, is_cptp, kraus_operators
from qdcnn.quantum.noise_text import parse_noise
from qdcnn.quantum.simulator import density_matrix, probabilities

STRENGTHS = [0.0, 0.11, 0.5, 0.99, 1.0]


@pytest.mark.parametrize("channel", list(CHANNELS))
@pytest.mark.parametrize("p", STRENGTHS)
def test_channels_are_cptp(channel: str, p: float) -> None:
    ops = kraus_operators(channel, p)
    assert is_cptp(ops)
    # complete positivity: the Choi matrix is positive semidefinite
    choi = sum(
        np.kron(np.eye(2), k)
        @ np.outer(v := np.array([1, 0, 0, 1.0]), v)
        @ np.kron(np.eye(2), k).conj().T
        for k in ops
    )
    assert np.linalg.eigvalsh(choi).min() > -1e-12


def test_noisy_states_stay_valid(rng: np.random.Generator) -> None:
    circ = vqc_circuit(rng.uniform(0, 3, (20, 2)), rng.uniform(-3, 3, 4))
    for channel in CHANNELS:
        rho = density_matrix(circ, NoiseSpec(channel, 0.3))
        np.testing.assert_allclose(np.trace(rho, axis1=1, axis2=2), 1.0, atol=1e-12)
        np.testing.assert_allclose(rho, np.conj(np.swapaxes(rho, 1, 2)), atol=1e-12)
        assert np.linalg.eigvalsh(rho).min() > -1e-12


def test_known_answers_on_uu_circuit() -> None:
    tc, tx = 1.0, 0.2
    ideal = np.cos((tc - tx) / 2) ** 2
    circ = uu_dagger_circuit(tc, tx)
    # depolarizing after each of the two gates shrinks the Bloch vector by (1 - p) twice
    p = 0.3
    got = probabilities(circ, NoiseSpec("depolarizing", p))[0, 0]
    assert got == pytest.approx(0.5 + (1 - p) ** 2 * (ideal - 0.5), abs=1e-12)
    # phase-flip after RY gates: exact value from the Kraus sum, checked independently
    ops = kraus_operators("phase-flip", p)

    def ry(t: float) -> np.ndarray:
        return np.array([[np.cos(t / 2), -np.sin(t / 2)], [np.sin(t / 2), np.cos(t / 2)]])

    rho = np.diag([1.0, 0.0]).astype(complex)
    for u in (ry(tc), ry(-tx)):
        rho = u @ rho @ u.T
        rho = sum(k @ rho @ k.conj().T for k in ops)
    assert probabilities(circ, NoiseSpec("phase-flip", p))[0, 0] == pytest.approx(
        rho[0, 0].real, abs=1e-12
    )


def test_paper_phase_damping_applies_z_at_zero() -> None:
    ops = kraus_operators("phase-damping-paper", 0.0)
    np.testing.assert_allclose(ops[0], Z, atol=0)
    np.testing.assert_allclose(ops[1:], 0)


def test_readout_error_flips_bits() -> None:
    circ = uu_dagger_circuit(0.0, 0.0)  # |0> with certainty
    probs = probabilities(circ, NoiseSpec(readout=0.1))
    np.testing.assert_allclose(probs, [[0.9, 0.1]], atol=1e-12)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("bit-flip:1.5", "p=1.5 is invalid: a probability in [0, 1]"),
        ("bitflip:0.1", "channel='bitflip' is invalid"),
        ("depolarizing", "noise='depolarizing' is invalid"),
        ("depolarizing:abc", "noise='depolarizing:abc' is invalid"),
        ("readout:-0.1", "readout=-0.1 is invalid"),
    ],
)
def test_bad_noise_specs(text: str, message: str) -> None:
    with pytest.raises(ParameterError) as err:
        parse_noise(text)
    assert message in str(err.value)


def test_parse_noise_round_trip() -> None:
    spec = parse_noise("amplitude-damping:0.22,readout:0.01")
    assert spec == NoiseSpec("amplitude-damping", 0.22, 0.01)
    assert spec.label() == "amplitude-damping:0.22,readout:0.01"


@pytest.mark.parametrize("channel", list(CHANNELS))
def test_noisy_probabilities_match_aer_density_matrix(
    channel: str, rng: np.random.Generator
) -> None:
    pytest.importorskip("qiskit_aer")
    from qdcnn.quantum.qiskit_bridge import run_aer

    for p in (0.0, 0.11, 0.55, 0.99):
        spec = NoiseSpec(channel, p)
        vqc = vqc_circuit(rng.uniform(0, 3, (6, 2)), rng.uniform(-3, 3, 4))
        uu = uu_dagger_circuit(rng.uniform(0, np.pi), rng.uniform(0, np.pi, 6))
        for circ in (vqc, uu):
            np.testing.assert_allclose(
                probabilities(circ, spec),
                run_aer(circ, noise=spec),
                atol=1e-9,
                err_msg=f"{channel} p={p}",
            )


def test_readout_error_matches_aer_shots(rng: np.random.Generator) -> None:
    pytest.importorskip("qiskit_aer")
    from qdcnn.quantum.qiskit_bridge import run_aer

    spec = NoiseSpec("bit-flip", 0.1, readout=0.2)
    circ = vqc_circuit(rng.uniform(0, 3, (10, 2)), rng.uniform(-3, 3, 4))
    exact = probabilities(circ, spec)
    freq = run_aer(circ, shots=8192, noise=spec, seed=5) / 8192
    sigma = np.sqrt(exact * (1 - exact) / 8192)
    assert (np.abs(freq - exact) < 4 * sigma + 1e-9).all()


def test_device_noise_without_the_quantum_extra_names_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import sys

    from qdcnn.errors import MissingExtraError
    from qdcnn.quantum.device import load_calibration

    load_calibration.cache_clear()  # a calibration read earlier in this process would answer
    monkeypatch.setitem(sys.modules, "qiskit_ibm_runtime", None)  # import fails as if absent
    with pytest.raises(MissingExtraError, match=r"pip install 'qdcnn\[quantum\]'"):
        parse_noise("device:FakeManilaV2")
