"""``qdcnn circuit`` as a library call: one circuit's diagram, probabilities and OpenQASM 3.

:func:`inspect_circuit` builds the circuit a :class:`CircuitSpec` describes, runs it
(NumPy or Aer, exact or with shots, with or without noise) and optionally writes it as
OpenQASM 3. Probabilities are indexed by basis state with qubit 0 the least significant
bit, as in Qiskit; with ``noise`` the channel acts after every gate on every qubit it
touches.

Circuit kinds are a table (:data:`CIRCUIT_KINDS`): each names the spec fields it reads and
a builder from those fields to ``(circuit, parameters)``, so a new kind is one entry.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from qdcnn._validation import check_int, check_optional_shots, check_seed
from qdcnn.errors import ParameterError
from qdcnn.runtime.reporting import Reporter

if TYPE_CHECKING:
    from qdcnn.quantum.noise import NoiseSpec

__all__ = [
    "CIRCUIT_KINDS",
    "CircuitInspection",
    "CircuitKind",
    "CircuitSpec",
    "angle_list",
    "build_circuit",
    "inspect_circuit",
    "parse_angle",
]

_PI_TERM = re.compile(
    r"^\s*(?P<sign>[+-]?)\s*(?:(?P<num>\d+(?:\.\d*)?|\.\d+)\s*\*?\s*)?pi"
    r"\s*(?:/\s*(?P<den>\d+(?:\.\d*)?|\.\d+))?\s*$"
)
QASM_UNCHECKED_NOTE = (
    "OpenQASM 3 written without the read-back check: pip install qiskit-qasm3-import"
)


#: Largest angle accepted in radians (beyond it the circuit drawer cannot print the angle).
MAX_ANGLE = 1e6


def parse_angle(text: str, name: str) -> float:
    """An angle in radians: a number, or a multiple of pi (``pi/2``, ``-3pi/4``, ``2*pi``).

    Examples
    --------
    >>> parse_angle("-3pi/4", "theta") == -3 * math.pi / 4
    True
    """
    try:
        value = float(text)
    except ValueError:
        m = _PI_TERM.match(text)
        if m is None:
            raise ParameterError(name, text, "an angle in radians, e.g. 1.2 or pi/2") from None
        value = (-1.0 if m["sign"] == "-" else 1.0) * float(m["num"] or 1.0) * math.pi
        if m["den"] is not None:
            den = float(m["den"])
            if den == 0:
                raise ParameterError(name, text, "a non-zero denominator") from None
            value /= den
    if not math.isfinite(value) or abs(value) > MAX_ANGLE:
        raise ParameterError(name, text, f"a finite angle of at most {MAX_ANGLE:g} radians")
    return value


def angle_list(text: str, name: str, count: int | None = None) -> list[float]:
    """Comma-separated angles (:func:`parse_angle`), exactly ``count`` of them when given.

    Examples
    --------
    >>> angle_list("0, pi", "x", 2) == [0.0, math.pi]
    True
    """
    values = [parse_angle(t, name) for t in text.split(",") if t.strip()]
    if count is not None and len(values) != count:
        raise ParameterError(name, text, f"{count} comma-separated angles")
    return values


@dataclass(frozen=True)
class CircuitSpec:
    """What ``qdcnn circuit`` shows; checked on construction.

    Attributes
    ----------
    kind : str
        A key of :data:`CIRCUIT_KINDS`: ``"uu"`` (the UU-dagger fidelity test) or
        ``"vqc"`` (the 2-qubit VQC).
    theta_c, theta_x : str or None
        ``uu``: centroid and test-value angles (``1.2``, ``pi/2``).
    x, weights : str or None
        ``vqc``: the two feature-map angles ``X1,X2`` and the ansatz angles (2 (reps + 1)).
    feature_map_reps : int
        ``vqc``: repetitions of the ZZ feature map.
    noise : str or None
        ``CHANNEL:P[,readout:E]`` (:func:`qdcnn.quantum.noise_text.parse_noise`).
    shots : int or None
        Shot estimates (default: exact probabilities).
    backend : {"numpy", "aer"}
    seed : int
        Seed of the shots.
    qasm : path or None
        Write the circuit (measured) as OpenQASM 3 here.
    qubits, layers : int or None
        ``head``: the quantum head's qubits (1 to 8) and StronglyEntanglingLayers.
    reupload : bool
        ``head``: re-upload the encoding before every layer.
    model : path or None
        ``head``: take qubits, layers and weights from the quantum head of a saved hybrid
        direction model (``train-direction --method qdcnn-head``).
    """

    kind: str
    theta_c: str | None = None
    theta_x: str | None = None
    x: str | None = None
    weights: str | None = None
    feature_map_reps: int = 2
    noise: str | None = None
    shots: int | None = None
    backend: str = "numpy"
    seed: int = 0
    qasm: Path | None = None
    qubits: int | None = None
    layers: int | None = None
    reupload: bool = False
    model: Path | None = None

    def __post_init__(self) -> None:
        from qdcnn.quantum.execute import check_backend

        build_circuit(self)  # checks the kind and its parameters
        self.noise_spec()
        check_backend(self.backend)
        check_optional_shots(self.shots)
        check_seed("seed", self.seed)
        if self.qasm is not None and not isinstance(self.qasm, str | os.PathLike):
            raise ParameterError("qasm", self.qasm, "a path or None")

    def noise_spec(self) -> NoiseSpec | None:
        """The parsed noise, or ``None``."""
        from qdcnn.quantum.noise_text import parse_noise

        return None if self.noise is None else parse_noise(self.noise)


@dataclass(frozen=True)
class CircuitKind:
    """One kind of circuit: the spec fields it reads and how to build it from them."""

    name: str
    fields: tuple[str, ...]
    build: Callable[[CircuitSpec], tuple[Any, dict[str, Any]]]
    summary: str = ""


def _build_uu(spec: CircuitSpec) -> tuple[Any, dict[str, Any]]:
    from qdcnn.quantum.circuits import uu_dagger_circuit

    if spec.theta_c is None or spec.theta_x is None:
        raise ParameterError("theta-c/theta-x", None, "both --theta-c and --theta-x for uu")
    tc, tx = parse_angle(spec.theta_c, "theta-c"), parse_angle(spec.theta_x, "theta-x")
    return uu_dagger_circuit(tc, tx), {"theta_c": tc, "theta_x": tx}


def _build_vqc(spec: CircuitSpec) -> tuple[Any, dict[str, Any]]:
    from qdcnn.quantum.circuits import vqc_circuit

    if spec.x is None or spec.weights is None:
        raise ParameterError("x/weights", None, "both --x X1,X2 and --weights W1,... for vqc")
    reps = check_int("feature-map-reps", spec.feature_map_reps, 1, 100)
    xs = angle_list(spec.x, "x", 2)
    ws = angle_list(spec.weights, "weights")
    if len(ws) < 2 or len(ws) % 2:
        raise ParameterError("weights", spec.weights, "2 (reps + 1) angles: 4 for the paper's VQC")
    circuit = vqc_circuit([xs], ws, feature_map_reps=reps, ansatz_reps=len(ws) // 2 - 1)
    return circuit, {"x": xs, "weights": ws, "feature_map_reps": reps}


def _build_head(spec: CircuitSpec) -> tuple[Any, dict[str, Any]]:
    """The hybrid QDCNN's quantum head: RY encoding, then Rot layers and rings of CNOTs
    (or of CZs, as a saved dressed head has them).

    ``weights`` are the layers x qubits x 3 Rot angles flattened in that order
    (PennyLane's ``StronglyEntanglingLayers`` shape); with ``model`` they come from the
    trained head of a saved hybrid model.
    """
    from qdcnn.quantum.templates import head_circuit

    ring: dict[str, Any] = {}
    if spec.model is not None:
        weights, reupload, ring = _trained_head(spec.model)
        qubits, layers = weights.shape[1], weights.shape[0]
    else:
        if spec.qubits is None or spec.layers is None or spec.weights is None:
            raise ParameterError(
                "qubits/layers/weights", None, "--qubits, --layers and --weights (or --model)"
            )
        qubits = check_int("qubits", spec.qubits, 1, 8)
        layers = check_int("layers", spec.layers, 1, 64)
        flat = angle_list(spec.weights, "weights", layers * qubits * 3)
        weights, reupload = np.reshape(flat, (layers, qubits, 3)), bool(spec.reupload)
    xs = [0.0] * qubits if spec.x is None else angle_list(spec.x, "x", qubits)
    circuit = head_circuit([xs], weights, reupload=reupload, **ring)
    params = {
        "x": xs,
        "weights": np.asarray(weights).ravel().tolist(),
        "qubits": qubits,
        "layers": layers,
        "reupload": reupload,
    }
    return circuit, params


def _trained_head(path: Path) -> tuple[Any, bool, dict[str, Any]]:
    from qdcnn.direction.model import DirectionModel

    model = DirectionModel.load(path)
    network = getattr(model.estimator, "model_", None)
    head = getattr(network, "head", None)
    weights = getattr(head, "weights", None)
    reupload = getattr(head, "reupload", None)
    if weights is None or reupload is None:
        raise ParameterError("model", str(path), "a hybrid model with a quantum head (qdcnn-*)")
    ring = {  # entangle False: the -noent ablation
        "entangle": bool(getattr(head, "entangle", True)),
        "entangler": str(getattr(head, "entangler", "cx")),
    }
    return weights.detach().double().cpu().numpy(), bool(reupload), ring


#: The circuit kinds, by name.
CIRCUIT_KINDS: dict[str, CircuitKind] = {
    "uu": CircuitKind(
        "uu", ("theta_c", "theta_x"), _build_uu, "UU-dagger fidelity test (one qubit)"
    ),
    "vqc": CircuitKind(
        "vqc", ("x", "weights", "feature_map_reps"), _build_vqc, "the paper's 2-qubit VQC"
    ),
    "head": CircuitKind(
        "head",
        ("x", "weights", "qubits", "layers", "model"),
        _build_head,
        "the hybrid QDCNN's quantum head (StronglyEntanglingLayers)",
    ),
}
#: Spec fields that only some kinds read (``None`` when not given), and their option names.
_KIND_OPTIONS: dict[str, str] = {
    "theta_c": "theta-c/theta-x",
    "theta_x": "theta-c/theta-x",
    "x": "x/weights",
    "weights": "x/weights",
    "qubits": "qubits",
    "layers": "layers",
    "model": "model",
}


def build_circuit(spec: CircuitSpec) -> tuple[Any, dict[str, Any]]:
    """The circuit of ``spec`` and its parameters (angles in radians).

    Raises
    ------
    ParameterError
        An unknown kind, a field the kind does not read, or a bad angle.
    """
    kind = CIRCUIT_KINDS.get(spec.kind) if isinstance(spec.kind, str) else None
    if kind is None:
        names = [repr(k) for k in CIRCUIT_KINDS]
        allowed = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " or " + names[-1]
        raise ParameterError("circuit", spec.kind, allowed)
    for name, option in _KIND_OPTIONS.items():
        value = getattr(spec, name)
        if value is not None and name not in kind.fields:
            readers = [k for k, info in CIRCUIT_KINDS.items() if name in info.fields]
            where = " or ".join(f"'circuit {k}'" for k in readers)
            raise ParameterError(option, value, f"only with {where}")
    return kind.build(spec)


@dataclass
class CircuitInspection:
    """A circuit's diagram and outcome probabilities (what ``qdcnn circuit`` prints).

    Attributes
    ----------
    spec : CircuitSpec
    parameters : dict
        The circuit's angles in radians.
    num_qubits : int
    diagram : str
        Text drawing (Qiskit's when installed).
    states : list of str
        Basis states ``q(n-1)..q0``, in index order.
    probabilities : list of float
        Outcome probability per basis state.
    expectations : list of float
        ``<Z_i>`` of qubit ``i``, in qubit order.
    noise : str or None
        Label of the noise (``depolarizing:0.1``).
    qasm : path or None
        The OpenQASM 3 file written.
    notes : list of str
        What the user should know (an export written without the read-back check).
    """

    spec: CircuitSpec
    parameters: dict[str, Any]
    num_qubits: int
    diagram: str
    states: list[str]
    probabilities: list[float]
    noise: str | None = None
    expectations: list[float] = field(default_factory=list)
    qasm: Path | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def evaluation(self) -> str:
        """``"exact"`` or ``"N shots, seed S"``."""
        spec = self.spec
        return "exact" if spec.shots is None else f"{spec.shots} shots, seed {spec.seed}"

    @property
    def header(self) -> str:
        """The line above the table: backend, evaluation, noise."""
        noise = "no noise" if self.noise is None else f"noise {self.noise}"
        return f"outcome probabilities: {self.spec.backend} backend, {self.evaluation}, {noise}"

    @property
    def state_header(self) -> str:
        """Head of the basis-state column (``state (q1..q0)``)."""
        n = self.num_qubits
        return f"state (q{n - 1}..q0)" if n > 1 else "state (q0)"

    def to_dict(self) -> dict[str, Any]:
        """The ``--json`` object."""
        spec = self.spec
        return {
            "circuit": spec.kind,
            "parameters": self.parameters,
            "num_qubits": self.num_qubits,
            "noise": self.noise,
            "shots": spec.shots,
            "backend": spec.backend,
            "seed": spec.seed,
            "states": self.states,
            "probabilities": self.probabilities,
            "expectations": self.expectations,
            "qasm": None if self.qasm is None else str(self.qasm),
            "diagram": self.diagram,
        }


def inspect_circuit(spec: CircuitSpec, reporter: Reporter | None = None) -> CircuitInspection:
    """Build, run and (optionally) export the circuit of ``spec``.

    Notes (an OpenQASM file written without the read-back check, when
    ``qiskit-qasm3-import`` is missing) go to ``reporter.note`` and the result's ``notes``.
    """
    from qdcnn._optional import has_module
    from qdcnn.quantum.execute import run_probabilities
    from qdcnn.quantum.export import draw_text, write_qasm3
    from qdcnn.quantum.templates import z_expectations

    report = reporter or Reporter()
    circuit, params = build_circuit(spec)
    noise = spec.noise_spec()
    probs = run_probabilities(
        circuit,
        shots=spec.shots,
        noise=noise,
        backend=spec.backend,
        rng=np.random.default_rng(spec.seed),
    )[0]
    n = circuit.num_qubits
    result = CircuitInspection(
        spec,
        params,
        n,
        draw_text(circuit),
        [format(i, f"0{n}b") for i in range(2**n)],
        [float(v) for v in probs],
        None if noise is None else noise.label(),
        [float(z) for z in z_expectations(np.asarray(probs)[None])[0]],
    )
    if spec.qasm is not None:
        checked = has_module("qiskit_qasm3_import")
        result.qasm = write_qasm3(circuit, Path(spec.qasm), check=checked)
        if not checked:
            result.notes.append(QASM_UNCHECKED_NOTE)
            report.note(QASM_UNCHECKED_NOTE)
    return result
