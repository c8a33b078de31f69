"""A real device's calibrated noise, read offline from an IBM fake backend.

:meth:`DeviceNoise.from_backend` reads the calibration that ships with
``qiskit_ibm_runtime.fake_provider`` (``FakeManilaV2`` and the others; no network) and
builds the errors qiskit-aer's ``NoiseModel.from_backend`` builds, with qiskit-aer's own
functions (``basic_device_gate_errors`` and ``basic_device_readout_errors``):

* after every native gate (``sx``, ``x`` and the two-qubit ``cx``, ``ecr`` or ``cz``) on
  its physical qubit(s): a depolarizing error composed with thermal relaxation from the
  qubits' ``T1``, ``T2`` (truncated to ``2 T1``) and the gate's duration, the depolarizing
  strength chosen so that the composition has the calibrated gate error (no depolarizing
  part when relaxation alone exceeds it); two-qubit gates get a two-qubit depolarizing
  error and one relaxation per qubit. ``rz`` is virtual: zero duration, no error (as in
  the calibration and in Aer's model);
* at measurement, each qubit's readout confusion matrix. By default it is asymmetric,
  ``P(1|0) = prob_meas1_prep0`` and ``P(0|1) = prob_meas0_prep1`` from the backend's
  properties (what the fake backend's own ``run`` simulates); ``readout="symmetric"``
  uses the target's single readout error for both, which is what
  ``NoiseModel.from_backend(backend)`` builds.

Each error becomes Kraus operators (``qiskit.quantum_info.Kraus``), applied by qdcnn's
batched simulators through the :class:`qdcnn.quantum.noise.GateNoise` protocol.

Running a qdcnn circuit on a device (:meth:`DeviceNoise.prepare`)
-----------------------------------------------------------------
*Native gates.* Every gate is rewritten into ``rz``, ``sx``, ``x`` and the device's
two-qubit gate with the same rules Qiskit's transpiler applies at ``optimization_level=0``
(checked in the tests), so the noisy gates are the ones a transpiled circuit has; angles
stay per-circuit arrays (one rewrite for the whole batch, no per-circuit transpile);
``rz`` gates next to each other on a qubit are merged (they are noise-free), and global
phases are dropped:

=============  ==========================================================
qdcnn gate     native gates, in time order
=============  ==========================================================
``rz(a)``      ``rz(a)``; ``p(a)`` the same (a global phase apart)
``ry(a)``      ``sx, rz(a + pi), sx, rz(3 pi)``
``rx(a)``      ``rz(pi/2), sx, rz(a + pi), sx, rz(5 pi/2)``
``h``          ``rz(pi/2), sx, rz(pi/2)``
``x``, ``sx``  themselves; ``y``: ``rz(pi), x``; ``z``: ``rz(pi)``
``cx(c, t)``   cx devices: ``cx`` if the device couples ``c -> t``, else
               ``H H cx(t, c) H H``; cz devices: ``h(t), cz, h(t)``; ecr
               devices: ``rz(-pi/2)`` on ``c``, ``rz(pi) sx rz(pi)`` on
               ``t``, ``ecr(c, t)``, ``x`` on ``c`` (or Qiskit's longer
               form around ``ecr(t, c)``)
``cz(c, t)``   ``cz`` on cz devices, else ``h(t), cx(c, t), h(t)``
=============  ==========================================================

*Layout.* Logical qubit ``i`` runs on physical qubit ``layout[i]``. By default
(``placement="best"``) the layout is, among the placements in which every two-qubit gate
of the circuit is between coupled qubits and each qubit with no two-qubit partner among
the lower-numbered ones is coupled to the previous qubit (so a chain when nothing else
constrains it), the one of least estimated error: the sum over logical qubits of its
noisy native one-qubit gates times the physical qubit's ``sx`` error plus its mean readout
error, and over coupled pairs of their two-qubit gates times the pair's error; ties go to
the lexicographically smallest, so the choice is deterministic. (Qubit 0 of
``FakeTorino`` reads out wrong 17 % of the time; this keeps circuits off such qubits, as a
noise-aware transpiler would.) ``placement="first"`` takes the lexicographically smallest
placement instead: ``[0]`` for the UU-dagger circuit and ``[0, 1]`` for the VQC on
``FakeManilaV2``. A ring of ``cx`` gets a ring when the device has one
(``FakeMelbourneV2`` has squares). When no placement couples every two-qubit gate (a
4-qubit CNOT ring on a line device such as ``FakeManilaV2``), the layout is the best (or
first) chain and the uncoupled ``cx`` is an error, unless ``route="swap"``: it then runs
through SWAPs (three ``cx`` each) along the shortest path inside the layout, the ``cx``,
and the SWAPs undone, so the circuit keeps its qubit order and pays the noise of every
extra gate. Qiskit's router would permute qubits instead of undoing; that choice is not
modelled.

What device noise leaves out: crosstalk between simultaneous gates and spectator qubits,
leakage out of the qubit space, non-Markovian (drifting, correlated) noise, coherent
over-rotation errors, idle relaxation of qubits waiting for others (the model adds no
noise to qubits a gate does not touch; ``delay`` is not used), state-preparation error
and measurement-induced dephasing, calibration drift since the snapshot was taken, and
queueing and run-time (see :mod:`qdcnn.quantum.hardware_time` for time estimates).
"""

