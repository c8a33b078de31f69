"""Compile a :class:`~qdcnn.quantum.circuits.CircuitTemplate` into simulation steps.

Plain Python and NumPy (no torch): the template's gates are grouped once into

* :class:`Block`: a run of one-qubit gates. Gates on different qubits commute, so a
  block is, per qubit, an ordered list of gates; *round* ``r`` holds the ``r``-th
  gate of every qubit that has one, so a block costs one batched product per round
  however many qubits it spans. With noise, a gate's channel on its own qubit is
  fused into the same per-qubit operator (a Pauli transfer matrix).
* :class:`Monomial`: two-qubit gates (``cx``, ``cz``), which permute basis states and
  flip signs. Without noise, consecutive ones fuse into one permutation and sign.
* :class:`Channels`: noise that cannot be fused into a block (every channel after a
  two-qubit gate, or a channel acting on other qubits than its gate's).

:func:`gate_channels` is the one place that asks a noise object which Kraus
operators act after a gate, on which qubits.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from qdcnn.errors import ParameterError
from qdcnn.quantum.circuits import TWO_QUBIT, CircuitTemplate, Gate
from qdcnn.quantum.noise import GateNoise

#: Largest register the PyTorch simulator accepts (a 256 x 256 density matrix per sample).
MAX_QUBITS = 8

Kraus = NDArray[np.complex128]
Channel = tuple[tuple[int, ...], Kraus]


def gate_channels(noise: GateNoise, gate: Gate) -> list[Channel]:
    """The noise channels acting after ``gate``: a list of ``(qubits, kraus)``.

    ``kraus`` has shape ``(k, 2**m, 2**m)`` for ``m = len(qubits)``, with ``qubits[0]``
    the least significant bit of its index (Qiskit's order). A :class:`NoiseSpec` puts
    its channel after every gate on every qubit the gate touches, exactly as
    :func:`qdcnn.quantum.simulator.density_matrix` applies it; per-qubit device noise
    answers per gate (``channels_after`` of the noise protocol, :class:`GateNoise`).
    """
    return [(tuple(q), np.asarray(k, dtype=np.complex128)) for q, k in noise.channels_after(gate)]


def readout_confusions(
    noise: GateNoise | None, num_qubits: int
) -> list[NDArray[np.float64]] | None:
    """Per-qubit readout matrices ``A[measured, prepared]``, or ``None`` without readout error.

    Read through the noise protocol (:class:`qdcnn.quantum.noise.GateNoise`).
    """
    hook = getattr(noise, "readout_matrices", None)  # a noise without readout may leave it out
    matrices = None if hook is None else hook(num_qubits)
    return None if matrices is None else [np.asarray(m, dtype=np.float64) for m in matrices]


def _check_template_noise(noise: GateNoise | None) -> None:
    """Refuse noise that rewrites circuits into a device's native gates.

    Device noise (:class:`qdcnn.quantum.device.DeviceNoise`) prepares each bound circuit
    in native gates on a layout; the PyTorch simulator runs symbolic templates, so such
    noise is simulated by the NumPy density-matrix simulator instead.
    """
    if noise is not None and getattr(noise, "device", None) is not None:
        raise ParameterError(
            "noise",
            noise.label(),
            "a channel noise (NoiseSpec) for the PyTorch simulator; device noise runs on "
            "the NumPy density-matrix simulator",
        )


@dataclass(frozen=True)
class Round:
    """The ``r``-th gate of each qubit of a block: ``positions`` index ``Block.qubits``."""

    positions: tuple[int, ...]
    gates: tuple[int, ...]


@dataclass(frozen=True)
class Block:
    """A run of one-qubit gates; ``qubits`` in order of their first gate (round 0)."""

    qubits: tuple[int, ...]
    rounds: tuple[Round, ...]


@dataclass(frozen=True)
class Monomial:
    """Two-qubit gates as one map ``psi'[i] = sign[i] * psi[perm[i]]``."""

    gates: tuple[int, ...]
    perm: NDArray[np.intp]
    sign: NDArray[np.float64] | None


@dataclass(frozen=True)
class Channels:
    """Channels applied in order: ``(qubits, index into Program.kraus)``."""

    channels: tuple[tuple[tuple[int, ...], int], ...]


Step = Block | Monomial | Channels


@dataclass
class Program:
    """The steps of one template under one noise model.

    ``fused_noise[g]`` lists the Kraus indices fused after one-qubit gate ``g`` on its
    own qubit; ``kraus`` holds each distinct Kraus set once.
    """

    template: CircuitTemplate
    steps: tuple[Step, ...]
    kraus: tuple[Kraus, ...] = ()
    fused_noise: dict[int, tuple[int, ...]] = field(default_factory=dict)
    readout: list[NDArray[np.float64]] | None = None

    @property
    def noisy(self) -> bool:
        return bool(self.kraus)


def _monomial_of(name: str, qubits: tuple[int, ...], n: int) -> Monomial:
    idx = np.arange(2**n)
    if name == "cx":
        control, target = qubits
        perm = np.where((idx >> control) & 1, idx ^ (1 << target), idx)
        return Monomial((), perm, None)
    a, b = qubits
    return Monomial((), idx, np.where((idx >> a) & (idx >> b) & 1, -1.0, 1.0))


def _then(first: Monomial, second: Monomial) -> Monomial:
    """``first`` followed by ``second``: ``psi''[i] = s2[i] s1[p2[i]] psi[p1[p2[i]]]``."""
    carried = None if first.sign is None else first.sign[second.perm]
    sign = carried if second.sign is None else second.sign
    if carried is not None and second.sign is not None:
        sign = carried * second.sign
    return Monomial(first.gates + second.gates, first.perm[second.perm], sign)


class _KrausTable:
    def __init__(self) -> None:
        self.ops: list[Kraus] = []
        self._index: dict[bytes, int] = {}

    def index(self, kraus: Kraus) -> int:
        k = np.ascontiguousarray(kraus, dtype=np.complex128)
        key = k.shape.__repr__().encode() + k.tobytes()
        if key not in self._index:
            self._index[key] = len(self.ops)
            self.ops.append(k)
        return self._index[key]


def _block(gates: Sequence[int], qubit_of: Sequence[int]) -> Block:
    per_qubit: dict[int, list[int]] = {}
    for g in gates:
        per_qubit.setdefault(qubit_of[g], []).append(g)
    qubits = tuple(per_qubit)
    depth = max(len(v) for v in per_qubit.values())
    rounds = []
    for r in range(depth):
        pos = tuple(i for i, q in enumerate(qubits) if len(per_qubit[q]) > r)
        rounds.append(Round(pos, tuple(per_qubit[qubits[i]][r] for i in pos)))
    return Block(qubits, tuple(rounds))


def compile_template(template: CircuitTemplate, noise: GateNoise | None = None) -> Program:
    """Group ``template``'s gates into steps for ``noise`` (``None``: noise-free)."""
    _check_template_noise(noise)
    n = template.num_qubits
    if not 1 <= n <= MAX_QUBITS:
        raise ParameterError("num_qubits", n, f"1 to {MAX_QUBITS} qubits for the PyTorch simulator")
    table = _KrausTable()
    fused: dict[int, tuple[int, ...]] = {}
    steps: list[Step] = []
    pending: list[int] = []
    qubit_of = [g.qubits[0] for g in template.gates]

    def flush() -> None:
        if pending:
            steps.append(_block(pending, qubit_of))
            pending.clear()

    for gi, g in enumerate(template.gates):
        channels = [] if noise is None else gate_channels(noise, Gate(g.name, g.qubits))
        if g.name not in TWO_QUBIT:
            own = [table.index(k) for qs, k in channels if qs == g.qubits]
            pending.append(gi)
            if own:
                fused[gi] = tuple(own)
            others = [(qs, table.index(k)) for qs, k in channels if qs != g.qubits]
            if others:
                flush()
                steps.append(Channels(tuple(others)))
            continue
        flush()
        mono = _monomial_of(g.name, g.qubits, n)
        mono = Monomial((gi,), mono.perm, mono.sign)
        last = steps[-1] if steps else None
        if isinstance(last, Monomial):  # no channel between them: one permutation
            steps[-1] = _then(last, mono)
        else:
            steps.append(mono)
        if channels:
            steps.append(Channels(tuple((qs, table.index(k)) for qs, k in channels)))
    flush()
    readout = None if noise is None else readout_confusions(noise, n)
    return Program(template, tuple(steps), tuple(table.ops), fused, readout)
