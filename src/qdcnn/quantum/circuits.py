"""Circuits for a whole batch of parameter sets, in one small gate list.

A :class:`CircuitBatch` is a sequence of gates on ``num_qubits`` qubits in which
every rotation angle is an array with one entry per batch element, so ``B``
circuits of the same shape are one object. The NumPy simulators run it in one
pass; :mod:`qdcnn.quantum.qiskit_bridge` turns it into ``B`` Qiskit circuits.

Qubit 0 is the least significant bit of a basis-state index, as in Qiskit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from qdcnn.errors import ParameterError
from qdcnn.quantum import gates

ONE_QUBIT_PARAMETRIC = frozenset(gates.PARAMETRIC)
ONE_QUBIT_CONSTANT = frozenset(gates.CONSTANT)
TWO_QUBIT = frozenset({"cx"})
GATE_NAMES = ONE_QUBIT_PARAMETRIC | ONE_QUBIT_CONSTANT | TWO_QUBIT


@dataclass(frozen=True)
class Gate:
    """One gate of a batched circuit.

    Attributes
    ----------
    name : str
        ``ry``, ``rx``, ``rz``, ``p`` (angle gates), ``h``, ``x``, ``y``, ``z`` or ``cx``.
    qubits : tuple of int
        Target qubit, or ``(control, target)`` for ``cx``.
    angle : ndarray of float64 or None
        Shape ``(B,)`` (one angle per circuit) or ``()`` (shared); ``None`` for
        gates without an angle.
    """

    name: str
    qubits: tuple[int, ...]
    angle: NDArray[np.float64] | None = None

    def matrix(self) -> gates.Matrix:
        """Return the one-qubit matrix, shape ``(B, 2, 2)`` or ``(1, 2, 2)``."""
        if self.name in gates.PARAMETRIC:
            assert self.angle is not None
            return gates.PARAMETRIC[self.name](np.atleast_1d(self.angle))
        return gates.CONSTANT[self.name][None]


def _pick(angle: NDArray[np.float64] | None, idx: NDArray[np.intp]) -> NDArray[np.float64] | None:
    return angle[idx] if angle is not None and angle.ndim else angle


@dataclass(frozen=True)
class CircuitBatch:
    """``batch_size`` circuits with the same gate sequence and per-circuit angles."""

    num_qubits: int
    batch_size: int
    gates: tuple[Gate, ...] = ()
    name: str = "circuit"

    def __len__(self) -> int:
        return self.batch_size

    def select(self, index: ArrayLike) -> CircuitBatch:
        """Return the circuits at ``index`` (an integer array, a slice or a boolean mask)."""
        idx = np.arange(self.batch_size)[index]  # type: ignore[index]
        idx = np.atleast_1d(idx)
        picked = tuple(Gate(g.name, g.qubits, _pick(g.angle, idx)) for g in self.gates)
        return CircuitBatch(self.num_qubits, int(idx.size), picked, self.name)

    def angles_of(self, i: int) -> list[float | None]:
        """The angles of circuit ``i``, one per gate (``None`` for angle-free gates)."""
        return [
            None if g.angle is None else float(g.angle if g.angle.ndim == 0 else g.angle[i])
            for g in self.gates
        ]


@dataclass
class CircuitBuilder:
    """Append gates to a batched circuit.

    Examples
    --------
    >>> c = CircuitBuilder(1, 3).ry(0, [0.1, 0.2, 0.3]).ry(0, -0.5).build("demo")
    >>> len(c), [g.name for g in c.gates]
    (3, ['ry', 'ry'])
    """

    num_qubits: int
    batch_size: int
    gates: list[Gate] = field(default_factory=list)

    def __post_init__(self) -> None:
        if not 1 <= self.num_qubits <= 12:
            raise ParameterError("num_qubits", self.num_qubits, "1 to 12 qubits")
        if self.batch_size < 1:
            raise ParameterError("batch_size", self.batch_size, "at least 1")

    def _qubit(self, q: int) -> int:
        if not 0 <= q < self.num_qubits:
            raise ParameterError("qubit", q, f"an index in [0, {self.num_qubits - 1}]")
        return q

    def _angle(self, angle: ArrayLike) -> NDArray[np.float64]:
        a = np.asarray(angle, dtype=np.float64)
        if a.ndim > 1 or (a.ndim == 1 and a.shape[0] != self.batch_size):
            raise ParameterError(
                "angle", f"array of shape {a.shape}", f"a scalar or shape ({self.batch_size},)"
            )
        _check_finite(a)
        return a

    def add(
        self, name: str, qubits: tuple[int, ...], angle: ArrayLike | None = None
    ) -> CircuitBuilder:
        """Append gate ``name`` on ``qubits`` with ``angle`` (for angle gates)."""
        if name not in GATE_NAMES:
            raise ParameterError("gate", name, f"one of {sorted(GATE_NAMES)}")
        qs = tuple(self._qubit(q) for q in qubits)
        arity = 2 if name in TWO_QUBIT else 1
        if len(qs) != arity or len(set(qs)) != arity:
            raise ParameterError(f"{name} qubits", qubits, f"{arity} distinct qubit(s)")
        needs_angle = name in ONE_QUBIT_PARAMETRIC
        if needs_angle != (angle is not None):
            raise ParameterError(f"{name} angle", angle, "an angle" if needs_angle else "no angle")
        self.gates.append(Gate(name, qs, None if angle is None else self._angle(angle)))
        return self

    def ry(self, q: int, angle: ArrayLike) -> CircuitBuilder:
        return self.add("ry", (q,), angle)

    def rx(self, q: int, angle: ArrayLike) -> CircuitBuilder:
        return self.add("rx", (q,), angle)

    def rz(self, q: int, angle: ArrayLike) -> CircuitBuilder:
        return self.add("rz", (q,), angle)

    def p(self, q: int, angle: ArrayLike) -> CircuitBuilder:
        return self.add("p", (q,), angle)

    def h(self, q: int) -> CircuitBuilder:
        return self.add("h", (q,))

    def x(self, q: int) -> CircuitBuilder:
        return self.add("x", (q,))

    def cx(self, control: int, target: int) -> CircuitBuilder:
        return self.add("cx", (control, target))

    def build(self, name: str = "circuit") -> CircuitBatch:
        return CircuitBatch(self.num_qubits, self.batch_size, tuple(self.gates), name)


def _check_finite(angles: NDArray[np.float64]) -> None:
    if not np.isfinite(angles).all():
        raise ParameterError("angle", "non-finite values", "finite angles")


def _batch_angles(*angles: ArrayLike) -> tuple[int, list[NDArray[np.float64]]]:
    """Common batch size of scalar or 1-D angle arrays; length-1 arrays become scalars."""
    arrs = [np.asarray(a, dtype=np.float64) for a in angles]
    if any(a.ndim > 1 for a in arrs):
        raise ParameterError("angles", [a.shape for a in arrs], "scalars or 1-D arrays")
    sizes = {a.shape[0] for a in arrs if a.ndim == 1 and a.shape[0] != 1}
    if len(sizes) > 1:
        raise ParameterError("angles", sorted(sizes), "one batch size")
    b = sizes.pop() if sizes else 1
    return b, [a.reshape(()) if a.ndim == 1 and a.shape[0] == 1 else a for a in arrs]


def uu_dagger_circuit(theta_c: ArrayLike, theta_x: ArrayLike) -> CircuitBatch:
    """The paper's one-qubit fidelity circuit ``A = U2^dagger U1`` (Alg. 1, Eqs. 5-9).

    ``U1 = RY(theta_c)`` encodes the centroid, ``U2 = RY(theta_x)`` the test value;
    the circuit applies ``RY(theta_c)`` then ``RY(-theta_x)`` to ``|0>``, so
    ``P(0) = cos^2((theta_c - theta_x) / 2) = |<T|C>|^2``.

    Parameters
    ----------
    theta_c, theta_x : array_like
        Angles: scalars or 1-D arrays of one common batch size.
    """
    b, (tc, tx) = _batch_angles(theta_c, theta_x)
    # built directly rather than through CircuitBuilder: one circuit per image block is
    # made per frame, and the builder's per-gate checks cost as much as simulating it
    _check_finite(tc)
    _check_finite(tx)
    return CircuitBatch(1, b, (Gate("ry", (0,), tc), Gate("ry", (0,), -tx)), "uu_dagger")


def zz_feature_map(
    builder: CircuitBuilder, x: NDArray[np.float64], reps: int = 2
) -> CircuitBuilder:
    """Append Qiskit's ``zz_feature_map(2, reps)`` for features ``x`` of shape ``(B, 2)``.

    Each repetition: ``H`` on both qubits, ``P(2 x_i)`` on qubit ``i``, then
    ``CX(0, 1) P(2 (pi - x_0)(pi - x_1)) CX(0, 1)`` (Havlicek et al., Nature 567, 2019).
    """
    x0, x1 = x[:, 0], x[:, 1]
    pair = 2.0 * (np.pi - x0) * (np.pi - x1)
    for _ in range(reps):
        builder.h(0).h(1).p(0, 2.0 * x0).p(1, 2.0 * x1).cx(0, 1).p(1, pair).cx(0, 1)
    return builder


def real_amplitudes(
    builder: CircuitBuilder, weights: NDArray[np.float64], reps: int = 1
) -> CircuitBuilder:
    """Append Qiskit's ``real_amplitudes(2, reps)``: RY layers joined by ``CX(0, 1)``.

    ``weights`` has shape ``(2 (reps + 1),)`` (shared) or ``(B, 2 (reps + 1))``.
    """
    w = np.asarray(weights, dtype=np.float64)
    n = 2 * (reps + 1)
    if w.shape[-1] != n:
        raise ParameterError("weights", f"shape {w.shape}", f"{n} angles for reps={reps}")
    for r in range(reps + 1):
        if r:
            builder.cx(0, 1)
        builder.ry(0, w[..., 2 * r]).ry(1, w[..., 2 * r + 1])
    return builder


def feature_pairs(x: ArrayLike) -> NDArray[np.float64]:
    """The VQC's input as a float array of shape ``(B, 2)``; one pair may be given flat."""
    xa = np.atleast_2d(np.asarray(x, dtype=np.float64))
    if xa.ndim != 2 or xa.shape[1] != 2:
        raise ParameterError("x", f"shape {np.shape(x)}", "two features per sample, shape (B, 2)")
    return xa


def vqc_circuit(
    x: ArrayLike, weights: ArrayLike, *, feature_map_reps: int = 2, ansatz_reps: int = 1
) -> CircuitBatch:
    """The paper's 2-qubit VQC circuit: ZZ feature map then RealAmplitudes ansatz.

    Parameters
    ----------
    x : array_like, shape (B, 2)
        Features (the two lane slopes, already scaled).
    weights : array_like, shape (2 (ansatz_reps + 1),) or (B, 2 (ansatz_reps + 1))
        Ansatz angles in Qiskit's parameter order.
    """
    xa = feature_pairs(x)
    builder = CircuitBuilder(2, xa.shape[0])
    zz_feature_map(builder, xa, feature_map_reps)
    real_amplitudes(builder, np.asarray(weights, dtype=np.float64), ansatz_reps)
    return builder.build("vqc")