from __future__ import annotations

import contextlib
import math
from collections import deque
from dataclasses import dataclass, field, replace
from functools import lru_cache
from itertools import pairwise
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._optional import require
from qdcnn.errors import ParameterError
from qdcnn.quantum.circuits import CircuitBatch, Gate
from qdcnn.quantum.noise import Channel, Kraus, NoiseSpec

#: the one-qubit native gates qdcnn circuits are rewritten into
_NATIVE_ONE_QUBIT: tuple[str, ...] = ("rz", "sx", "x")
#: the two-qubit native gates a device may have (one of them)
_NATIVE_TWO_QUBIT: tuple[str, ...] = ("cx", "ecr", "cz")
_ROUTES: tuple[str, ...] = ("none", "swap")
_PLACEMENTS: tuple[str, ...] = ("best", "first")
_READOUT_MODELS: tuple[str, ...] = ("asymmetric", "symmetric", "none")
#: placement steps the default layout search takes at most (then: the best found so far)
_LAYOUT_SEARCH_BUDGET = 200_000

_TWO_QUBIT = frozenset({"cx", "cz"})


def _available_backends() -> list[str]:
    """Names of the offline fake backends of ``qiskit_ibm_runtime.fake_provider``."""
    fake_provider = require("qiskit_ibm_runtime", "device noise").fake_provider
    from qiskit_ibm_runtime.fake_provider.fake_backend import FakeBackendV2

    return sorted(
        name
        for name in dir(fake_provider)
        if isinstance(cls := getattr(fake_provider, name), type)
        and issubclass(cls, FakeBackendV2)
        and cls is not FakeBackendV2
    )


def _backend_class_name(name: str) -> str:
    names = _available_backends()
    by_lower = {n.lower(): n for n in names}
    if name.lower() not in by_lower:
        raise ParameterError("device", name, f"an IBM fake backend, one of {', '.join(names)}")
    return by_lower[name.lower()]


@dataclass(frozen=True, eq=False)
class DeviceCalibration:
    """A fake backend's calibration and the errors built from it (physical qubits).

    Attributes
    ----------
    name : str
        Class name in ``qiskit_ibm_runtime.fake_provider``, e.g. ``FakeManilaV2``.
    num_qubits : int
        Physical qubits of the device.
    two_qubit_gate : str
        The device's native two-qubit gate: ``cx``, ``ecr`` or ``cz`` (``""`` for one qubit).
    coupling : frozenset of (int, int)
        Directed pairs ``(first, second)`` that have the native two-qubit gate.
    t1, t2 : tuple of float or None
        Per physical qubit, in seconds (as calibrated; the model truncates ``T2`` to
        ``2 T1``).
    durations, gate_errors : dict
        ``(gate, physical qubits) -> seconds`` and ``-> error`` (1 - average gate fidelity)
        for the native gates.
    readout_p1_given_0, readout_p0_given_1 : tuple of float
        Per physical qubit, the readout errors the model uses.
    readout : dict
        ``physical qubit -> A[measured, prepared]``.
    aer_errors : dict
        ``(gate, physical qubits) -> QuantumError`` built by qiskit-aer; :meth:`channel` gives
        its Kraus operators.
    backend : object
        The fake backend instance.
    """

    name: str
    num_qubits: int
    two_qubit_gate: str
    coupling: frozenset[tuple[int, int]]
    t1: tuple[float | None, ...]
    t2: tuple[float | None, ...]
    durations: dict[tuple[str, tuple[int, ...]], float]
    gate_errors: dict[tuple[str, tuple[int, ...]], float]
    readout_p1_given_0: tuple[float, ...]
    readout_p0_given_1: tuple[float, ...]
    readout: dict[int, NDArray[np.float64]] = field(repr=False)
    aer_errors: dict[tuple[str, tuple[int, ...]], Any] = field(repr=False)
    backend: Any = field(repr=False)
    _kraus: dict[tuple[str, tuple[int, ...]], Kraus] = field(
        default_factory=dict, repr=False, init=False
    )

    @property
    def native_gates(self) -> tuple[str, ...]:
        """``rz``, ``sx``, ``x`` and the two-qubit gate."""
        return _NATIVE_ONE_QUBIT + ((self.two_qubit_gate,) if self.two_qubit_gate else ())

    def channel(self, gate: str, qubits: tuple[int, ...]) -> Kraus | None:
        """Kraus operators of the error after ``gate`` on physical ``qubits`` (``None``: none).

        ``qubits[0]`` is the least significant bit of the operators. Converted once, on
        first use, and returned read-only (the same array every time).
        """
        key = (gate, qubits)
        ops = self._kraus.get(key)
        if ops is None and key in self.aer_errors:
            ops = self._kraus[key] = _kraus_of(self.aer_errors[key])
        return ops

    def neighbours(self, q: int) -> list[int]:
        """Physical qubits coupled to ``q`` in either direction, ascending."""
        return sorted(
            {b for a, b in self.coupling if a == q} | {a for a, b in self.coupling if b == q}
        )

    def coupled(self, a: int, b: int) -> bool:
        """Whether a ``cx`` exists between ``a`` and ``b`` in either direction."""
        return (a, b) in self.coupling or (b, a) in self.coupling

    def qubit_table(self, qubits: tuple[int, ...] | None = None) -> list[dict[str, Any]]:
        """One row per physical qubit: T1, T2 (us), sx error and duration (ns), readout errors."""
        rows = []
        for q in range(self.num_qubits) if qubits is None else qubits:
            t1, t2 = self.t1[q], self.t2[q]
            rows.append(
                {
                    "qubit": q,
                    "t1_us": None if t1 is None else t1 * 1e6,
                    "t2_us": None if t2 is None else t2 * 1e6,
                    "sx_error": self.gate_errors.get(("sx", (q,))),
                    "sx_ns": _ns(self.durations.get(("sx", (q,)))),
                    "readout_p1_given_0": self.readout_p1_given_0[q],
                    "readout_p0_given_1": self.readout_p0_given_1[q],
                }
            )
        return rows


