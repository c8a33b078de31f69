"""Circuits for a whole batch of parameter sets, in one small gate list.

A :class:`CircuitBatch` is a sequence of gates on ``num_qubits`` qubits in which
every rotation angle is an array with one entry per batch element, so ``B``
circuits of the same shape are one object. The NumPy simulators run it in one
pass; :mod:`qdcnn.quantum.qiskit_bridge` turns it into ``B`` Qiskit circuits.

A :class:`CircuitTemplate` is the same gate sequence with symbolic angles: each
angle is a slot in a parameter vector made of per-sample ``inputs`` followed by
``weights``. :meth:`CircuitTemplate.bind` turns it into a :class:`CircuitBatch`
for the NumPy simulators, Qiskit and export; the PyTorch simulator
(:mod:`qdcnn.quantum.torchsim`) evaluates the same template on tensors, so
gradients flow to the inputs and weights. A circuit is therefore written once.

Qubit 0 is the least significant bit of a basis-state index, as in Qiskit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from qdcnn._validation import check_shape
from qdcnn.errors import ParameterError
from qdcnn.quantum import gates

_ONE_QUBIT_PARAMETRIC = frozenset(gates.PARAMETRIC)
_ONE_QUBIT_CONSTANT = frozenset(gates.CONSTANT)
TWO_QUBIT = frozenset({"cx", "cz"})
GATE_NAMES = _ONE_QUBIT_PARAMETRIC | _ONE_QUBIT_CONSTANT | TWO_QUBIT


@dataclass(frozen=True)
class Gate:
    """One gate of a batched circuit.

    Attributes
    ----------
    name : str
        ``ry``, ``rx``, ``rz``, ``p`` (angle gates), ``rot`` (three angles), ``h``,
        ``x``, ``y``, ``z``, ``cx`` or ``cz``.
    qubits : tuple of int
        Target qubit, or ``(control, target)`` for ``cx`` (``cz`` is symmetric).
    angle : ndarray of float64 or None
        Shape ``(B,)`` (one angle per circuit) or ``()`` (shared); for ``rot``,
        ``(B, 3)`` or ``(3,)`` holding ``(phi, theta, omega)``. ``None`` for gates
        without an angle.
    """

    name: str
    qubits: tuple[int, ...]
    angle: NDArray[np.float64] | None = None

    @property
    def per_circuit(self) -> bool:
        """Whether the angles differ between circuits (an extra leading batch axis)."""
        return self.angle is not None and self.angle.ndim > _angle_ndim(self.name)

    def matrix(self) -> gates.Matrix:
        """Return the one-qubit matrix, shape ``(B, 2, 2)`` or ``(1, 2, 2)``."""
        if self.name in gates.PARAMETRIC:
            assert self.angle is not None
            batched = self.angle if self.per_circuit else self.angle[None]
            return gates.PARAMETRIC[self.name](batched)
        return gates.CONSTANT[self.name][None]

    def params(self, i: int) -> tuple[float, ...]:
        """The angles of circuit ``i`` (``()`` for gates without an angle)."""
        if self.angle is None:
            return ()
        a = self.angle[i] if self.per_circuit else self.angle
        return tuple(float(v) for v in np.atleast_1d(a))


def _angle_ndim(name: str) -> int:
    """Dimensions of one circuit's angle value: 1 for ``rot`` (three angles), else 0."""
    return 1 if gates.ANGLE_COUNT.get(name, 1) > 1 else 0


