"""Density matrices in the Pauli basis: real vectors, real one-qubit maps, signed permutations.

A density matrix on ``n`` qubits is ``rho = 2**-n sum_a c_a sigma_a`` over the ``4**n``
Pauli strings ``sigma_a = sigma_{a_{n-1}} (x) ... (x) sigma_{a_0}`` (``a = sum_q a_q 4**q``,
``sigma_0..3 = I, X, Y, Z``); the coefficients ``c_a = Tr(sigma_a rho)`` are real. A
gate or a noise channel ``E`` acts on them through its Pauli transfer matrix
``R[a, b] = 2**-m Tr(sigma_a E(sigma_b))``, a real ``4**m x 4**m`` matrix, so the
whole density-matrix simulation runs in real arithmetic: one-qubit gates and their
noise are real ``4 x 4`` maps on one axis, CX and CZ (Clifford gates) permute the
strings with signs, and a product state is a Kronecker product of Bloch vectors
``(1, x, y, z)``. Vectors are stored batch-last, ``(4**n, B)``, so a shared ``4 x 4``
map is one large matrix product per qubit.

References
----------
.. [1] D. Greenbaum, "Introduction to quantum gate set tomography", arXiv:1509.02921
   (2015), Sec. 3 (Pauli transfer matrices).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from qdcnn._optional import require
from qdcnn.quantum import gates as np_gates

require("torch", "the PyTorch quantum simulator")
import torch  # noqa: E402

from qdcnn.quantum.torchsim._constants import cached_constant  # noqa: E402

_PAULIS = np.stack([np_gates.I2, np_gates.X, np_gates.Y, np_gates.Z]).astype(np.complex128)
#: Bloch vector of |0><0|: c = (Tr rho, <X>, <Y>, <Z>) = (1, 0, 0, 1)
ZERO_STATE = (1.0, 0.0, 0.0, 1.0)


# ---- NumPy, at compile time ------------------------------------------------------------


def _pauli_strings(m: int) -> NDArray[np.complex128]:
    """``(4**m, 2**m, 2**m)``: string ``a`` is ``sigma_{a_{m-1}} (x) ... (x) sigma_{a_0}``."""
    out = np.ones((1, 1, 1), dtype=np.complex128)
    for _ in range(m):
        out = np.einsum("aij,bkl->bakilj", out, _PAULIS).reshape(
            4 * out.shape[0], 2 * out.shape[1], 2 * out.shape[2]
        )
    return out


def kraus_ptm(kraus: NDArray[np.complex128]) -> NDArray[np.float64]:
    """Pauli transfer matrix ``(4**m, 4**m)`` of the channel with Kraus operators ``kraus``.

    ``kraus`` has shape ``(k, 2**m, 2**m)`` with its first qubit the least significant
    bit, which is also the last digit of the string index.
    """
    d = kraus.shape[-1]
    m = int(np.log2(d))
    sigma = _pauli_strings(m)
    mapped = np.einsum("kij,bjl,kml->bim", kraus, sigma, kraus.conj())
    return np.einsum("aij,bji->ab", sigma, mapped).real / d


def clifford_map(
    unitary: NDArray[np.complex128], qubits: tuple[int, ...], n: int
) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """A Clifford gate on ``qubits`` as a signed permutation of the ``4**n`` strings.

    Returns ``(src, sign)`` with ``c'[a] = sign[a] * c[src[a]]``.
    """
    local = kraus_ptm(unitary[None])
    target = np.abs(local).argmax(axis=0)  # string b goes to target[b] ...
    signs = local[target, np.arange(local.shape[1])]  # ... with this sign
    if not np.allclose(np.abs(signs), 1.0, atol=1e-12):
        raise ValueError("not a Clifford gate")
    full = np.arange(4**n)
    digits = [(full >> (2 * q)) & 3 for q in qubits]
    loc = sum(dg << (2 * t) for t, dg in enumerate(digits))
    new_loc = target[loc]
    dest = full.copy()
    for t, q in enumerate(qubits):
        dest += (((new_loc >> (2 * t)) & 3) - digits[t]) << (2 * q)
    src = np.empty_like(full)
    src[dest] = full
    sign = np.empty(4**n)
    sign[dest] = signs[loc]
    return src, sign


def then(
    first: tuple[NDArray[np.intp], NDArray[np.float64]],
    second: tuple[NDArray[np.intp], NDArray[np.float64]],
) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Signed permutation ``first`` followed by ``second``."""
    return first[0][second[0]], second[1] * first[1][second[0]]


@lru_cache(maxsize=16)
def _z_strings(n: int) -> NDArray[np.intp]:
    """Indices of the ``2**n`` strings made of ``I`` and ``Z``, by their ``Z`` bitmask."""
    z = np.arange(2**n)
    return sum(((z >> q) & 1) * 3 << (2 * q) for q in range(n))  # type: ignore[return-value]