def _ns(seconds: float | None) -> float | None:
    return None if seconds is None else seconds * 1e9


def _kraus_of(error: Any) -> Kraus:
    info = require("qiskit", "device noise").quantum_info
    ops = np.ascontiguousarray(np.stack(info.Kraus(error).data), dtype=np.complex128)
    ops.setflags(write=False)
    return ops


def _readout_errors(backend: Any, model: str) -> list[tuple[list[int], Any]]:
    from qiskit_aer.noise.device.models import basic_device_readout_errors

    if model == "none":
        return []
    if model == "asymmetric":
        properties = backend.properties()
        if properties is not None:
            return list(basic_device_readout_errors(properties=properties))
    return list(basic_device_readout_errors(target=backend.target))


def _native_two_qubit_gates(backend: Any, class_name: str) -> list[str]:
    """The backend's native two-qubit gate (a list of one; none on a one-qubit device),
    refusing a backend without native ``rz``, ``sx``, ``x`` and exactly one of ``cx``,
    ``ecr``, ``cz``."""
    ops = set(backend.target.operation_names)
    two_qubit = [g for g in _NATIVE_TWO_QUBIT if g in ops]
    if (
        any(g not in ops for g in _NATIVE_ONE_QUBIT)
        or len(two_qubit) > 1
        or (backend.num_qubits > 1 and not two_qubit)
    ):
        raise ParameterError(
            "device",
            class_name,
            "a backend with native rz, sx, x and one of cx, ecr, cz (this one has "
            f"{', '.join(sorted(ops))})",
        )
    return two_qubit


_GateTable = dict[tuple[str, tuple[int, ...]], float]


def _gate_properties(target: Any, native: tuple[str, ...]) -> tuple[_GateTable, _GateTable]:
    """Duration (seconds) and error of every calibrated native gate, by ``(gate, qubits)``."""
    ops = set(target.operation_names)
    durations: _GateTable = {}
    gate_errs: _GateTable = {}
    for g in native:
        for qargs, prop in target[g].items() if g in ops else ():
            if prop is not None and qargs is not None:
                durations[(g, tuple(qargs))] = float(prop.duration or 0.0)
                gate_errs[(g, tuple(qargs))] = float(prop.error or 0.0)
    return durations, gate_errs


def _readout_matrices(backend: Any, model: str) -> dict[int, NDArray[np.float64]]:
    """Read-only ``A[measured, prepared]`` per qubit of the readout ``model`` (none: empty)."""
    readout_mats = {
        int(q[0]): np.asarray(err.probabilities, dtype=np.float64).T
        for q, err in _readout_errors(backend, model)
    }
    for a in readout_mats.values():
        a.setflags(write=False)
    return readout_mats


