"""One entry point to run a batch of circuits: NumPy or Aer, exact or with shots."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from qdcnn._validation import check_shots
from qdcnn.errors import ParameterError
from qdcnn.quantum.circuits import CircuitBatch
from qdcnn.quantum.noise import NoiseSpec
from qdcnn.quantum.sampling import as_generator, sample_probabilities
from qdcnn.quantum.simulator import probabilities

_BACKENDS: tuple[str, ...] = ("numpy", "aer")


def check_backend(backend: str) -> str:
    """Return ``backend`` if known, else raise :class:`ParameterError`."""
    if backend not in _BACKENDS:
        raise ParameterError("backend", backend, "'numpy' or 'aer'")
    return backend


def run_probabilities(
    circuit: CircuitBatch,
    *,
    shots: int | None = None,
    noise: NoiseSpec | None = None,
    backend: str = "numpy",
    rng: int | np.random.Generator | None = None,
) -> NDArray[np.float64]:
    """Outcome probabilities of every circuit: exact (``shots=None``) or estimated from shots.

    Parameters
    ----------
    circuit : CircuitBatch
        The circuits.
    shots : int or None
        Measurements per circuit; ``None`` for exact probabilities.
    noise : NoiseSpec or None
        Gate and readout noise: a channel after every gate, or a device's calibrated
        noise (:class:`qdcnn.quantum.device.DeviceNoise`, e.g.
        ``parse_noise("device:FakeManilaV2")``).
    backend : {"numpy", "aer"}
        Batched NumPy simulation, or Qiskit Aer (all circuits in one run call).
    rng : int, Generator or None
        Seed or generator for the shots (with Aer, an integer seed is drawn from it).

    Returns
    -------
    ndarray of float64, shape (B, 2**n)
    """
    check_backend(backend)
    if shots is not None:
        check_shots(shots)
    if backend == "numpy":
        exact = probabilities(circuit, noise)
        return exact if shots is None else sample_probabilities(exact, shots, rng)
    from qdcnn.quantum.qiskit_bridge import run_aer

    seed = int(as_generator(rng).integers(2**31 - 1))
    if shots is None:
        out = np.asarray(run_aer(circuit, noise=noise, seed=seed), dtype=np.float64)
        if noise is not None and not noise.is_ideal:
            from qdcnn.quantum.simulator import apply_readout_error

            # Aer's exact probabilities leave out readout error; each qubit's is applied here
            bound = noise.prepare(circuit)[1]
            out = apply_readout_error(out, bound, circuit.num_qubits)
        return out
    return run_aer(circuit, shots=shots, noise=noise, seed=seed) / float(shots)