def _pick(gate: Gate, idx: NDArray[np.intp]) -> NDArray[np.float64] | None:
    return gate.angle[idx] if gate.angle is not None and gate.per_circuit else gate.angle


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
        picked = tuple(Gate(g.name, g.qubits, _pick(g, idx)) for g in self.gates)
        return CircuitBatch(self.num_qubits, int(idx.size), picked, self.name)

    def angles_of(self, i: int) -> list[float | None]:
        """The angle of each gate of circuit ``i`` (``None`` for angle-free gates).

        One number per gate, so a circuit with a ``rot`` gate has no such list: use
        :meth:`params_of`, which gives every gate's angles as a tuple.
        """
        if any(g.name == "rot" for g in self.gates):
            raise ParameterError("circuit", self.name, "no rot gate for angles_of (use params_of)")
        return [p[0] if p else None for p in self.params_of(i)]

    def params_of(self, i: int) -> list[tuple[float, ...]]:
        """The angles of circuit ``i``, one tuple per gate (``()`` for angle-free gates)."""
        return [g.params(i) for g in self.gates]

    def as_template(self) -> tuple[CircuitTemplate, NDArray[np.float64], NDArray[np.float64]]:
        """The circuit as a template with its angles: ``(template, inputs, weights)``.

        Per-circuit angles become ``inputs`` of shape ``(B, P_in)`` and shared angles
        ``weights`` of shape ``(P_w,)``, in gate order; ``template.bind(inputs, weights)``
        gives this batch back. This is how any batch runs on the PyTorch simulator.
        """
        per: list[NDArray[np.float64]] = []
        shared: list[NDArray[np.float64]] = []
        for g in self.gates:
            if g.angle is not None:
                a = g.angle.reshape(self.batch_size, -1) if g.per_circuit else g.angle.ravel()
                (per if g.per_circuit else shared).append(a)
        n_in = sum(a.shape[1] for a in per)
        builder = TemplateBuilder(self.num_qubits, n_in, sum(a.size for a in shared))
        next_in, next_w = 0, n_in
        for g in self.gates:
            k = 0 if g.angle is None else gates.ANGLE_COUNT[g.name]
            start = next_in if g.per_circuit else next_w
            builder.add(g.name, g.qubits, tuple(range(start, start + k)))
            if g.per_circuit:
                next_in += k
            else:
                next_w += k
        inputs = np.concatenate(per, axis=1) if per else np.zeros((self.batch_size, 0))
        weights = np.concatenate(shared) if shared else np.zeros(0)
        return builder.build(self.name), inputs, weights


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
        check_num_qubits(self.num_qubits)
        if self.batch_size < 1:
            raise ParameterError("batch_size", self.batch_size, "at least 1")

    def _angle(self, name: str, angle: ArrayLike) -> NDArray[np.float64]:
        a = np.asarray(angle, dtype=np.float64)
        k = _angle_ndim(name)
        count = gates.ANGLE_COUNT[name]
        one = (count,) if k else ()
        if a.shape not in (one, (self.batch_size, *one)):
            expected = f"shape {one}" if k else "a scalar"
            raise ParameterError(
                "angle",
                f"array of shape {a.shape}",
                f"{expected} or shape {(self.batch_size, *one)}",
            )
        _check_finite(a)
        return a

    def add(
        self, name: str, qubits: tuple[int, ...], angle: ArrayLike | None = None
    ) -> CircuitBuilder:
        """Append gate ``name`` on ``qubits`` with ``angle`` (for angle gates).

        ``rot`` takes its three angles ``(phi, theta, omega)`` as the last axis of
        ``angle``: shape ``(3,)`` (shared) or ``(B, 3)``.
        """
        qs = _check_gate(name, qubits, self.num_qubits)
        needs_angle = name in _ONE_QUBIT_PARAMETRIC
        if needs_angle != (angle is not None):
            raise ParameterError(f"{name} angle", angle, "an angle" if needs_angle else "no angle")
        self.gates.append(Gate(name, qs, None if angle is None else self._angle(name, angle)))
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

    def y(self, q: int) -> CircuitBuilder:
        return self.add("y", (q,))

    def z(self, q: int) -> CircuitBuilder:
        return self.add("z", (q,))

    def rot(self, q: int, phi: ArrayLike, theta: ArrayLike, omega: ArrayLike) -> CircuitBuilder:
        """Append ``Rot(phi, theta, omega) = RZ(omega) RY(theta) RZ(phi)`` (PennyLane's)."""
        angles = np.stack(
            np.broadcast_arrays(*(np.asarray(a, float) for a in (phi, theta, omega))), -1
        )
        return self.add("rot", (q,), angles)

    def cx(self, control: int, target: int) -> CircuitBuilder:
        return self.add("cx", (control, target))

    def cz(self, a: int, b: int) -> CircuitBuilder:
        return self.add("cz", (a, b))

    def cnot_ring(self, r: int = 1) -> CircuitBuilder:
        """Append :func:`cnot_ring` of range ``r`` on all qubits."""
        for control, target in cnot_ring(self.num_qubits, r):
            self.cx(control, target)
        return self

    def build(self, name: str = "circuit") -> CircuitBatch:
        return CircuitBatch(self.num_qubits, self.batch_size, tuple(self.gates), name)


