"""Read-out of simulated states: probabilities, readout error, ``<Z_i>`` and shots."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from qdcnn._optional import require
from qdcnn._validation import check_shots
from qdcnn.quantum.sampling import sample_probabilities

require("torch", "the PyTorch quantum simulator")
import torch  # noqa: E402

from qdcnn.quantum.torchsim._constants import cached_constant  # noqa: E402


def state_probabilities(psi: torch.Tensor) -> torch.Tensor:
    """``|psi_i|^2`` of states ``(B, 2**n)``, real or complex."""
    if psi.is_complex():
        return psi.real.square() + psi.imag.square()
    return psi.square()


def readout_matrix(confusions: list[NDArray[np.float64]], like: torch.Tensor) -> torch.Tensor:
    """``A_{n-1} (x) ... (x) A_0`` for per-qubit ``A_q[measured, prepared]`` (qubit 0 = LSB)."""
    full = np.ones((1, 1))
    for a in reversed(confusions):
        full = np.asarray(np.kron(full, a), dtype=np.float64)
    return torch.as_tensor(full, dtype=like.dtype, device=like.device)


def z_signs(num_qubits: int, like: torch.Tensor) -> torch.Tensor:
    """``(2**n, n)`` table of ``+1`` / ``-1``: the eigenvalue of ``Z_q`` on each basis state."""
    return _z_signs(num_qubits, like.dtype, like.device)


@cached_constant(64)
def _z_signs(num_qubits: int, dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    idx = np.arange(2**num_qubits)[:, None]
    signs = 1.0 - 2.0 * ((idx >> np.arange(num_qubits)[None, :]) & 1)
    return torch.as_tensor(signs, dtype=dtype, device=device)


def z_expectations(probs: torch.Tensor, num_qubits: int) -> torch.Tensor:
    """``<Z_q>`` for each qubit from outcome probabilities ``(B, 2**n)``: shape ``(B, n)``."""
    return probs @ z_signs(num_qubits, probs)


def sampled(
    probs: torch.Tensor, shots: int, rng: int | np.random.Generator | None = None
) -> torch.Tensor:
    """Shot-estimated probabilities with the statistics of measuring ``shots`` copies.

    Counts are multinomial with the exact probabilities (binomial for one qubit),
    drawn by :func:`qdcnn.quantum.sampling.sample_probabilities` from a seeded NumPy
    generator, the same sampler every NumPy path uses. Not differentiable: the result
    is a constant on the device and in the dtype of ``probs``.
    """
    check_shots(shots)
    exact = probs.detach().to("cpu", torch.float64).numpy()
    flat = exact.reshape(-1, exact.shape[-1])
    est = sample_probabilities(flat, shots, rng).reshape(exact.shape)
    return torch.as_tensor(est, dtype=probs.dtype, device=probs.device)