@lru_cache(maxsize=16)
def load_calibration(
    name: str,
    readout: str = "asymmetric",
    gate_error: bool = True,
    thermal_relaxation: bool = True,
) -> DeviceCalibration:
    """Read fake backend ``name``'s calibration and build its errors (cached; read-only).

    Large devices take a few seconds (qiskit-aer builds the errors of every gate on
    every qubit: 4-13 s measured for 127-133 qubits here); the Kraus operators are converted per
    gate on first use.

    Raises
    ------
    ParameterError
        For an unknown backend (the message lists them) or one without native ``rz``,
        ``sx``, ``x`` and one of ``cx``, ``ecr``, ``cz``.
    """
    if readout not in _READOUT_MODELS:
        raise ParameterError("readout", readout, f"one of {', '.join(_READOUT_MODELS)}")
    class_name = _backend_class_name(name)
    require("qiskit_aer", "device noise")
    from qiskit_aer.noise.device.models import basic_device_gate_errors

    fake_provider = require("qiskit_ibm_runtime", "device noise").fake_provider
    backend = getattr(fake_provider, class_name)()
    target = backend.target
    two_qubit = _native_two_qubit_gates(backend, class_name)
    gate2 = two_qubit[0] if two_qubit else ""
    native = (*_NATIVE_ONE_QUBIT, *two_qubit)
    errors = basic_device_gate_errors(
        target=target, gate_error=gate_error, thermal_relaxation=thermal_relaxation
    )
    aer_errors = {(g, tuple(q)): e for g, q, e in errors if g in native}
    durations, gate_errs = _gate_properties(target, native)
    coupling = frozenset(tuple(q) for q in target[gate2] if q is not None) if gate2 else frozenset()
    readout_mats = _readout_matrices(backend, readout)
    props = target.qubit_properties or [None] * backend.num_qubits
    return DeviceCalibration(
        name=class_name,
        num_qubits=int(backend.num_qubits),
        two_qubit_gate=gate2,
        coupling=coupling,
        t1=tuple(getattr(p, "t1", None) for p in props),
        t2=tuple(getattr(p, "t2", None) for p in props),
        durations=durations,
        gate_errors=gate_errs,
        readout_p1_given_0=tuple(
            float(readout_mats[q][1, 0]) if q in readout_mats else 0.0
            for q in range(backend.num_qubits)
        ),
        readout_p0_given_1=tuple(
            float(readout_mats[q][0, 1]) if q in readout_mats else 0.0
            for q in range(backend.num_qubits)
        ),
        readout=readout_mats,
        aer_errors=aer_errors,
        backend=backend,
    )


# ------------------------------------------------------------------ layout


def _cx_partners(circuit: CircuitBatch) -> list[set[int]]:
    partners: list[set[int]] = [set() for _ in range(circuit.num_qubits)]
    for g in circuit.gates:
        if g.name in _TWO_QUBIT:
            a, b = g.qubits
            partners[a].add(b)
            partners[b].add(a)
    return partners


class _BudgetSpent(Exception):
    """The placement search ran out of its budget; the best placement so far stands."""


#: noisy native one-qubit gates each qdcnn gate becomes (module docstring's table)
_NATIVE_1Q_COST = {"ry": 2, "rx": 2, "h": 1, "x": 1, "y": 1, "sx": 1}


@dataclass(frozen=True)
class _LayoutCost:
    """Estimated error of a placement: gate errors times gate counts, plus readout errors."""

    one_qubit: tuple[int, ...]  # noisy native 1q gates per logical qubit
    two_qubit: dict[tuple[int, int], int]  # 2q gates per logical pair (a < b)

    @classmethod
    def of(cls, circuit: CircuitBatch) -> _LayoutCost:
        ones = [0] * circuit.num_qubits
        twos: dict[tuple[int, int], int] = {}
        for g in circuit.gates:
            if len(g.qubits) == 2:
                a, b = sorted(g.qubits)
                twos[(a, b)] = twos.get((a, b), 0) + 1
            else:
                ones[g.qubits[0]] += _NATIVE_1Q_COST.get(g.name, 0)
        return cls(tuple(ones), twos)

    def qubit(self, i: int, p: int, cal: DeviceCalibration) -> float:
        """Cost of logical qubit ``i`` on physical ``p``: its 1q gates and its readout."""
        ro = cal.readout.get(p)
        readout = 0.0 if ro is None else float(ro[1, 0] + ro[0, 1]) / 2
        return self.one_qubit[i] * cal.gate_errors.get(("sx", (p,)), 0.0) + readout

    def pair(self, i: int, j: int, pi: int, pj: int, cal: DeviceCalibration) -> float:
        """Cost of the 2q gates between logical ``i`` and ``j`` on physical ``pi``, ``pj``."""
        count = self.two_qubit.get((min(i, j), max(i, j)), 0)
        if not count:
            return 0.0
        g = cal.two_qubit_gate
        errors = [
            cal.gate_errors[(g, q)] for q in ((pi, pj), (pj, pi)) if (g, q) in cal.gate_errors
        ]
        return count * min(errors, default=0.0)


