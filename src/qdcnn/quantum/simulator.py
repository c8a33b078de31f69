"""Exact batched simulation of :class:`CircuitBatch` in NumPy.

The statevector simulator applies each gate to all ``B`` states at once through
a ``(B, 2**(n-1-q), 2, 2**q)`` view of the state, so the only Python loop is
over the gates of the circuit. The density-matrix simulator embeds each gate in
the full register and applies the channels the noise model names after each gate
(:class:`qdcnn.quantum.noise.GateNoise`: a :class:`NoiseSpec` channel on every qubit
the gate touches, or a device's calibrated per-gate, per-qubit channels).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._threads import single_thread
from qdcnn.quantum import gates
from qdcnn.quantum.circuits import CircuitBatch, Gate
from qdcnn.quantum.noise import GateNoise, Kraus


def _cx_permutation(n: int, control: int, target: int) -> NDArray[np.intp]:
    idx = np.arange(2**n)
    return np.where((idx >> control) & 1, idx ^ (1 << target), idx)


def _cz_signs(n: int, a: int, b: int) -> NDArray[np.float64]:
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


def _fuse_rotations(gates: tuple[Gate, ...]) -> list[Gate]:
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

    ``fused`` is ``_fuse_rotations(circuit.gates)`` when the caller already has it.
    """
    n = circuit.num_qubits
    state: NDArray[Any] = np.zeros((circuit.batch_size, 2**n))
    state[:, 0] = 1.0
    for g in _fuse_rotations(circuit.gates) if fused is None else fused:
        if g.name == "cx":
            state = state[:, _cx_permutation(n, *g.qubits)]
        elif g.name == "cz":
            state = state * _cz_signs(n, *g.qubits)
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
        return np.diag(_cz_signs(n, *g.qubits)).astype(np.complex128)[None]
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


def _embed_operator(ops: NDArray[Any], qubits: tuple[int, ...], n: int) -> NDArray[np.complex128]:
    """Embed ``k``-qubit operators ``(K, 2**k, 2**k)`` on ``qubits`` into ``(K, 2**n, 2**n)``.

    ``qubits[0]`` is the least significant bit of the operators' index (Qiskit's
    convention), so ``_embed_operator(cx_matrix, (c, t), n)`` is a CX with control ``c``.
    """
    if len(qubits) == 1:
        return embed(ops, qubits[0], n)
    idx = np.arange(2**n)
    sub = np.zeros_like(idx)  # the operator's index of each basis state
    for m, q in enumerate(qubits):
        sub |= ((idx >> q) & 1) << m
    mask = sum(1 << q for q in qubits)
    same_rest = (idx[:, None] & ~mask) == (idx[None, :] & ~mask)
    full = np.asarray(ops, dtype=np.complex128)[:, sub[:, None], sub[None, :]]
    return full * same_rest


#: registers up to this many qubits apply a channel through its full-register Kraus
#: operators (one einsum, the fastest there); larger ones act on the touched qubits only
_EMBED_MAX_QUBITS = 2

_ChannelCache = dict[tuple[int, tuple[int, ...]], tuple[Kraus, NDArray[np.complex128]]]


def _cached(
    cache: _ChannelCache, ops: Kraus, qubits: tuple[int, ...], n: int
) -> NDArray[np.complex128]:
    # keyed by the array's identity: noise models hand out one array per (gate, qubits), and
    # the cache keeps a reference to it so that the id cannot be reused within one run
    key = (id(ops), qubits)
    hit = cache.get(key)
    if hit is None:
        if n <= _EMBED_MAX_QUBITS:
            derived = _embed_operator(ops, qubits, n)
        else:
            # superoperator S[(i, m), (j, l)] = sum_k K_ij conj(K_ml) on the touched qubits
            d = ops.shape[-1]
            derived = np.einsum("kij,kml->imjl", ops, ops.conj()).reshape(d * d, d * d)
        hit = cache[key] = (ops, derived)
    return hit[1]


def _apply_channel(
    rho: NDArray[np.complex128],
    ops: Kraus,
    qubits: tuple[int, ...],
    n: int,
    cache: _ChannelCache,
) -> NDArray[np.complex128]:
    """``sum_k K_k rho K_k^dagger`` with the Kraus operators ``ops`` acting on ``qubits``."""
    derived = _cached(cache, ops, qubits, n)
    if n <= _EMBED_MAX_QUBITS:
        return np.einsum("kij,bjl,kml->bim", derived, rho, derived.conj(), optimize=True)
    k = len(qubits)
    # row bit of qubit q is tensor axis 1 + (n - 1 - q), its column bit that plus n; the
    # operator's index has qubits[k - 1] as its most significant bit
    rows = [n - qubits[m] for m in reversed(range(k))]
    axes = rows + [a + n for a in rows]
    t = rho.reshape((rho.shape[0],) + (2,) * (2 * n))
    t = np.moveaxis(t, axes, range(2 * n + 1 - 2 * k, 2 * n + 1))
    shape = t.shape
    t = (t.reshape(-1, 4**k) @ derived.T).reshape(shape)
    t = np.moveaxis(t, range(2 * n + 1 - 2 * k, 2 * n + 1), axes)
    return t.reshape(rho.shape)