def check_num_qubits(num_qubits: int, most: int = 12) -> int:
    """Return ``num_qubits`` if it is an integer in ``[1, most]``, else raise."""
    ok = isinstance(num_qubits, int | np.integer) and not isinstance(num_qubits, bool)
    if not ok or not 1 <= num_qubits <= most:
        raise ParameterError("num_qubits", num_qubits, f"1 to {most} qubits")
    return int(num_qubits)


def _check_gate(name: str, qubits: tuple[int, ...], num_qubits: int) -> tuple[int, ...]:
    """The qubits of gate ``name`` if the name is known and the qubits fit, else raise."""
    if name not in GATE_NAMES:
        raise ParameterError("gate", name, f"one of {sorted(GATE_NAMES)}")
    for q in qubits:
        if not 0 <= q < num_qubits:
            raise ParameterError("qubit", q, f"an index in [0, {num_qubits - 1}]")
    qs = tuple(int(q) for q in qubits)
    arity = 2 if name in TWO_QUBIT else 1
    if len(qs) != arity or len(set(qs)) != arity:
        raise ParameterError(f"{name} qubits", qubits, f"{arity} distinct qubit(s)")
    return qs


def cnot_ring(num_qubits: int, r: int = 1) -> list[tuple[int, int]]:
    """``(control, target)`` pairs of a CNOT ring: ``CX(i, (i + r) mod n)`` for ``i = 0..n-1``.

    The entangler of PennyLane's ``StronglyEntanglingLayers`` with range ``r``. Two
    qubits with ``r = 1`` give ``CX(0, 1) CX(1, 0)``, as PennyLane does; one qubit has
    no ring (an empty list), and ``r`` must be in ``[1, n - 1]`` otherwise.

    Examples
    --------
    >>> cnot_ring(4, 2)
    [(0, 2), (1, 3), (2, 0), (3, 1)]
    """
    if num_qubits == 1:
        return []
    if isinstance(r, bool) or not isinstance(r, int | np.integer) or not 1 <= r < num_qubits:
        raise ParameterError("r", r, f"an integer in [1, {num_qubits - 1}]")
    return [(i, (i + int(r)) % num_qubits) for i in range(num_qubits)]


@dataclass(frozen=True)
class TemplateGate:
    """One gate of a :class:`CircuitTemplate`: its angles are parameter slots.

    Attributes
    ----------
    name : str
        A gate of :data:`GATE_NAMES`.
    qubits : tuple of int
        As in :class:`Gate`.
    slots : tuple of int
        Indices into the parameter vector ``[inputs..., weights...]``: one per angle
        (three for ``rot``: ``phi, theta, omega``), none for angle-free gates.
    """

    name: str
    qubits: tuple[int, ...]
    slots: tuple[int, ...] = ()