def _search_placement(
    must_touch: list[list[int]],
    cal: DeviceCalibration,
    budget: int,
    cost: _LayoutCost | None,
) -> tuple[int, ...] | None:
    """An injective placement with ``layout[i]`` coupled to ``layout[j]`` for every ``j`` in
    ``must_touch[i]`` (all ``j < i``), ``None`` if there is none.

    ``cost=None``: the lexicographically smallest. Otherwise the one of least ``cost``
    (branch and bound in lexicographic order, so ties go to the smallest), among those
    seen within ``budget`` placement steps.
    """
    n = len(must_touch)
    adj = [set(cal.neighbours(q)) for q in range(cal.num_qubits)]
    placed: list[int] = []
    best: tuple[float, tuple[int, ...] | None] = (math.inf, None)
    steps = 0

    def extra(i: int, c: int) -> float:
        if cost is None:
            return 0.0
        return cost.qubit(i, c, cal) + sum(cost.pair(i, j, c, placed[j], cal) for j in range(i))

    def place(i: int, so_far: float) -> bool:
        nonlocal steps, best
        if i == n:
            if so_far < best[0]:
                best = (so_far, tuple(placed))
            return cost is None  # the first complete placement is the answer
        if i == 0:
            candidates: list[int] = list(range(cal.num_qubits))
        else:
            common = set.intersection(*(adj[placed[j]] for j in must_touch[i]))
            candidates = sorted(common - set(placed))
        for c in candidates:
            steps += 1
            if steps > budget:
                raise _BudgetSpent
            total = so_far + extra(i, c)
            if total >= best[0]:
                continue
            placed.append(c)
            if place(i + 1, total):
                return True
            placed.pop()
        return False

    with contextlib.suppress(_BudgetSpent):
        place(0, 0.0)
    return best[1]


def default_layout(
    circuit: CircuitBatch, cal: DeviceCalibration, placement: str = "best"
) -> tuple[int, ...]:
    """The layout :meth:`DeviceNoise.prepare` uses when none is given (module docstring).

    ``placement="best"``: of the placements that couple every two-qubit gate (each qubit
    without a partner among lower ones coupled to the previous qubit), the one of least
    estimated error; ``"first"``: the lexicographically smallest.
    """
    if placement not in _PLACEMENTS:
        raise ParameterError("placement", placement, f"one of {', '.join(_PLACEMENTS)}")
    n = circuit.num_qubits
    if n > cal.num_qubits:
        raise ParameterError(
            "circuit", f"{n} qubits", f"at most {cal.num_qubits} qubits on {cal.name}"
        )
    cost = _LayoutCost.of(circuit) if placement == "best" else None
    partners = _cx_partners(circuit)
    coupled = [sorted(j for j in partners[i] if j < i) or ([i - 1] if i else []) for i in range(n)]
    found = _search_placement(coupled, cal, _LAYOUT_SEARCH_BUDGET, cost)
    if found is None:
        chain = [[i - 1] if i else [] for i in range(n)]
        found = _search_placement(chain, cal, _LAYOUT_SEARCH_BUDGET, cost)
    if found is None:
        raise ParameterError(
            "layout", None, f"a chain of {n} coupled qubits, which {cal.name} lacks: give a layout"
        )
    return found


def _check_layout(layout: object, cal: DeviceCalibration) -> tuple[int, ...]:
    """Return ``layout`` as a tuple of distinct physical qubits of ``cal``, else raise."""
    try:
        out = tuple(int(q) for q in layout)  # type: ignore[attr-defined]
        ok = all(float(q) == int(q) for q in layout)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        ok = False
    if not ok or not out or len(set(out)) != len(out):
        raise ParameterError("layout", layout, "distinct physical qubit indices")
    if not all(0 <= q < cal.num_qubits for q in out):
        raise ParameterError("layout", layout, f"qubits in [0, {cal.num_qubits - 1}] on {cal.name}")
    return out


# ------------------------------------------------------------------ native gates


class _NativeEmitter:
    """Collects native gates; keeps ``rz`` angles pending per qubit and merges them."""

    def __init__(self, merge_rz: bool) -> None:
        self.gates: list[Gate] = []
        self.merge_rz = merge_rz
        self.pending: dict[int, NDArray[np.float64]] = {}

    def rz(self, q: int, angle: NDArray[np.float64] | float) -> None:
        a = np.asarray(angle, dtype=np.float64)
        if not self.merge_rz:
            self.gates.append(Gate("rz", (q,), a))
        elif q in self.pending:
            self.pending[q] = self.pending[q] + a
        else:
            self.pending[q] = a

    def gate(self, name: str, qubits: tuple[int, ...]) -> None:
        for q in qubits:
            self._flush(q)
        self.gates.append(Gate(name, qubits))

    def _flush(self, q: int) -> None:
        a = self.pending.pop(q, None)
        if a is not None and not (a.ndim == 0 and a == 0.0):
            self.gates.append(Gate("rz", (q,), a))

    def finish(self) -> list[Gate]:
        for q in sorted(self.pending):
            self._flush(q)
        return self.gates


_PI = np.pi


