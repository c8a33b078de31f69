"""Look at and export one circuit of a batch: text diagrams and OpenQASM 3.

The diagram is Qiskit's ``QuantumCircuit.draw("text")`` when Qiskit is installed,
otherwise a plain gate listing (:func:`gate_listing`). OpenQASM 3 comes from
``qiskit.qasm3.dumps``; :func:`check_qasm_round_trip` reads the text back with
``qiskit.qasm3.loads`` (which needs the ``qiskit-qasm3-import`` package) and checks
that it is the same circuit: the same gates on the same qubits with the same angles.

Noise is not part of a circuit: a density-matrix run with a
:class:`~qdcnn.quantum.noise.NoiseSpec` applies the channel after every gate (see
:mod:`qdcnn.quantum.noise`), which OpenQASM 3 cannot express. Exported programs end
with a measurement of every qubit into a classical register ``c`` (``c[i]`` holds
qubit ``i``), so they run as they are.

References
----------
.. [1] A. Cross et al., "OpenQASM 3: A broader and deeper quantum assembly language",
   ACM Transactions on Quantum Computing 3 (3), 2022.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

from qdcnn._fileio import atomic_write_text
from qdcnn._optional import has_module, require
from qdcnn.errors import InputError, MissingExtraError, ParameterError
from qdcnn.quantum.circuits import CircuitBatch

#: tolerance on angles when a QASM text is compared with the circuit it came from
_ANGLE_ATOL = 1e-12


def _check_index(circuit: CircuitBatch, index: int) -> int:
    if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(circuit):
        raise ParameterError("index", index, f"a circuit index in [0, {len(circuit) - 1}]")
    return index


def gate_listing(circuit: CircuitBatch, index: int = 0) -> str:
    """Plain-text listing of circuit ``index``: one gate per line, in order.

    Used as the diagram when Qiskit is not installed.

    Examples
    --------
    >>> from qdcnn.quantum.circuits import uu_dagger_circuit
    >>> print(gate_listing(uu_dagger_circuit(1.0, 0.25)))
    uu_dagger: 1 qubit, 2 gates (qubit 0 = least significant bit)
      1  ry(1) q[0]
      2  ry(-0.25) q[0]
    """
    _check_index(circuit, index)
    n = circuit.num_qubits
    lines = [
        f"{circuit.name}: {n} qubit{'s' if n != 1 else ''}, {len(circuit.gates)} gates "
        "(qubit 0 = least significant bit)"
    ]
    width = len(str(len(circuit.gates)))
    for k, (gate, params) in enumerate(zip(circuit.gates, circuit.params_of(index), strict=True)):
        args = f"({', '.join(f'{a:.10g}' for a in params)})" if params else ""
        qubits = ", ".join(f"q[{q}]" for q in gate.qubits)
        lines.append(f"  {k + 1:>{width}}  {gate.name}{args} {qubits}")
    return "\n".join(lines)


def qiskit_circuit(circuit: CircuitBatch, index: int = 0, *, measure: bool = False) -> Any:
    """Circuit ``index`` as a ``qiskit.QuantumCircuit``.

    Parameters
    ----------
    circuit : CircuitBatch
        The batch.
    index : int
        Which circuit of the batch.
    measure : bool
        Append a measurement of qubit ``i`` into bit ``c[i]`` for every qubit.
    """
    _check_index(circuit, index)
    from qdcnn.quantum.qiskit_bridge import to_qiskit

    qc = to_qiskit(circuit, index)
    if measure:
        qiskit = require("qiskit", "measured Qiskit circuits")
        out = qiskit.QuantumCircuit(
            qiskit.QuantumRegister(circuit.num_qubits, "q"),
            qiskit.ClassicalRegister(circuit.num_qubits, "c"),
            name=qc.name,
        )
        out.compose(qc, inplace=True)
        out.measure(range(circuit.num_qubits), range(circuit.num_qubits))
        qc = out
    return qc


def draw_text(circuit: CircuitBatch, index: int = 0) -> str:
    """Text diagram of circuit ``index``: Qiskit's ``draw("text")``, else :func:`gate_listing`."""
    if not has_module("qiskit"):
        return gate_listing(circuit, index)
    return str(qiskit_circuit(circuit, index).draw("text", fold=-1))


