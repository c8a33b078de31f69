"""Exact batched simulation of :class:`CircuitBatch` in NumPy.

The statevector simulator applies each gate to all ``B`` states at once through
a ``(B, 2**(n-1-q), 2, 2**q)`` view of the state, so the only Python loop is
over the gates of the circuit. The density-matrix simulator embeds each gate in
the full register and applies gate noise after every gate on every qubit it
touches (see :mod:`qdcnn.quantum.noise`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._threads import single_thread
from qdcnn.quantum.circuits import CircuitBatch, Gate
from qdcnn.quantum.noise import NoiseSpec


def _cx_permutation(n: int, control: int, target: int) -> NDArray[np.intp]:
    idx = np.arange(2**n)
    return np.where((idx >> control) & 1, idx ^ (1 << target), idx)


def cz_signs(n: int, a: int, b: int) -> NDArray[np.float64]:
    """Diagonal of ``CZ(a, b)`` on ``n`` qubits: ``-1`` where both bits are set, else ``1``."""
    idx = np.arange(2**n)
    return np.where((idx >> a) & (idx >> b) & 1, -1.0, 1.0)


def _apply_1q(state: NDArray[Any], m: NDArray[Any], q: int, n: int) -> NDArray[Any]:
    b = state.shape[0]
    view = state.reshape(b, 2 ** (n - 1 - q), 2, 2**q)
    a0, a1 = view[:, :, 0, :], view[:, :, 1, :]
    m = m.reshape(m.shape[0], 1, 2, 2, 1)  # broadcast over the other qubits' axes
    out = np.empty(view.shape, dtype=np.result_type(state, m))
    out[:, :, 0, :] = m[:, :, 0, 0] * a0 + m[:, :, 0, 1] * a1
    out[:, :, 1, :] = m[:, :, 1, 0] * a0 + m[:, :, 1, 1] * a1
    return out.reshape(b, 2**n)


_FUSABLE = frozenset({"ry", "rx", "rz", "p"})


def fuse_rotations(gates: tuple[Gate, ...]) -> list[Gate]:
    """Merge runs of same-axis rotations on one qubit into one gate (exact).

    ``RY(a) RY(b) = RY(a + b)``, and likewise for ``RX``, ``RZ`` and ``P``; the
    UU-dagger circuit ``RY(-theta_x) RY(theta_c)`` becomes one ``RY``.
    """
    out: list[Gate] = []
    for g in gates:
        prev = out[-1] if out else None
        if (
            prev is not None
            and g.name in _FUSABLE
            and prev.name == g.name
            and prev.qubits == g.qubits
            and prev.angle is not None
            and g.angle is not None
        ):
            out[-1] = Gate(g.name, g.qubits, prev.angle + g.angle)
        else:
            out.append(g)
    return out


def _evolve(circuit: CircuitBatch, fused: list[Gate] | None = None) -> NDArray[Any]:
    """Final states, in real arithmetic while every gate so far is real (RY, H, X, Z, CX, CZ).

    ``fused`` is ``fuse_rotations(circuit.gates)`` when the caller already has it.
    """
    n = circuit.num_qubits
    state: NDArray[Any] = np.zeros((circuit.batch_size, 2**n))
    state[:, 0] = 1.0
    for g in fuse_rotations(circuit.gates) if fused is None else fused:
        if g.name == "cx":
            state = state[:, _cx_permutation(n, *g.qubits)]
        elif g.name == "cz":
            state = state * cz_signs(n, *g.qubits)
        else:
            state = _apply_1q(state, g.matrix(), g.qubits[0], n)
    return state


def statevector(circuit: CircuitBatch) -> NDArray[np.complex128]:
    """Final states of all circuits, shape ``(B, 2**n)``, starting from ``|0...0>``.

    Examples
    --------
    >>> from qdcnn.quantum.circuits import uu_dagger_circuit
    >>> psi = statevector(uu_dagger_circuit(0.0, np.pi))
    >>> np.round(abs(psi) ** 2, 12).tolist()
    [[0.0, 1.0]]
    """
    return _evolve(circuit).astype(np.complex128, copy=False)


def embed(m: NDArray[Any], q: int, n: int) -> NDArray[np.complex128]:
    """Embed one-qubit matrices ``(K, 2, 2)`` acting on qubit ``q`` into ``(K, 2**n, 2**n)``."""
    hi, lo = np.eye(2 ** (n - 1 - q)), np.eye(2**q)
    full = np.einsum("hH,kij,lL->khilHjL", hi, m, lo)
    return full.reshape(m.shape[0], 2**n, 2**n)


def _gate_unitary(g: Gate, n: int) -> NDArray[np.complex128]:
    if g.name == "cx":
        perm = _cx_permutation(n, *g.qubits)
        return np.eye(2**n, dtype=np.complex128)[perm][None]
    if g.name == "cz":
        return np.diag(cz_signs(n, *g.qubits)).astype(np.complex128)[None]
    return embed(g.matrix(), g.qubits[0], n)


def unitary(circuit: CircuitBatch) -> NDArray[np.complex128]:
    """The unitary of every circuit, shape ``(K, 2**n, 2**n)``.

    ``K`` is 1 when no gate angle varies over the batch (one shared unitary),
    else the batch size. Column ``j`` is the final state from basis state ``j``.
    """
    n = circuit.num_qubits
    u = np.eye(2**n, dtype=np.complex128)[None]
    for g in circuit.gates:
        u = _gate_unitary(g, n) @ u
    return u


def density_matrix(circuit: CircuitBatch, noise: NoiseSpec | None = None) -> NDArray[np.complex128]:
    """Final density matrices, shape ``(B, 2**n, 2**n)``, with optional gate noise.

    The channel of ``noise`` acts after every gate on each qubit the gate
    touches. Readout error is not part of the state; see :func:`probabilities`.
    """
    n = circuit.num_qubits
    d = 2**n
    rho = np.zeros((circuit.batch_size, d, d), dtype=np.complex128)
    rho[:, 0, 0] = 1.0
    kraus = None if noise is None else noise.kraus()
    kraus_on = [] if kraus is None else [embed(kraus, q, n) for q in range(n)]
    with single_thread():  # products of 4x4 matrices: BLAS threads only add overhead
        for g in circuit.gates:
            u = _gate_unitary(g, n)
            rho = u @ rho @ np.conj(np.swapaxes(u, 1, 2))
            for q in g.qubits if kraus_on else ():
                k = kraus_on[q]
                rho = np.einsum("kij,bjl,kml->bim", k, rho, k.conj(), optimize=True)
    return rho


def apply_readout_error(
    probs: NDArray[np.float64], noise: NoiseSpec, n: int
) -> NDArray[np.float64]:
    """Apply the symmetric readout error of ``noise`` to each qubit of ``probs`` ``(B, 2**n)``."""
    if noise.readout == 0.0:
        return probs
    a = noise.readout_matrix()
    t = probs.reshape((probs.shape[0],) + (2,) * n)
    for q in range(n):
        axis = n - q  # qubit q is tensor axis n - q (qubit 0 is the last axis)
        t = np.moveaxis(np.tensordot(t, a, axes=([axis], [1])), -1, axis)
    return t.reshape(probs.shape)


def _single_rotation(circuit: CircuitBatch, gates: list[Gate]) -> NDArray[np.float64] | None:
    """Probabilities of a one-qubit circuit whose fused ``gates`` are one ``RY(t)``, or ``None``.

    ``RY(t)|0> = (cos t/2, sin t/2)``, so ``P(1) = sin^2(t/2) = (1 - cos t) / 2``: the
    statevector result with one cosine per circuit instead of a cosine, a sine and a
    2x2 product (the UU-dagger circuit of every image block takes this path).
    """
    if circuit.num_qubits != 1 or len(gates) != 1:
        return None
    if gates[0].name != "ry" or gates[0].angle is None:
        return None
    half_cos = np.cos(gates[0].angle)
    half_cos *= 0.5
    out = np.empty((circuit.batch_size, 2))
    np.add(0.5, half_cos, out=out[:, 0])
    np.subtract(0.5, half_cos, out=out[:, 1])
    return out


def probabilities(circuit: CircuitBatch, noise: NoiseSpec | None = None) -> NDArray[np.float64]:
    """Exact outcome probabilities, shape ``(B, 2**n)``, index = basis state (qubit 0 = LSB).

    Noise-free circuits use the statevector simulator; otherwise the
    density-matrix simulator, then the readout error.
    """
    if noise is None or noise.is_ideal:
        fused = fuse_rotations(circuit.gates)
        single = _single_rotation(circuit, fused)
        if single is not None:
            return single
        psi = _evolve(circuit, fused)
        probs = np.abs(psi) ** 2 if np.iscomplexobj(psi) else psi * psi
    else:
        rho = density_matrix(circuit, noise)
        probs = np.clip(np.einsum("bii->bi", rho).real, 0.0, None)
        probs = apply_readout_error(probs, noise, circuit.num_qubits)
    return probs / probs.sum(axis=1, keepdims=True)