def _lower_one_qubit(e: _NativeEmitter, g: Gate) -> None:
    q = g.qubits[0]
    a = g.angle
    if g.name in ("rz", "p"):
        assert a is not None
        e.rz(q, a)
    elif g.name in ("ry", "rx"):
        assert a is not None
        if g.name == "rx":
            e.rz(q, _PI / 2)
        e.gate("sx", (q,))
        e.rz(q, a + _PI)
        e.gate("sx", (q,))
        e.rz(q, 3 * _PI if g.name == "ry" else 5 * _PI / 2)
    elif g.name == "h":
        e.rz(q, _PI / 2)
        e.gate("sx", (q,))
        e.rz(q, _PI / 2)
    elif g.name in ("x", "sx"):
        e.gate(g.name, (q,))
    elif g.name == "y":
        e.rz(q, _PI)
        e.gate("x", (q,))
    elif g.name == "z":
        e.rz(q, _PI)
    elif g.name == "rot":  # Rot(phi, theta, omega) = RZ(omega) RY(theta) RZ(phi)
        assert a is not None
        for name, k in (("rz", 0), ("ry", 1), ("rz", 2)):
            _lower_one_qubit(e, Gate(name, (q,), a[..., k]))
    else:
        raise ParameterError(
            "gate", g.name, "a gate with a native decomposition (see qdcnn.quantum.device)"
        )


class _Lowering:
    """Rewrites one circuit's gates into native gates on a layout of ``cal``."""

    def __init__(self, cal: DeviceCalibration, layout: tuple[int, ...], route: str) -> None:
        self.cal, self.layout, self.route = cal, layout, route
        self.logical = {p: i for i, p in enumerate(layout)}
        self.e = _NativeEmitter(merge_rz=not any(k[0] == "rz" for k in cal.aer_errors))

    def h(self, q: int) -> None:
        _lower_one_qubit(self.e, Gate("h", (q,)))

    def cx(self, c: int, t: int) -> None:
        pc, pt = self.layout[c], self.layout[t]
        gate2 = self.cal.two_qubit_gate
        if (pc, pt) in self.cal.coupling or (pt, pc) in self.cal.coupling:
            forward = (pc, pt) in self.cal.coupling
            if gate2 == "cx" and forward:
                self.e.gate("cx", (c, t))
            elif gate2 == "cx":
                self._h_pair(c, t)
                self.e.gate("cx", (t, c))
                self._h_pair(c, t)
            elif gate2 == "cz":
                self.h(t)
                self.e.gate("cz", (c, t) if forward else (t, c))
                self.h(t)
            else:
                self._ecr_cx(c, t, forward)
        elif self.route == "swap":
            self._routed_cx(c, t)
        else:
            raise ParameterError(
                "layout",
                self.layout,
                f"coupled physical qubits for every cx: cx({c}, {t}) runs on ({pc}, {pt}), not "
                f"coupled on {self.cal.name}; give a layout that couples them, use route "
                "'swap' (route:swap), or a device whose coupling has the circuit's cx graph",
            )

    def _ecr_cx(self, c: int, t: int, forward: bool) -> None:
        """``cx(c, t)`` from an ``ecr`` on ``(c, t)`` or ``(t, c)``, as Qiskit translates it."""
        e, half = self.e, _PI / 2
        if forward:
            e.rz(c, -half)
            e.rz(t, _PI)
            e.gate("sx", (t,))
            e.rz(t, _PI)
            e.gate("ecr", (c, t))
            e.gate("x", (c,))
            return
        e.rz(c, 0.0)
        e.gate("sx", (c,))
        e.rz(c, -half)
        e.rz(t, _PI)
        e.gate("sx", (t,))
        e.rz(t, half)
        e.gate("sx", (t,))
        e.rz(t, half)
        e.gate("ecr", (t, c))
        self.h(c)
        e.gate("x", (c,))
        self.h(t)

    def _coupled(self, a: int, b: int) -> bool:
        return self.cal.coupled(self.layout[a], self.layout[b])

    def _h_pair(self, a: int, b: int) -> None:
        self.h(a)
        self.h(b)

    def swap(self, a: int, b: int) -> None:
        self.cx(a, b)
        self.cx(b, a)
        self.cx(a, b)

    def _routed_cx(self, c: int, t: int) -> None:
        path = self._path(self.layout[c], self.layout[t])
        hops = [(self.logical[u], self.logical[v]) for u, v in pairwise(path[:-1])]
        for a, b in hops:
            self.swap(a, b)
        self.cx(self.logical[path[-2]], t)
        for a, b in reversed(hops):
            self.swap(a, b)

    def _path(self, start: int, goal: int) -> list[int]:
        allowed = set(self.layout)
        previous: dict[int, int] = {start: start}
        queue = deque([start])
        while queue:
            u = queue.popleft()
            if u == goal:
                break
            for v in self.cal.neighbours(u):
                if v in allowed and v not in previous:
                    previous[v] = u
                    queue.append(v)
        if goal not in previous:
            raise ParameterError(
                "layout", self.layout, f"a connected layout on {self.cal.name} to route cx by SWAPs"
            )
        path = [goal]
        while path[-1] != start:
            path.append(previous[path[-1]])
        return path[::-1]

    def run(self, gates: tuple[Gate, ...]) -> list[Gate]:
        for g in gates:
            if g.name == "cx":
                self.cx(*g.qubits)
            elif g.name == "cz" and self.cal.two_qubit_gate == "cz" and self._coupled(*g.qubits):
                self.e.gate("cz", g.qubits)
            elif g.name == "cz":
                c, t = g.qubits
                self.h(t)
                self.cx(c, t)
                self.h(t)
            elif len(g.qubits) == 1:
                _lower_one_qubit(self.e, g)
            else:
                raise ParameterError("gate", g.name, "a gate with a native decomposition")
        return self.e.finish()


