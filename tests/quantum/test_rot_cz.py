"""The rot and cz gates and circuit templates in the shared vocabulary (NumPy, Qiskit, export)."""

from __future__ import annotations

import numpy as np
import pytest
from all_gates import random_all_gates_circuit

from qdcnn.errors import ParameterError
from qdcnn.quantum import gates
from qdcnn.quantum.circuits import CircuitBuilder, TemplateBuilder, cnot_ring
from qdcnn.quantum.export import gate_listing
from qdcnn.quantum.noise import CHANNELS, NoiseSpec
from qdcnn.quantum.simulator import density_matrix, probabilities, statevector, unitary


def test_rot_is_rz_ry_rz_and_cz_is_diagonal(rng: np.random.Generator) -> None:
    a = rng.uniform(-7, 7, (20, 3))
    expected = np.einsum(
        "bij,bjk,bkl->bil", gates.rz(a[:, 2]), gates.ry(a[:, 1]), gates.rz(a[:, 0])
    )
    np.testing.assert_allclose(gates.rot(a), expected, atol=1e-15)
    np.testing.assert_allclose(gates.CZ, np.diag([1, 1, 1, -1]))
    with pytest.raises(ParameterError, match="three angles on the last axis"):
        gates.rot(np.zeros(2))


def test_rot_equals_pennylane() -> None:
    qml = pytest.importorskip("pennylane")
    for phi, theta, omega in [(0.3, -1.2, 2.5), (4.0, 0.1, -0.7)]:
        np.testing.assert_allclose(
            gates.rot([phi, theta, omega]), qml.Rot.compute_matrix(phi, theta, omega), atol=1e-15
        )


def test_all_gate_circuits_equal_qiskit_statevector(rng: np.random.Generator) -> None:
    pytest.importorskip("qiskit")
    from qiskit.quantum_info import Operator, Statevector

    from qdcnn.quantum.qiskit_bridge import to_qiskit

    for n in (1, 2, 3):
        circ = random_all_gates_circuit(rng, n, 5)
        psi, u = statevector(circ), unitary(circ)
        for i, qc in enumerate(to_qiskit(circ)):
            np.testing.assert_allclose(psi[i], Statevector(qc).data, atol=1e-12)
            np.testing.assert_allclose(u[i % len(u)], Operator(qc).data, atol=1e-12)


@pytest.mark.parametrize("channel", list(CHANNELS))
def test_all_gate_circuits_match_aer_density_matrix_with_noise(
    channel: str, rng: np.random.Generator
) -> None:
    pytest.importorskip("qiskit_aer")
    from qdcnn.quantum.qiskit_bridge import run_aer

    circ = random_all_gates_circuit(rng, 3, 6, n_gates=15)
    for p in (0.0, 0.3):
        spec = NoiseSpec(channel, p)
        np.testing.assert_allclose(
            probabilities(circ, spec), run_aer(circ, noise=spec), atol=1e-9, err_msg=channel
        )
    rho = density_matrix(circ)
    psi = statevector(circ)
    np.testing.assert_allclose(rho, np.einsum("bi,bj->bij", psi, psi.conj()), atol=1e-12)


def test_rot_exports_as_u_and_reads_back() -> None:
    pytest.importorskip("qiskit_qasm3_import")
    from qiskit.quantum_info import Statevector

    from qdcnn.quantum.export import check_qasm_round_trip, from_qasm3, to_qasm3

    c = CircuitBuilder(2, 1).rot(0, 0.3, 1.1, -0.4).cz(0, 1).rot(1, 0.5, 0.2, 0.9).build("r")
    text = to_qasm3(c)
    assert "U(1.1, -0.4, 0.3) q[0];" in text and "cz q[0], q[1];" in text
    check_qasm_round_trip(c, text)
    loaded = from_qasm3(text).remove_final_measurements(inplace=False)
    # OpenQASM 3 drops the global phase; the probabilities are those of the circuit
    np.testing.assert_allclose(Statevector(loaded).probabilities(), probabilities(c)[0], atol=1e-12)


def test_gate_listing_and_params_of_rot() -> None:
    c = CircuitBuilder(1, 2).rot(0, [0.1, 0.2], 0.5, -1.0).ry(0, 0.25).build("r")
    assert c.params_of(1) == [(0.2, 0.5, -1.0), (0.25,)]
    assert "rot(0.2, 0.5, -1) q[0]" in gate_listing(c, 1)
    with pytest.raises(ParameterError, match="no rot gate for angles_of"):
        c.angles_of(0)
    picked = c.select([1])
    assert picked.params_of(0) == c.params_of(1)


def test_template_round_trip_through_as_template(rng: np.random.Generator) -> None:
    circ = random_all_gates_circuit(rng, 3, 4)
    template, inputs, weights = circ.as_template()
    assert inputs.shape[0] == 4 and template.num_inputs == inputs.shape[1]
    again = template.bind(inputs, weights)
    assert [g.name for g in again.gates] == [g.name for g in circ.gates]
    for i in range(4):
        assert again.params_of(i) == circ.params_of(i)
    np.testing.assert_allclose(statevector(again), statevector(circ), atol=1e-15)


def test_template_bind_shares_and_batches() -> None:
    t = TemplateBuilder(1, num_inputs=1, num_weights=3).ry(0, 0).rot(0, 1).build()
    batch = t.bind([[0.1], [0.2]], [1.0, 2.0, 3.0])
    assert len(batch) == 2 and batch.params_of(1) == [(0.2,), (1.0, 2.0, 3.0)]
    assert len(t.bind([0.1], [1.0, 2.0, 3.0])) == 1


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: TemplateBuilder(2, 1).ry(0, 1), r"ry slots=\(1,\) is invalid: 1 parameter"),
        (lambda: TemplateBuilder(2, 3).add("rot", (0,), (0, 1)), "3 parameter indices"),
        (lambda: TemplateBuilder(2).add("cz", (1, 1)), r"cz qubits=\(1, 1\) is invalid"),
        (lambda: TemplateBuilder(13), "num_qubits=13 is invalid: 1 to 12 qubits"),
        (lambda: TemplateBuilder(1, 1).build().bind([[0.1, 0.2]]), r"inputs='shape \(1, 2\)'"),
        (
            lambda: TemplateBuilder(1, 1, 1).build().bind([[0.1], [0.2]], [[1.0]] * 3),
            r"inputs/weights=\[2, 3\] is invalid: one batch size",
        ),
        (lambda: CircuitBuilder(1, 2).rot(0, [1, 2, 3], 0, 0), "angle='array of shape"),
        (lambda: cnot_ring(3, 3), "r=3 is invalid: an integer in"),
    ],
)
def test_template_errors(call, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ParameterError, match=message):
        call()


def test_cnot_ring_is_pennylane_entangler() -> None:
    assert cnot_ring(1) == []
    assert cnot_ring(2) == [(0, 1), (1, 0)]
    assert cnot_ring(4, 3) == [(0, 3), (1, 0), (2, 1), (3, 2)]
