"""Circuit diagrams and OpenQASM 3 export that Qiskit reads back to the same circuit."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from qdcnn.errors import InputError, MissingExtraError, ParameterError
from qdcnn.quantum import export
from qdcnn.quantum.circuits import uu_dagger_circuit, vqc_circuit
from qdcnn.quantum.export import (
    check_qasm_round_trip,
    circuit_differences,
    draw_text,
    from_qasm3,
    gate_listing,
    qiskit_circuit,
    to_qasm3,
    write_qasm3,
)
from qdcnn.quantum.simulator import probabilities


def _circuits(rng: np.random.Generator) -> list:
    return [
        uu_dagger_circuit(rng.uniform(0, np.pi), rng.uniform(0, np.pi)),
        vqc_circuit(rng.uniform(0, np.pi, (1, 2)), rng.uniform(-np.pi, np.pi, 4)),
        vqc_circuit(rng.uniform(0, np.pi, (1, 2)), rng.uniform(-3, 3, 6), ansatz_reps=2),
    ]


def test_gate_listing_known_text() -> None:
    c = vqc_circuit([[0.5, 1.0]], [0.1, 0.2, 0.3, 0.4], feature_map_reps=1)
    lines = gate_listing(c).splitlines()
    assert lines[0] == "vqc: 2 qubits, 12 gates (qubit 0 = least significant bit)"
    assert lines[1:4] == ["   1  h q[0]", "   2  h q[1]", "   3  p(1) q[0]"]
    # (pi - 0.5)(pi - 1) * 2 on qubit 1 between the two CX
    assert lines[5] == "   5  cx q[0], q[1]"
    assert lines[6] == f"   6  p({2 * (np.pi - 0.5) * (np.pi - 1):.10g}) q[1]"
    assert lines[-1] == "  12  ry(0.4) q[1]"


def test_index_is_checked() -> None:
    c = uu_dagger_circuit(0.1, [0.2, 0.3])
    assert "ry(-0.3)" in gate_listing(c, 1)
    with pytest.raises(ParameterError, match=r"index=2 is invalid: a circuit index in \[0, 1\]"):
        gate_listing(c, 2)


def test_fallback_diagram_without_qiskit(monkeypatch: pytest.MonkeyPatch) -> None:
    c = uu_dagger_circuit(1.0, 0.25)
    monkeypatch.setattr(export, "has_module", lambda name: False)
    assert draw_text(c) == gate_listing(c)
    with pytest.raises(MissingExtraError, match=r"pip install 'qdcnn\[quantum\]'"):
        from_qasm3("OPENQASM 3.0;")


def test_qiskit_diagram_names_the_gates() -> None:
    pytest.importorskip("qiskit")
    text = draw_text(uu_dagger_circuit(1.0, 0.25))
    assert "Ry(1)" in text and "Ry(-0.25)" in text


def test_qasm3_round_trip_is_the_same_circuit(rng: np.random.Generator) -> None:
    pytest.importorskip("qiskit_qasm3_import")
    from qiskit.quantum_info import Statevector

    for c in _circuits(rng):
        text = to_qasm3(c)
        assert text.startswith("OPENQASM 3.0;")
        loaded = from_qasm3(text)
        assert circuit_differences(qiskit_circuit(c, measure=True), loaded) == []
        check_qasm_round_trip(c, text)
        # the program read back gives our simulator's probabilities (qubit 0 = LSB)
        unmeasured = loaded.remove_final_measurements(inplace=False)
        np.testing.assert_allclose(
            Statevector(unmeasured).probabilities(), probabilities(c)[0], atol=1e-12
        )


def test_changed_angle_fails_the_round_trip() -> None:
    pytest.importorskip("qiskit_qasm3_import")
    c = uu_dagger_circuit(0.5, 0.25)
    text = to_qasm3(c)
    assert "ry(0.5) q[0];" in text
    with pytest.raises(InputError, match=r"OpenQASM 3 round trip: instruction 1: \('ry'"):
        check_qasm_round_trip(c, text.replace("ry(0.5)", "ry(0.6)"))
    with pytest.raises(InputError, match="2 instructions instead of 3"):
        check_qasm_round_trip(c, text.replace("ry(-0.25) q[0];\n", ""))


def test_write_qasm3(tmp_path: Path) -> None:
    pytest.importorskip("qiskit_qasm3_import")
    c = vqc_circuit([[0.3, 1.2]], [0.1, 0.2, 0.3, 0.4])
    path = write_qasm3(c, tmp_path / "sub" / "vqc.qasm")
    text = path.read_text()
    assert text == to_qasm3(c)
    assert text.rstrip().endswith("c[1] = measure q[1];")
    blocked = tmp_path / "file"
    blocked.write_text("")
    with pytest.raises(InputError, match="cannot write the OpenQASM file"):
        write_qasm3(c, blocked / "x.qasm")
