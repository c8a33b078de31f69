"""The batched NumPy simulators agree with Qiskit's reference results."""

from __future__ import annotations

import numpy as np
import pytest

from qdcnn.errors import ParameterError
from qdcnn.quantum.circuits import CircuitBuilder, uu_dagger_circuit, vqc_circuit
from qdcnn.quantum.simulator import density_matrix, probabilities, statevector, unitary
from qdcnn.quantum.vqc import feature_map_states

qiskit = pytest.importorskip("qiskit")
pytest.importorskip("qiskit_aer")
from qiskit.circuit.library import real_amplitudes, zz_feature_map  # noqa: E402
from qiskit.quantum_info import Statevector  # noqa: E402

from qdcnn.quantum.qiskit_bridge import run_aer, to_qiskit  # noqa: E402


def random_circuit(rng: np.random.Generator, batch: int, n_gates: int = 12) -> CircuitBuilder:
    """Random 2-qubit circuits using every supported gate, with per-circuit angles."""
    b = CircuitBuilder(2, batch)
    for _ in range(n_gates):
        kind = rng.choice(["ry", "rx", "rz", "p", "h", "x", "cx", "cx10"])
        q = int(rng.integers(2))
        if kind in ("ry", "rx", "rz", "p"):
            b.add(str(kind), (q,), rng.uniform(-2 * np.pi, 2 * np.pi, batch))
        elif kind == "cx":
            b.cx(0, 1)
        elif kind == "cx10":
            b.cx(1, 0)
        else:
            b.add(str(kind), (q,))
    return b


def test_statevector_matches_qiskit_for_random_circuits(rng: np.random.Generator) -> None:
    circ = random_circuit(rng, 16).build()
    ours = statevector(circ)
    for i, qc in enumerate(to_qiskit(circ)):
        np.testing.assert_allclose(ours[i], Statevector(qc).data, atol=1e-12)


def test_probabilities_match_aer_statevector(rng: np.random.Generator) -> None:
    circ = random_circuit(rng, 32).build()
    np.testing.assert_allclose(probabilities(circ), run_aer(circ), atol=1e-10)


def test_density_matrix_matches_aer_density_matrix(rng: np.random.Generator) -> None:
    circ = random_circuit(rng, 32).build()
    rho = density_matrix(circ)
    np.testing.assert_allclose(
        np.einsum("bii->bi", rho).real, run_aer(circ, method="density_matrix"), atol=1e-10
    )
    # a pure state's density matrix is |psi><psi|
    psi = statevector(circ)
    np.testing.assert_allclose(rho, np.einsum("bi,bj->bij", psi, psi.conj()), atol=1e-12)


def test_uu_dagger_probabilities_match_aer_and_formula(rng: np.random.Generator) -> None:
    tc, tx = rng.uniform(0, np.pi), rng.uniform(0, np.pi, 64)
    circ = uu_dagger_circuit(tc, tx)
    ours = probabilities(circ)
    np.testing.assert_allclose(ours[:, 0], np.cos((tc - tx) / 2) ** 2, atol=1e-12)
    np.testing.assert_allclose(ours, run_aer(circ), atol=1e-10)


def test_single_rotation_path_equals_the_statevector_path(rng: np.random.Generator) -> None:
    # one-qubit RY-only circuits skip the 2x2 products; the result must not change
    tx = rng.uniform(-4 * np.pi, 4 * np.pi, 200)
    for circ in (
        uu_dagger_circuit(1.3, tx),
        uu_dagger_circuit(tx, 0.4),
        CircuitBuilder(1, 200).ry(0, tx).ry(0, 0.2).ry(0, -tx / 3).build(),
        CircuitBuilder(1, 1).ry(0, 2.0).build(),
    ):
        psi = statevector(circ)
        np.testing.assert_allclose(probabilities(circ), np.abs(psi) ** 2, atol=1e-14)
    # anything else takes the general path, and agrees with Aer as before
    mixed = CircuitBuilder(1, 50).ry(0, tx[:50]).rz(0, tx[50:100]).ry(0, 0.3).build()
    np.testing.assert_allclose(probabilities(mixed), run_aer(mixed), atol=1e-10)


def test_vqc_circuit_equals_qiskit_library_circuits(rng: np.random.Generator) -> None:
    x = rng.uniform(-1, 4, (8, 2))
    w = rng.uniform(-np.pi, np.pi, 4)
    ours = statevector(vqc_circuit(x, w))
    fm, ansatz = zz_feature_map(2), real_amplitudes(2, reps=1)
    full = fm.compose(ansatz)
    for i in range(len(x)):
        bound = full.assign_parameters(
            {
                **dict(zip(fm.parameters, x[i], strict=True)),
                **dict(zip(ansatz.parameters, w, strict=True)),
            }
        )
        np.testing.assert_allclose(ours[i], Statevector(bound).data, atol=1e-12)


def test_batched_weights_match_one_at_a_time(rng: np.random.Generator) -> None:
    x = rng.uniform(0, 3, (5, 2))
    w = rng.uniform(-3, 3, (5, 4))
    batched = probabilities(vqc_circuit(x, w))
    single = np.vstack([probabilities(vqc_circuit(x[i : i + 1], w[i])) for i in range(5)])
    np.testing.assert_allclose(batched, single, atol=1e-14)


def test_select_picks_circuits(rng: np.random.Generator) -> None:
    circ = random_circuit(rng, 10).build()
    np.testing.assert_allclose(probabilities(circ.select([2, 7])), probabilities(circ)[[2, 7]])


def test_probabilities_sum_to_one_and_qubit0_is_lsb() -> None:
    circ = CircuitBuilder(2, 1).x(0).build()
    np.testing.assert_allclose(probabilities(circ), [[0, 1, 0, 0]], atol=1e-15)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda b: b.add("rq", (0,), 1.0), "gate='rq' is invalid"),
        (lambda b: b.ry(2, 1.0), "qubit=2 is invalid"),
        (lambda b: b.cx(0, 0), "cx qubits=(0, 0) is invalid"),
        (lambda b: b.ry(0, [1.0, 2.0]), "angle='array of shape (2,)' is invalid"),
        (lambda b: b.ry(0, float("nan")), "angle='non-finite values' is invalid"),
    ],
)
def test_builder_rejects_bad_gates(call, message: str) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ParameterError, match=message.replace("(", r"\(").replace(")", r"\)")):
        call(CircuitBuilder(2, 3))


def test_unitary_columns_are_the_states_from_each_basis_state(rng: np.random.Generator) -> None:
    from qiskit.quantum_info import Operator

    circ = random_circuit(rng, 3).build("random")
    u = unitary(circ)
    assert u.shape == (3, 4, 4)
    np.testing.assert_allclose(u[:, :, 0], statevector(circ), atol=1e-12)
    for i in range(3):
        np.testing.assert_allclose(u[i], Operator(to_qiskit(circ, i)).data, atol=1e-12)


def test_feature_map_states_equal_qiskit(rng: np.random.Generator) -> None:
    x = rng.uniform(-1, 4, (6, 2))
    fm = zz_feature_map(2, reps=2)
    ours = feature_map_states(x, 2)
    for i in range(len(x)):
        bound = fm.assign_parameters(dict(zip(fm.parameters, x[i], strict=True)))
        np.testing.assert_allclose(ours[i], Statevector(bound).data, atol=1e-12)