@lru_cache(maxsize=16)
def _walsh(n: int) -> NDArray[np.float64]:
    """``W[s, z] = (-1)**popcount(s & z) / 2**n``: probabilities from ``Z``-string coefficients."""
    s = np.arange(2**n)
    parity = np.zeros((2**n, 2**n), dtype=np.int64)
    both = s[:, None] & s[None, :]
    for q in range(n):
        parity ^= (both >> q) & 1
    return (1.0 - 2.0 * parity) / 2**n


# ---- torch, at run time ----------------------------------------------------------------


@cached_constant(32)
def _basis_change(dtype: torch.dtype, device: torch.device) -> tuple[torch.Tensor, torch.Tensor]:
    """``T`` (row-major ``vec(rho)`` -> ``c``) and its inverse, for one qubit."""
    t = np.stack([p.T.ravel() for p in _PAULIS])  # T[a, 2i + j] = sigma_a[j, i]
    t_inv = np.stack([p.ravel() for p in _PAULIS], axis=1) / 2  # [2i + j, a] = sigma_a[i, j] / 2
    return (
        torch.as_tensor(t, dtype=dtype, device=device),
        torch.as_tensor(t_inv, dtype=dtype, device=device),
    )


def unitary_ptm(u: torch.Tensor) -> torch.Tensor:
    """Real Pauli transfer matrices ``(..., 4, 4)`` of one-qubit unitaries ``(..., 2, 2)``."""
    t, t_inv = _basis_change(u.dtype, u.device)
    sup = (u[..., :, None, :, None] * u.conj()[..., None, :, None, :]).reshape(*u.shape[:-2], 4, 4)
    return (t @ sup @ t_inv).real


def apply_local(c: torch.Tensor, r: torch.Tensor, q: int, n: int) -> torch.Tensor:
    """Apply ``4 x 4`` maps ``r`` on qubit ``q`` of ``c`` ``(4**n, B')``.

    ``r`` is one shared ``(4, 4)`` map (one batched product over the other qubits) or one
    map per sample ``(B, 4, 4)``.
    """
    hi, lo = 4 ** (n - 1 - q), 4**q
    if r.ndim == 2:
        view = c.reshape(hi, 4, lo * c.shape[1])
        return (r @ view).reshape(4**n, c.shape[1])
    view = c.reshape(hi, 4, lo, c.shape[1])
    out = torch.einsum("bij,hjlb->hilb", r, view)
    return out.reshape(4**n, out.shape[-1])


def apply_strings(
    c: torch.Tensor, r: torch.Tensor, qubits: tuple[int, ...], n: int
) -> torch.Tensor:
    """Apply an ``m``-qubit transfer matrix ``(4**m, 4**m)`` on ``qubits`` (``qubits[0]`` LSB)."""
    if len(qubits) == 1:
        return apply_local(c, r, qubits[0], n)
    m = len(qubits)
    t = c.reshape(*([4] * n), c.shape[1])
    axes = [n - 1 - q for q in reversed(qubits)]  # most significant first
    moved = torch.movedim(t, axes, list(range(m)))
    out = (r @ moved.reshape(4**m, -1)).reshape(moved.shape)
    return torch.movedim(out, list(range(m)), axes).reshape(4**n, c.shape[1])


def product(bloch: list[torch.Tensor]) -> torch.Tensor:
    """``(4**n, B')`` from per-qubit Bloch vectors ``(B', 4)``, listed from qubit ``n-1`` to 0."""
    out = bloch[0].T
    for v in bloch[1:]:
        out = (out[:, None, :] * v.T[None, :, :]).reshape(-1, out.shape[-1])
    return out


def probabilities(c: torch.Tensor, n: int) -> torch.Tensor:
    """Outcome probabilities ``(B, 2**n)`` (qubit 0 = LSB) from coefficients ``(4**n, B)``."""
    z = torch.as_tensor(_z_strings(n), device=c.device)
    w = torch.as_tensor(_walsh(n), dtype=c.dtype, device=c.device)
    return (w @ c.index_select(0, z)).T


def density_matrix(c: torch.Tensor, n: int, cdtype: torch.dtype) -> torch.Tensor:
    """Density matrices ``(B, 2**n, 2**n)`` from coefficients ``(4**n, B)``."""
    _, t_inv = _basis_change(cdtype, c.device)
    vec = c.to(cdtype)
    for q in range(n):  # per qubit: c -> (ket bit, bra bit) pair
        vec = apply_local(vec, t_inv, q, n)
    d = 2**n
    k, b = np.divmod(np.arange(d * d), d)
    order = sum((2 * ((k >> q) & 1) + ((b >> q) & 1)) << (2 * q) for q in range(n))
    index = torch.as_tensor(np.asarray(order), device=c.device)
    return vec.index_select(0, index).T.reshape(-1, d, d)