@dataclass(frozen=True)
class CircuitTemplate:
    """A gate sequence whose angles are slots of ``num_inputs + num_weights`` parameters.

    Slots ``0 .. num_inputs - 1`` are the per-sample ``inputs``, the rest the
    ``weights``. A slot may appear in several gates (re-uploaded inputs).
    """

    num_qubits: int
    num_inputs: int
    num_weights: int
    gates: tuple[TemplateGate, ...] = ()
    name: str = "circuit"

    @property
    def num_params(self) -> int:
        return self.num_inputs + self.num_weights

    def bind(
        self, inputs: ArrayLike | None = None, weights: ArrayLike | None = None
    ) -> CircuitBatch:
        """Concrete circuits for ``inputs`` ``(B, num_inputs)`` and ``weights``.

        Each of them may be 1-D (shared by every circuit) or 2-D with one row per
        circuit; the batch size is the common number of rows (1 when both are 1-D).
        """
        params = self.parameter_matrix(inputs, weights)
        batch = params.shape[0]
        out = []
        for g in self.gates:
            angle = None
            if g.slots:
                col = params[:, list(g.slots)] if _angle_ndim(g.name) else params[:, g.slots[0]]
                angle = col if batch > 1 else col[0]
            out.append(Gate(g.name, g.qubits, angle))
        return CircuitBatch(self.num_qubits, batch, tuple(out), self.name)

    def parameter_matrix(
        self, inputs: ArrayLike | None = None, weights: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """``[inputs, weights]`` as one finite float array of shape ``(B, num_params)``."""
        parts = []
        for label, value, size in (
            ("inputs", inputs, self.num_inputs),
            ("weights", weights, self.num_weights),
        ):
            a = np.zeros((0,)) if value is None and size == 0 else np.asarray(value, np.float64)
            check_shape(label, a, f"{size}|B,{size}", f"({size},) or (B, {size})")
            parts.append(np.atleast_2d(a))
        rows = {p.shape[0] for p in parts if p.shape[0] != 1}
        if len(rows) > 1:
            raise ParameterError("inputs/weights", sorted(rows), "one batch size")
        batch = rows.pop() if rows else 1
        params = np.concatenate([np.broadcast_to(p, (batch, p.shape[1])) for p in parts], axis=1)
        _check_finite(params)
        return params


@dataclass
class TemplateBuilder:
    """Append gates with parameter slots to a :class:`CircuitTemplate`.

    Examples
    --------
    >>> t = TemplateBuilder(1, num_inputs=1, num_weights=1).ry(0, 0).ry(0, 1).build("uu")
    >>> t.bind([[0.5], [0.25]], [1.0]).params_of(1)
    [(0.25,), (1.0,)]
    """

    num_qubits: int
    num_inputs: int = 0
    num_weights: int = 0
    gates: list[TemplateGate] = field(default_factory=list)

    def __post_init__(self) -> None:
        check_num_qubits(self.num_qubits)
        for label, n in (("num_inputs", self.num_inputs), ("num_weights", self.num_weights)):
            if isinstance(n, bool) or not isinstance(n, int) or n < 0:
                raise ParameterError(label, n, "a non-negative integer")

    def add(
        self, name: str, qubits: tuple[int, ...], slots: tuple[int, ...] = ()
    ) -> TemplateBuilder:
        """Append gate ``name`` on ``qubits`` whose angles are parameters ``slots``."""
        qs = _check_gate(name, qubits, self.num_qubits)
        count = gates.ANGLE_COUNT.get(name, 0)
        n_params = self.num_inputs + self.num_weights
        if len(slots) != count or not all(
            isinstance(k, int) and not isinstance(k, bool) and 0 <= k < n_params for k in slots
        ):
            raise ParameterError(
                f"{name} slots", slots, f"{count} parameter indices in [0, {n_params - 1}]"
            )
        self.gates.append(TemplateGate(name, qs, tuple(slots)))
        return self

    def ry(self, q: int, slot: int) -> TemplateBuilder:
        return self.add("ry", (q,), (slot,))

    def rot(self, q: int, first_slot: int) -> TemplateBuilder:
        """``Rot`` with ``phi, theta, omega`` in slots ``first_slot .. first_slot + 2``."""
        return self.add("rot", (q,), (first_slot, first_slot + 1, first_slot + 2))

    def cx(self, control: int, target: int) -> TemplateBuilder:
        return self.add("cx", (control, target))

    def cnot_ring(self, r: int = 1) -> TemplateBuilder:
        return self.ring(r, "cx")

    def ring(self, r: int = 1, gate: str = "cx") -> TemplateBuilder:
        """The two-qubit ``gate`` on :func:`cnot_ring`'s pairs (``cz``: PennyLane's
        ``StronglyEntanglingLayers(..., imprimitive=qml.CZ)``)."""
        for pair in cnot_ring(self.num_qubits, r):
            self.add(gate, pair)
        return self

    def build(self, name: str = "circuit") -> CircuitTemplate:
        return CircuitTemplate(
            self.num_qubits, self.num_inputs, self.num_weights, tuple(self.gates), name
        )


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
    check_shape("weights", w, f"*,{n}", f"{n} angles for reps={reps}")
    for r in range(reps + 1):
        if r:
            builder.cx(0, 1)
        builder.ry(0, w[..., 2 * r]).ry(1, w[..., 2 * r + 1])
    return builder


def feature_pairs(x: ArrayLike) -> NDArray[np.float64]:
    """The VQC's input as a float array of shape ``(B, 2)``; one pair may be given flat."""
    xa = np.asarray(x, dtype=np.float64)
    check_shape("x", xa, "2|B,2", "two features per sample, shape (B, 2)")
    return np.atleast_2d(xa)


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