def to_qasm3(circuit: CircuitBatch, index: int = 0, *, measure: bool = True) -> str:
    """OpenQASM 3 text of circuit ``index`` (``qiskit.qasm3.dumps``), measured by default."""
    qiskit = require("qiskit", "OpenQASM 3 export")
    text: str = qiskit.qasm3.dumps(qiskit_circuit(circuit, index, measure=measure))
    return text


def from_qasm3(text: str) -> Any:
    """Parse OpenQASM 3 with ``qiskit.qasm3.loads`` (needs ``qiskit-qasm3-import``)."""
    qiskit = require("qiskit", "reading OpenQASM 3")
    if not has_module("qiskit_qasm3_import"):
        raise MissingExtraError("qiskit-qasm3-import", "quantum", "reading OpenQASM 3")
    return qiskit.qasm3.loads(text)


def _instructions(qc: Any) -> list[tuple[str, tuple[int, ...], tuple[int, ...], tuple[float, ...]]]:
    out = []
    for inst in qc.data:
        op = inst.operation
        qubits = tuple(qc.find_bit(q).index for q in inst.qubits)
        clbits = tuple(qc.find_bit(c).index for c in inst.clbits)
        out.append((op.name, qubits, clbits, tuple(float(p) for p in op.params)))
    return out


def circuit_differences(expected: Any, actual: Any, atol: float = _ANGLE_ATOL) -> list[str]:
    """Differences between two Qiskit circuits, instruction by instruction ([] when equal).

    Compares qubit and bit counts, then each instruction's name, qubit and bit indices
    and parameters (within ``atol``).
    """
    diffs = []
    if expected.num_qubits != actual.num_qubits:
        diffs.append(f"{actual.num_qubits} qubits instead of {expected.num_qubits}")
    if expected.num_clbits != actual.num_clbits:
        diffs.append(f"{actual.num_clbits} bits instead of {expected.num_clbits}")
    a, b = _instructions(expected), _instructions(actual)
    if len(a) != len(b):
        diffs.append(f"{len(b)} instructions instead of {len(a)}")
    for k, (x, y) in enumerate(zip(a, b, strict=False)):
        same_params = len(x[3]) == len(y[3]) and all(
            math.isclose(p, q, rel_tol=0.0, abs_tol=atol) for p, q in zip(x[3], y[3], strict=True)
        )
        if x[:3] != y[:3] or not same_params:
            diffs.append(f"instruction {k + 1}: {y} instead of {x}")
    return diffs


def check_qasm_round_trip(
    circuit: CircuitBatch, text: str, index: int = 0, *, measure: bool = True
) -> None:
    """Raise :class:`InputError` unless ``text`` reads back as circuit ``index``."""
    expected = qiskit_circuit(circuit, index, measure=measure)
    diffs = circuit_differences(expected, from_qasm3(text))
    if diffs:
        raise InputError("OpenQASM 3 round trip", "; ".join(diffs[:3]))


def write_qasm3(
    circuit: CircuitBatch,
    path: str | os.PathLike[str],
    index: int = 0,
    *,
    measure: bool = True,
    check: bool = True,
) -> Path:
    """Write circuit ``index`` as OpenQASM 3 to ``path``; with ``check``, verify the round trip.

    The check needs ``qiskit-qasm3-import``; without it, pass ``check=False``.
    """
    text = to_qasm3(circuit, index, measure=measure)
    if check:
        check_qasm_round_trip(circuit, text, index, measure=measure)
    try:
        return atomic_write_text(path, text)
    except InputError as exc:
        raise InputError(exc.source, f"cannot write the OpenQASM file ({exc.reason})") from None