def to_native(
    circuit: CircuitBatch, cal: DeviceCalibration, layout: tuple[int, ...], route: str = "none"
) -> CircuitBatch:
    """``circuit`` in ``cal``'s native gates (``rz``, ``sx``, ``x``, two-qubit) on ``layout``.

    The result acts on the same logical qubits (qubit ``i`` on physical ``layout[i]``), with
    the same probabilities; see the module docstring for the rules.
    """
    gates = _Lowering(cal, layout[: circuit.num_qubits], route).run(circuit.gates)
    return CircuitBatch(circuit.num_qubits, circuit.batch_size, tuple(gates), circuit.name)


# ------------------------------------------------------------------ the noise object


@dataclass(frozen=True, kw_only=True)
class DeviceNoise(NoiseSpec):
    """A fake backend's calibrated noise; accepted wherever a :class:`NoiseSpec` is.

    Build it with :meth:`from_backend` (or ``parse_noise("device:FakeManilaV2")``). A
    simulator calls :meth:`prepare` on each circuit, which returns the circuit in native
    gates and a ``DeviceNoise`` bound to a layout; that one answers
    :meth:`channels_after` and :meth:`readout_matrices`.

    Attributes
    ----------
    device : str
        Fake backend class name, e.g. ``FakeManilaV2``.
    layout : tuple of int or None
        Physical qubit of each logical qubit (a circuit with fewer qubits uses the first
        entries); ``None``: :func:`default_layout` per circuit.
    placement : {"best", "first"}
        How :func:`default_layout` picks when ``layout`` is ``None``.
    route : {"none", "swap"}
        What an uncoupled ``cx`` does: raise, or run through SWAPs.
    readout_model : {"asymmetric", "symmetric", "none"}
        Readout confusion from ``prob_meas1_prep0``/``prob_meas0_prep1``, from the target's
        one readout error, or none.
    gate_error, thermal_relaxation : bool
        Include the depolarizing part and the thermal-relaxation part of the gate errors.
    calibration : DeviceCalibration
        The calibration and its Kraus operators.
    """

    channel: str | None = field(default=None, init=False)
    p: float = field(default=0.0, init=False)
    readout: float = field(default=0.0, init=False)
    device: str
    layout: tuple[int, ...] | None = None
    placement: str = "best"
    route: str = "none"
    readout_model: str = "asymmetric"
    gate_error: bool = True
    thermal_relaxation: bool = True
    calibration: DeviceCalibration = field(repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.route not in _ROUTES:
            raise ParameterError("route", self.route, f"one of {', '.join(_ROUTES)}")
        if self.placement not in _PLACEMENTS:
            raise ParameterError("placement", self.placement, f"one of {', '.join(_PLACEMENTS)}")
        if self.layout is not None:
            object.__setattr__(self, "layout", _check_layout(self.layout, self.calibration))

    def __deepcopy__(self, memo: dict[int, Any]) -> DeviceNoise:
        return self  # immutable, and its calibration is read-only (scikit-learn clones params)

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        # pickles as the backend name and options; unpickling reads the calibration again
        return (
            _rebuild,
            (
                self.device,
                self.layout,
                self.placement,
                self.route,
                self.readout_model,
                self.gate_error,
                self.thermal_relaxation,
            ),
        )

    @classmethod
    def from_backend(
        cls,
        name: str,
        *,
        layout: tuple[int, ...] | list[int] | None = None,
        placement: str = "best",
        route: str = "none",
        readout: str = "asymmetric",
        gate_error: bool = True,
        thermal_relaxation: bool = True,
    ) -> DeviceNoise:
        """Noise of fake backend ``name`` (e.g. ``"FakeManilaV2"``, any letter case).

        Needs the ``quantum`` extra (qiskit, qiskit-aer, qiskit-ibm-runtime); reads only
        files installed with qiskit-ibm-runtime.
        """
        cal = load_calibration(name, readout, bool(gate_error), bool(thermal_relaxation))
        return cls(
            device=cal.name,
            layout=None if layout is None else tuple(layout),
            placement=placement,
            route=route,
            readout_model=readout,
            gate_error=bool(gate_error),
            thermal_relaxation=bool(thermal_relaxation),
            calibration=cal,
        )

    @property
    def is_ideal(self) -> bool:
        return not self.calibration.aer_errors and not self.calibration.readout

    def kraus(self) -> Kraus | None:
        raise ParameterError(
            "noise",
            self.label(),
            "a single-channel NoiseSpec; device noise is per gate and "
            "qubit: use prepare() and channels_after()",
        )

    def readout_matrix(self) -> NDArray[np.float64]:
        raise ParameterError(
            "noise",
            self.label(),
            "a single-channel NoiseSpec; device readout is per qubit: use readout_matrices()",
        )

    def layout_for(self, circuit: CircuitBatch) -> tuple[int, ...]:
        """The physical qubits ``circuit``'s logical qubits run on."""
        if self.layout is None:
            return default_layout(circuit, self.calibration, self.placement)
        if len(self.layout) < circuit.num_qubits:
            raise ParameterError(
                "layout", self.layout, f"at least {circuit.num_qubits} qubits for this circuit"
            )
        return self.layout[: circuit.num_qubits]

    def prepare(self, circuit: CircuitBatch) -> tuple[CircuitBatch, DeviceNoise]:
        """The circuit in native gates on its layout, and this noise bound to that layout."""
        layout = self.layout_for(circuit)
        native = to_native(circuit, self.calibration, layout, self.route)
        return native, (self if self.layout == layout else replace(self, layout=layout))

    def _physical(self, qubits: tuple[int, ...]) -> tuple[int, ...]:
        if self.layout is None:
            raise ParameterError(
                "noise", self.label(), "a prepared DeviceNoise: call prepare(circuit) first"
            )
        return tuple(self.layout[q] for q in qubits)

    def channels_after(self, gate: Gate) -> list[Channel]:
        """The calibrated error of ``gate`` on its physical qubits (none for ``rz``)."""
        cal = self.calibration
        if gate.name not in cal.native_gates:
            raise ParameterError(
                "gate", gate.name, f"a native gate ({', '.join(cal.native_gates)}): prepare() first"
            )
        physical = self._physical(gate.qubits)
        ops = cal.channel(gate.name, physical)
        if ops is None and len(physical) == 2 and physical not in cal.coupling:
            raise ParameterError(
                f"{gate.name} qubits", physical, f"a coupled pair of {self.device}"
            )
        return [] if ops is None else [(gate.qubits, ops)]

    def readout_matrices(self, num_qubits: int) -> list[NDArray[np.float64]] | None:
        """Each logical qubit's ``A[measured, prepared]``: that of its physical qubit."""
        if not self.calibration.readout:
            return None
        eye = np.eye(2)
        return [
            self.calibration.readout.get(q, eye) for q in self._physical(tuple(range(num_qubits)))
        ]

    def label(self) -> str:
        parts = [f"device:{self.device}"]
        if self.layout is not None:
            parts.append("layout:" + "-".join(str(q) for q in self.layout))
        elif self.placement != "best":
            parts.append(f"layout:{self.placement}")
        if self.route != "none":
            parts.append(f"route:{self.route}")
        if self.readout_model != "asymmetric":
            parts.append(f"readout:{self.readout_model}")
        return ",".join(parts)


def _rebuild(
    device: str,
    layout: tuple[int, ...] | None,
    placement: str,
    route: str,
    readout: str,
    gate_error: bool,
    thermal_relaxation: bool,
) -> DeviceNoise:
    return DeviceNoise.from_backend(
        device,
        layout=layout,
        placement=placement,
        route=route,
        readout=readout,
        gate_error=gate_error,
        thermal_relaxation=thermal_relaxation,
    )


def parse_device_noise(text: str) -> DeviceNoise:
    """Parse ``device:NAME[,layout:0-1-2|best|first][,route:none|swap][,readout:MODEL]``.

    ``MODEL`` is ``asymmetric`` (default), ``symmetric`` or ``none``.

    Examples
    --------
    ``parse_device_noise("device:FakeManilaV2,layout:1-2")`` runs logical qubits 0 and 1 on
    physical qubits 1 and 2 of ``FakeManilaV2``.
    """
    options: dict[str, str] = {}
    for part in filter(None, (t.strip() for t in text.split(","))):
        key, sep, value = part.partition(":")
        if not sep or not value or key not in ("device", "layout", "route", "readout"):
            raise ParameterError(
                "noise",
                text,
                "device:NAME with optional ,layout:0-1-2 ,route:swap ,readout:symmetric "
                "(device noise does not combine with a channel)",
            )
        if key in options:
            raise ParameterError("noise", text, f"'{key}' given once")
        options[key] = value
    if "device" not in options:
        raise ParameterError("noise", text, "device:NAME, e.g. device:FakeManilaV2")
    layout = None
    placement = options.get("layout", "best")
    if placement not in _PLACEMENTS:
        try:
            layout = tuple(int(q) for q in placement.split("-"))
        except ValueError:
            raise ParameterError(
                "layout", placement, "physical qubits like 0-1-2, or best, or first"
            ) from None
        placement = "best"
    return DeviceNoise.from_backend(
        options["device"],
        layout=layout,
        placement=placement,
        route=options.get("route", "none"),
        readout=options.get("readout", "asymmetric"),
    )
