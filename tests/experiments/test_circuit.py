"""inspect_circuit: what ``qdcnn circuit`` shows, from Python (the CLI tests, one level down)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from qdcnn._optional import has_module
from qdcnn.errors import MissingExtraError, ParameterError
from qdcnn.experiments.circuit import (
    CIRCUIT_KINDS,
    QASM_UNCHECKED_NOTE,
    CircuitSpec,
    angle_list,
    inspect_circuit,
    parse_angle,
)
from qdcnn.quantum.circuits import vqc_circuit
from qdcnn.quantum.simulator import probabilities
from qdcnn.runtime.reporting import Collector


def test_parse_angle() -> None:
    assert parse_angle("pi/2", "a") == np.pi / 2
    assert parse_angle("-3pi/4", "a") == -3 * np.pi / 4
    assert parse_angle("2*pi", "a") == 2 * np.pi
    assert parse_angle(" + pi / 4 ", "a") == np.pi / 4
    assert parse_angle("0.25", "a") == 0.25
    for bad in ("abc", "pi/0", "inf", "pi pi"):
        with pytest.raises(ParameterError, match=f"a={bad!r} is invalid"):
            parse_angle(bad, "a")
    assert angle_list("0,pi,", "w") == [0.0, math.pi]
    with pytest.raises(ParameterError, match="x='1' is invalid: 2 comma-separated angles"):
        angle_list("1", "x", 2)


def test_uu_exact_and_noisy() -> None:
    res = inspect_circuit(CircuitSpec("uu", theta_c="pi/2", theta_x="0.3"))
    ideal = np.cos((np.pi / 2 - 0.3) / 2) ** 2
    np.testing.assert_allclose(res.probabilities, [ideal, 1 - ideal], atol=1e-12)
    obj = res.to_dict()
    assert obj["circuit"] == "uu" and obj["qasm"] is None and obj["noise"] is None
    assert obj["parameters"] == {"theta_c": np.pi / 2, "theta_x": 0.3}
    assert obj["states"] == ["0", "1"] and obj["num_qubits"] == 1
    assert set(obj) == {
        "circuit",
        "parameters",
        "num_qubits",
        "noise",
        "shots",
        "backend",
        "seed",
        "states",
        "probabilities",
        "expectations",
        "qasm",
        "diagram",
    }
    assert res.header == "outcome probabilities: numpy backend, exact, no noise"
    assert res.state_header == "state (q0)" and res.notes == []
    # depolarizing after each of the two gates shrinks the Bloch vector by (1 - p) twice
    noisy = inspect_circuit(
        CircuitSpec("uu", theta_c="pi/2", theta_x="0.3", noise="depolarizing:0.3")
    )
    assert noisy.probabilities[0] == pytest.approx(0.5 + 0.7**2 * (ideal - 0.5), abs=1e-12)
    assert noisy.noise == "depolarizing:0.3"
    assert noisy.header.endswith("noise depolarizing:0.3")


@pytest.mark.base
def test_vqc_matches_the_simulator_and_exports_qasm(tmp_path: Path) -> None:
    qasm = tmp_path / "vqc.qasm"
    spec = CircuitSpec("vqc", x="0.3,1.2", weights="0.1,0.2,0.3,0.4", qasm=qasm)
    if not has_module("qiskit"):  # the export needs the quantum extra, and says so
        with pytest.raises(MissingExtraError, match=r"pip install 'qdcnn\[quantum\]'"):
            inspect_circuit(spec, Collector())
        assert not qasm.exists()
        spec = replace(spec, qasm=None)
    report = Collector()
    res = inspect_circuit(spec, report)
    assert res.states == ["00", "01", "10", "11"] and res.state_header == "state (q1..q0)"
    expected = probabilities(vqc_circuit([[0.3, 1.2]], [0.1, 0.2, 0.3, 0.4]))[0]
    np.testing.assert_allclose(res.probabilities, expected, atol=1e-12)
    if spec.qasm is None:
        pytest.skip("qiskit not installed: no OpenQASM export")
    assert res.qasm == qasm and res.to_dict()["qasm"] == str(qasm)
    assert res.parameters == {
        "x": [0.3, 1.2],
        "weights": [0.1, 0.2, 0.3, 0.4],
        "feature_map_reps": 2,
    }
    assert "Ry(0.4)" in res.diagram or "ry(0.4)" in res.diagram
    if not has_module("qiskit_qasm3_import"):
        assert res.notes == [QASM_UNCHECKED_NOTE] and report.notes == [QASM_UNCHECKED_NOTE]
        pytest.skip("qiskit-qasm3-import not installed: the file is not read back")
    assert res.notes == [] and report.notes == []
    from qiskit import qasm3
    from qiskit.quantum_info import Statevector

    loaded = qasm3.loads(qasm.read_text()).remove_final_measurements(inplace=False)
    np.testing.assert_allclose(Statevector(loaded).probabilities(), expected, atol=1e-12)


def test_aer_and_shots() -> None:
    pytest.importorskip("qiskit_aer")
    base = {"x": "0.3,1.2", "weights": "0.1,0.2,0.3,0.4", "noise": "amplitude-damping:0.2"}
    exact = np.array(inspect_circuit(CircuitSpec("vqc", **base)).probabilities)
    aer = inspect_circuit(CircuitSpec("vqc", backend="aer", **base)).probabilities
    np.testing.assert_allclose(aer, exact, atol=1e-9)
    spec = CircuitSpec("vqc", shots=1000, seed=4, **base)
    a = np.array(inspect_circuit(spec).probabilities)
    assert a.tolist() == inspect_circuit(spec).probabilities
    np.testing.assert_allclose(a * 1000, np.round(a * 1000), atol=1e-9)
    assert np.all(np.abs(a - exact) < 5 * np.sqrt(exact * (1 - exact) / 1000) + 1e-9)
    assert inspect_circuit(spec).header == (
        "outcome probabilities: numpy backend, 1000 shots, seed 4, noise amplitude-damping:0.2"
    )


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            {"kind": "uu", "theta_c": "1", "theta_x": "2", "noise": "bit-flip:1.5"},
            "p=1.5 is invalid",
        ),
        (
            {"kind": "uu", "theta_c": "1", "theta_x": "2", "noise": "bitflip:0.1"},
            "channel='bitflip'",
        ),
        ({"kind": "uu", "theta_c": "1"}, "both --theta-c and --theta-x"),
        ({"kind": "uu", "theta_c": "1", "theta_x": "2", "x": "1,2"}, "only with 'circuit vqc'"),
        ({"kind": "vqc", "theta_x": "1", "x": "1,2"}, "only with 'circuit uu'"),
        ({"kind": "vqc", "x": "1,2"}, "both --x X1,X2 and --weights"),
        ({"kind": "vqc", "x": "1", "weights": "1,2,3,4"}, "x='1' is invalid: 2 comma-separated"),
        ({"kind": "vqc", "x": "1,2", "weights": "1,2,3"}, "weights='1,2,3' is invalid"),
        (
            {"kind": "vqc", "x": "1,2", "weights": "1,2,3,4", "feature_map_reps": 0},
            "feature-map-reps=0 is invalid",
        ),
        ({"kind": "ghz"}, "circuit='ghz' is invalid: 'uu', 'vqc' or 'head'"),
        ({"kind": "uu", "theta_c": "1", "theta_x": "y"}, "theta-x='y' is invalid"),
        ({"kind": "uu", "theta_c": "1", "theta_x": "2", "backend": "gpu"}, "backend='gpu'"),
        ({"kind": "uu", "theta_c": "1", "theta_x": "2", "shots": 0}, "shots=0 is invalid"),
        ({"kind": "uu", "theta_c": "1", "theta_x": "2", "seed": -2}, "seed=-2 is invalid"),
    ],
)
def test_bad_specs(kwargs: dict, message: str) -> None:
    with pytest.raises(ParameterError) as err:
        CircuitSpec(**kwargs)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_a_new_kind_is_one_table_entry(monkeypatch: pytest.MonkeyPatch) -> None:
    from qdcnn.experiments.circuit import CircuitKind
    from qdcnn.quantum.circuits import uu_dagger_circuit

    def build_pair(spec: CircuitSpec) -> tuple:
        xs = angle_list(spec.x or "", "x", 2)
        return uu_dagger_circuit(xs[0], xs[1]), {"x": xs}

    monkeypatch.setitem(CIRCUIT_KINDS, "pair", CircuitKind("pair", ("x",), build_pair))
    res = inspect_circuit(CircuitSpec("pair", x="0,pi"))
    np.testing.assert_allclose(res.probabilities, [0.0, 1.0], atol=1e-12)
    with pytest.raises(
        ParameterError, match="circuit='ghz' is invalid: 'uu', 'vqc', 'head' or 'pair'"
    ):
        CircuitSpec("ghz")
    with pytest.raises(
        ParameterError, match="only with 'circuit vqc' or 'circuit head' or 'circuit pair'"
    ):
        CircuitSpec("uu", theta_c="1", theta_x="1", x="1,2")


def test_a_saved_product_head_is_drawn_without_entangling_gates(tmp_path: Path) -> None:
    """The -noent ablation's circuit has no CNOTs; drawn from its model file, neither."""
    pytest.importorskip("torch")
    from qdcnn.config import PipelineConfig
    from qdcnn.direction.model import DirectionModel
    from qdcnn.models import CNNDirectionClassifier
    from qdcnn.models.networks import build_network
    from qdcnn.quantum.templates import head_circuit

    for head, entangled in (("product", False), ("quantum", True)):
        network = build_network("qdcnn-head", seed=0, head=head)
        clf = CNNDirectionClassifier.from_network(
            network, "qdcnn-head", device="cpu", network_params={"head": head}
        )
        path = DirectionModel("qdcnn-head", PipelineConfig(), clf, "toy", {}).save(
            tmp_path / f"{head}.safetensors"
        )
        res = inspect_circuit(CircuitSpec("head", model=path, x="0.1,0.2,0.3,0.4"), Collector())
        weights = network.head.weights.detach().double().numpy()
        expected = probabilities(
            head_circuit([[0.1, 0.2, 0.3, 0.4]], weights, entangle=entangled, entangler="cz")
        )
        np.testing.assert_allclose(res.probabilities, expected[0], atol=1e-12)
        assert ("■" in res.diagram or "cx" in res.diagram.lower()) == entangled