#: two-qubit gates of device-native circuits (Qiskit's matrices, first qubit the least
#: significant bit), applied by the density-matrix path
_NATIVE_TWO_QUBIT: dict[str, NDArray[np.complex128]] = {
    "ecr": np.array(
        [[0, 1, 0, 1j], [1, 0, -1j, 0], [0, 1j, 0, 1], [-1j, 0, 1, 0]], dtype=np.complex128
    )
    / np.sqrt(2),
    "cz": gates.CZ.astype(np.complex128),
}


def _density_step_unitary(g: Gate, n: int) -> NDArray[np.complex128]:
    if g.name in _NATIVE_TWO_QUBIT:
        return _embed_operator(_NATIVE_TWO_QUBIT[g.name][None], g.qubits, n)
    return _gate_unitary(g, n)


def _evolve_density(circuit: CircuitBatch, noise: GateNoise | None) -> NDArray[np.complex128]:
    """Density matrices after ``circuit`` (already prepared), with ``noise``'s channels."""
    n = circuit.num_qubits
    d = 2**n
    rho = np.zeros((circuit.batch_size, d, d), dtype=np.complex128)
    rho[:, 0, 0] = 1.0
    cache: _ChannelCache = {}
    with single_thread():  # products of 4x4 matrices: BLAS threads only add overhead
        for g in circuit.gates:
            u = _density_step_unitary(g, n)
            rho = u @ rho @ np.conj(np.swapaxes(u, 1, 2))
            for qubits, ops in () if noise is None else noise.channels_after(g):
                rho = _apply_channel(rho, ops, qubits, n, cache)
    return rho


def density_matrix(circuit: CircuitBatch, noise: GateNoise | None = None) -> NDArray[np.complex128]:
    """Final density matrices, shape ``(B, 2**n, 2**n)``, with optional gate noise.

    The circuit first becomes what runs under ``noise`` (``noise.prepare``: itself for a
    :class:`~qdcnn.quantum.noise.NoiseSpec`, native gates on a layout for device noise),
    then the channels of ``noise.channels_after(gate)`` follow each gate: for a
    ``NoiseSpec``, its channel on each qubit the gate touches. Readout error is not part
    of the state; see :func:`probabilities`.
    """
    if noise is None:
        return _evolve_density(circuit, None)
    native, bound = noise.prepare(circuit)
    return _evolve_density(native, bound)


def apply_readout_error(
    probs: NDArray[np.float64], noise: GateNoise, n: int
) -> NDArray[np.float64]:
    """Apply each qubit's readout confusion matrix of ``noise`` to ``probs`` ``(B, 2**n)``.

    ``noise`` is a prepared noise (a :class:`~qdcnn.quantum.noise.NoiseSpec`, or what
    ``noise.prepare(circuit)`` returned); qubit ``q`` gets ``readout_matrices(n)[q]``,
    ``A[measured, prepared]``, which need not be symmetric.
    """
    mats = noise.readout_matrices(n)
    if mats is None:
        return probs
    t = probs.reshape((probs.shape[0],) + (2,) * n)
    for q in range(n):
        axis = n - q  # qubit q is tensor axis n - q (qubit 0 is the last axis)
        t = np.moveaxis(np.tensordot(t, mats[q], axes=([axis], [1])), -1, axis)
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


def probabilities(circuit: CircuitBatch, noise: GateNoise | None = None) -> NDArray[np.float64]:
    """Exact outcome probabilities, shape ``(B, 2**n)``, index = basis state (qubit 0 = LSB).

    Noise-free circuits use the statevector simulator; otherwise the
    density-matrix simulator (:func:`density_matrix`), then each qubit's readout error.
    """
    if noise is None or noise.is_ideal:
        fused = _fuse_rotations(circuit.gates)
        single = _single_rotation(circuit, fused)
        if single is not None:
            return single
        psi = _evolve(circuit, fused)
        probs = np.abs(psi) ** 2 if np.iscomplexobj(psi) else psi * psi
    else:
        native, bound = noise.prepare(circuit)
        rho = _evolve_density(native, bound)
        probs = np.clip(np.einsum("bii->bi", rho).real, 0.0, None)
        probs = apply_readout_error(probs, bound, circuit.num_qubits)
    return probs / probs.sum(axis=1, keepdims=True)
