"""Device noise from IBM fake backends equals qiskit-aer's device noise models.

The reference side of every comparison is built by Qiskit and Aer themselves: circuits
transpiled by ``qiskit.transpile(optimization_level=0)`` on a fixed layout (or, where qdcnn
routes by SWAPs, qdcnn's native circuit through the Qiskit bridge), simulated by
``AerSimulator(method="density_matrix")`` with ``NoiseModel.from_backend(backend)``.

Aer's simulator leaves out the terms of a noise mixture whose probability is at most 1e-10
(its ``QuantumError`` threshold; a CX error on FakeManilaV2 has 15 such terms out of 144).
qdcnn applies the whole channel. So the 1e-9 comparisons give Aer each error of the model
as one Kraus instruction (the same channel, which Aer then keeps whole), and the
comparison with the unmodified model allows exactly the probability Aer drops.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from qdcnn.errors import ParameterError
from qdcnn.quantum import noise as noise_mod
from qdcnn.quantum.circuits import (
    CircuitBatch,
    CircuitBuilder,
    Gate,
    uu_dagger_circuit,
    vqc_circuit,
)
from qdcnn.quantum.noise import NoiseSpec, kraus_operators
from qdcnn.quantum.noise_text import parse_noise
from qdcnn.quantum.simulator import embed, probabilities, unitary

pytest.importorskip("qiskit_ibm_runtime")
pytest.importorskip("qiskit_aer")
import qiskit
import qiskit.quantum_info as qi
from qiskit_aer import AerSimulator
from qiskit_aer.noise import NoiseModel, QuantumError

from qdcnn.quantum.device import DeviceNoise, default_layout, to_native
from qdcnn.quantum.qiskit_bridge import to_qiskit

AER_DROP = 1e-10  # Aer's QuantumError threshold (see the module docstring)


@pytest.fixture(scope="module")
def manila() -> DeviceNoise:
    return DeviceNoise.from_backend("FakeManilaV2")


def sel_circuit(rng: np.random.Generator, batch: int, layers: int = 2) -> CircuitBatch:
    """4 qubits: RY encoding, then per layer Rot = RZ RY RZ on each qubit and a CNOT ring."""
    b = CircuitBuilder(4, batch)
    for q in range(4):
        b.ry(q, rng.uniform(-np.pi, np.pi, batch))
    for _ in range(layers):
        for q in range(4):
            b.rz(q, rng.uniform(-np.pi, np.pi, batch))
            b.ry(q, rng.uniform(-np.pi, np.pi, batch))
            b.rz(q, rng.uniform(-np.pi, np.pi, batch))
        for q in range(4):
            b.cx(q, (q + 1) % 4)
    return b.build("sel")


def circuits(rng: np.random.Generator, batch: int = 50) -> dict[str, CircuitBatch]:
    return {
        "uu_dagger": uu_dagger_circuit(rng.uniform(0, np.pi), rng.uniform(0, np.pi, batch)),
        "vqc": vqc_circuit(rng.uniform(0, 3, (batch, 2)), rng.uniform(-3, 3, 4)),
    }


# ------------------------------------------------------------------ Aer references


def kraus_wrapped(
    model: NoiseModel, backend: object, readout_from: NoiseModel, only: tuple[int, ...] = ()
) -> NoiseModel:
    """``model``'s gate errors, each as one Kraus instruction (on the qubits ``only``, if given).

    Readout is applied separately (:func:`with_readout`), as Aer's exact probabilities have none.
    """
    out = NoiseModel(basis_gates=list(backend.operation_names))  # type: ignore[attr-defined]
    for name, by_qubits in model._local_quantum_errors.items():
        for qubits, err in by_qubits.items():
            if not only or set(qubits) <= set(only):
                out.add_quantum_error(QuantumError(qi.Kraus(err)), name, list(qubits))
    return out


def readout_matrices(model: NoiseModel, layout: tuple[int, ...]) -> list[np.ndarray]:
    """``A[measured, prepared]`` of each layout qubit, read from the model's public dict."""
    found = {}
    for err in model.to_dict()["errors"]:
        if err["type"] == "roerror":
            (q,) = err["gate_qubits"][0]
            found[q] = np.asarray(err["probabilities"], dtype=float).T
    return [found.get(q, np.eye(2)) for q in layout]


def with_readout(probs: np.ndarray, mats: list[np.ndarray]) -> np.ndarray:
    """Apply per-qubit confusion matrices by one Kronecker product (qubit 0 = LSB)."""
    full = np.ones((1, 1))
    for a in mats:
        full = np.kron(a, full)
    return probs @ full.T


def aer_probabilities(qcs: list, model: NoiseModel, layout: tuple[int, ...]) -> np.ndarray:
    for qc in qcs:
        qc.save_probabilities(list(layout))
    result = AerSimulator(method="density_matrix", noise_model=model).run(qcs, shots=1).result()
    return np.array([result.data(i)["probabilities"] for i in range(len(qcs))])


def transpiled(circ: CircuitBatch, backend: object, layout: tuple[int, ...]) -> list:
    return [
        qiskit.transpile(qc, backend, initial_layout=list(layout), optimization_level=0)
        for qc in to_qiskit(circ)
    ]


def from_native(native: CircuitBatch, num_physical: int, layout: tuple[int, ...]) -> list:
    out = []
    for qc in to_qiskit(native):
        wide = qiskit.QuantumCircuit(num_physical)
        out.append(wide.compose(qc, qubits=list(layout)))
    return out


def noisy_ops(qc: qiskit.QuantumCircuit) -> list[tuple[str, tuple[int, ...]]]:
    return [
        (ins.operation.name, tuple(qc.find_bit(q).index for q in ins.qubits))
        for ins in qc.data
        if ins.operation.name not in ("rz", "save_probabilities", "barrier")
    ]


def noisy_wires(qc: qiskit.QuantumCircuit) -> dict[int, list[tuple[str, tuple[int, ...]]]]:
    """The noisy gates on each physical qubit, in order: the circuit's DAG up to ``rz``.

    Gates on different qubits commute, so two circuits with the same wires have the same
    noisy gates in the same order wherever it matters.
    """
    wires: dict[int, list[tuple[str, tuple[int, ...]]]] = {}
    for op in noisy_ops(qc):
        for q in op[1]:
            wires.setdefault(q, []).append(op)
    return wires


def dropped_probability(model: NoiseModel, qc: qiskit.QuantumCircuit) -> float:
    """Total probability of the noise terms Aer leaves out over the gates of ``qc``."""
    total = 0.0
    for name, qubits in noisy_ops(qc):
        err = model._local_quantum_errors.get(name, {}).get(qubits)
        if err is not None:
            total += sum(p for p in err.probabilities if p <= AER_DROP)
    return total


# ------------------------------------------------------------------ equality with Aer


@pytest.mark.parametrize("name", ["uu_dagger", "vqc"])
def test_probabilities_equal_aer_from_backend_on_transpiled_circuits(
    name: str, rng: np.random.Generator
) -> None:
    dev = DeviceNoise.from_backend("FakeManilaV2", readout="symmetric")
    backend = dev.calibration.backend
    circ = circuits(rng)[name]
    layout = dev.layout_for(circ)
    model = NoiseModel.from_backend(backend)
    qcs = transpiled(circ, backend, layout)
    native = dev.prepare(circ)[0]
    # the same noisy gates in the same order on the same physical qubits as Qiskit's
    ours = from_native(native, backend.num_qubits, layout)[0]
    assert noisy_wires(ours) == noisy_wires(qcs[0])
    ref = aer_probabilities(qcs, kraus_wrapped(model, backend, model), layout)
    ref = with_readout(ref, readout_matrices(model, layout))
    got = probabilities(circ, dev)
    assert got.shape == (50, 2**circ.num_qubits)
    np.testing.assert_allclose(got, ref, atol=1e-9, rtol=0)
    # the unmodified model: equal up to the probability Aer's simulator leaves out
    raw = with_readout(
        aer_probabilities(transpiled(circ, backend, layout), model, layout),
        readout_matrices(model, layout),
    )
    tol = 2 * dropped_probability(model, qcs[0]) + 1e-12
    assert np.abs(got - raw).max() <= tol


@pytest.mark.slow
@pytest.mark.parametrize("device", ["FakeSherbrooke", "FakeTorino"])
def test_ecr_and_cz_devices_equal_aer_from_backend(device: str, rng: np.random.Generator) -> None:
    """127- and 133-qubit devices (ecr, cz); about 10 s each, most of it building errors."""
    dev = DeviceNoise.from_backend(device, readout="symmetric", layout=(5, 6))
    backend = dev.calibration.backend
    assert dev.calibration.coupled(5, 6)
    circ = circuits(rng, 20)["vqc"]
    qcs = transpiled(circ, backend, (5, 6))
    ours = from_native(dev.prepare(circ)[0], backend.num_qubits, (5, 6))[0]
    assert noisy_wires(ours) == noisy_wires(qcs[0])
    model = NoiseModel.from_backend(backend)
    ref = aer_probabilities(qcs, kraus_wrapped(model, backend, model, only=(5, 6)), (5, 6))
    ref = with_readout(ref, readout_matrices(model, (5, 6)))
    np.testing.assert_allclose(probabilities(circ, dev), ref, atol=1e-9, rtol=0)
    if device == "FakeTorino":  # its qubit 0 reads out wrong 17 % of the time
        placed = replace(dev, layout=None).layout_for(uu_dagger_circuit(0.1, 0.2))
        assert placed != (0,) and cal_readout(dev, placed[0]) < 0.05


def cal_readout(dev: DeviceNoise, q: int) -> float:
    a = dev.calibration.readout[q]
    return float(a[1, 0] + a[0, 1]) / 2


def test_asymmetric_readout_equals_the_backend_properties_model(rng: np.random.Generator) -> None:
    dev = DeviceNoise.from_backend("FakeManilaV2")  # readout="asymmetric", the default
    backend = dev.calibration.backend
    circ = circuits(rng)["vqc"]
    layout = dev.layout_for(circ)
    # Aer's model from the backend's properties has prob_meas1_prep0 / prob_meas0_prep1
    props_model = NoiseModel.from_backend_properties(backend.properties(), dt=backend.dt)
    mats = readout_matrices(props_model, layout)
    assert all(a[1, 0] != a[0, 1] for a in mats)  # asymmetric
    for q, a in zip(layout, mats, strict=True):
        qp = backend.properties().qubit_property(q)
        assert a[1, 0] == qp["prob_meas1_prep0"][0] and a[0, 1] == qp["prob_meas0_prep1"][0]
    gates = kraus_wrapped(NoiseModel.from_backend(backend), backend, props_model)
    ref = with_readout(aer_probabilities(transpiled(circ, backend, layout), gates, layout), mats)
    np.testing.assert_allclose(probabilities(circ, dev), ref, atol=1e-9, rtol=0)


def test_four_qubit_ring_on_a_line_device_with_swap_routing(rng: np.random.Generator) -> None:
    dev = DeviceNoise.from_backend("FakeManilaV2", route="swap", readout="symmetric")
    backend = dev.calibration.backend
    circ = sel_circuit(rng, 50)
    native, bound = dev.prepare(circ)
    assert bound.layout is not None  # a chain of 4 on the line 0-1-2-3-4
    assert all(dev.calibration.coupled(*bound.layout[q : q + 2]) for q in range(3))
    # each layer: 3 coupled cx, and cx(3, 0) through 2 SWAPs there and 2 back: 3 + 13
    assert sum(g.name == "cx" for g in native.gates) == 2 * 16
    model = NoiseModel.from_backend(backend)
    ref = aer_probabilities(
        from_native(native, backend.num_qubits, bound.layout),
        kraus_wrapped(model, backend, model),
        bound.layout,
    )
    ref = with_readout(ref, readout_matrices(model, bound.layout))
    np.testing.assert_allclose(probabilities(circ, dev), ref, atol=1e-9, rtol=0)
    # and the native circuit is the original circuit
    ideal = probabilities(circ)
    np.testing.assert_allclose(probabilities(native), ideal, atol=1e-12)


def test_four_qubit_ring_runs_on_a_square_of_a_ladder_device(rng: np.random.Generator) -> None:
    dev = DeviceNoise.from_backend("FakeMelbourneV2", readout="symmetric")
    backend = dev.calibration.backend
    circ = sel_circuit(rng, 20)
    layout = dev.layout_for(circ)
    cal = dev.calibration
    assert all(cal.coupled(layout[q], layout[(q + 1) % 4]) for q in range(4))
    qcs = transpiled(circ, backend, layout)
    ours = from_native(dev.prepare(circ)[0], backend.num_qubits, layout)[0]
    assert noisy_wires(ours) == noisy_wires(qcs[0])
    model = NoiseModel.from_backend(backend)
    ref = aer_probabilities(qcs, kraus_wrapped(model, backend, model), layout)
    ref = with_readout(ref, readout_matrices(model, layout))
    np.testing.assert_allclose(probabilities(circ, dev), ref, atol=1e-9, rtol=0)


def test_aer_backend_runs_device_noise_with_the_device_model(
    manila: DeviceNoise, rng: np.random.Generator
) -> None:
    from qdcnn.quantum.execute import run_probabilities

    circ = vqc_circuit(rng.uniform(0, 3, (8, 2)), rng.uniform(-3, 3, 4))
    exact = run_probabilities(circ, noise=manila)
    model = NoiseModel.from_backend(manila.calibration.backend)
    tol = (
        2
        * dropped_probability(
            model, transpiled(circ.select([0]), manila.calibration.backend, (0, 1))[0]
        )
        + 1e-12
    )
    assert np.abs(run_probabilities(circ, noise=manila, backend="aer") - exact).max() <= tol
    # shots: Aer applies the asymmetric readout error itself at measurement
    shots = 20000
    freq = run_probabilities(circ, noise=manila, backend="aer", shots=shots, rng=3)
    sigma = np.sqrt(exact * (1 - exact) / shots)
    assert (np.abs(freq - exact) < 4.5 * sigma + 1e-9).all()


# ------------------------------------------------------------------ the calibration


def test_gate_channels_are_depolarizing_then_thermal_relaxation(manila: DeviceNoise) -> None:
    """Each sx channel from textbook formulas and the calibration's T1, T2, time and error."""
    cal = manila.calibration
    target = cal.backend.target
    checked = 0
    for q in range(cal.num_qubits):
        t1, t2 = target.qubit_properties[q].t1, target.qubit_properties[q].t2
        t2 = min(t2, 2 * t1)
        t, err = target["sx"][(q,)].duration, target["sx"][(q,)].error
        damp = kraus_operators("amplitude-damping", 1 - math.exp(-t / t1))
        # after amplitude damping the coherence is exp(-t / 2T1); dephase the rest to exp(-t/T2)
        deph = kraus_operators("phase-damping", 1 - math.exp(-2 * t / t2 + t / t1))
        relax_ops = np.array([b @ a for a in damp for b in deph])
        f_relax = _average_fidelity(relax_ops)
        got = cal.channel("sx", (q,))
        if err <= 1 - f_relax:  # relaxation alone explains the error: no depolarizing part
            np.testing.assert_allclose(_superop(got), _superop(relax_ops), atol=1e-12)
            continue
        p = 2 * (err - (1 - f_relax)) / (2 * f_relax - 1)
        expected = np.array([r @ d for d in kraus_operators("depolarizing", p) for r in relax_ops])
        np.testing.assert_allclose(_superop(got), _superop(expected), atol=1e-12)
        # and its average gate infidelity is the calibrated sx error
        assert 1 - _average_fidelity(got) == pytest.approx(err, abs=1e-12)
        checked += 1
    assert checked >= 1


def _superop(ops: np.ndarray) -> np.ndarray:
    return sum(np.kron(k.conj(), k) for k in ops)


def _average_fidelity(ops: np.ndarray) -> float:
    d = ops.shape[-1]
    process = sum(abs(np.trace(k)) ** 2 for k in ops) / d**2
    return float((d * process + 1) / (d + 1))


def test_rz_is_virtual_and_readout_is_per_qubit(manila: DeviceNoise) -> None:
    cal = manila.calibration
    target = cal.backend.target
    assert all(
        target["rz"][(q,)].duration == 0 and target["rz"][(q,)].error == 0
        for q in range(cal.num_qubits)
    )
    assert not any(name == "rz" for name, _ in cal.aer_errors)
    circ = CircuitBuilder(2, 1).rz(0, 0.3).build()
    native, bound = manila.prepare(circ)
    assert [g.name for g in native.gates] == ["rz"] and bound.channels_after(native.gates[0]) == []
    mats = bound.readout_matrices(2)
    props = cal.backend.properties()
    assert bound.layout is not None
    for q, a in zip(bound.layout, mats, strict=True):
        assert a[1, 0] == props.qubit_property(q)["prob_meas1_prep0"][0]
        assert a[0, 1] == props.qubit_property(q)["prob_meas0_prep1"][0]
        np.testing.assert_allclose(a.sum(axis=0), 1.0, atol=1e-15)
    # |0> reads 1 with P(1|0) of its physical qubit: a known answer with readout only
    only_readout = DeviceNoise.from_backend(
        "FakeManilaV2", gate_error=False, thermal_relaxation=False, layout=(2,)
    )
    got = probabilities(uu_dagger_circuit(0.0, 0.0), only_readout)
    p10 = props.qubit_property(2)["prob_meas1_prep0"][0]
    np.testing.assert_allclose(got, [[1 - p10, p10]], atol=1e-15)


# ------------------------------------------------------------------ native gates


def _equal_up_to_phase(a: np.ndarray, b: np.ndarray) -> None:
    for x, y in zip(a, b, strict=True):
        k = np.unravel_index(np.argmax(abs(y)), y.shape)
        phase = x[k] / y[k]
        np.testing.assert_allclose(abs(phase), 1.0, atol=1e-12)
        np.testing.assert_allclose(x, phase * y, atol=1e-12)


@pytest.mark.parametrize("gate", ["ry", "rx", "rz", "p", "h", "x", "y", "z", "sx", "cx", "cx10"])
def test_native_rewrite_is_the_same_unitary(
    gate: str, manila: DeviceNoise, rng: np.random.Generator
) -> None:
    b = CircuitBuilder(2, 7)
    b.ry(0, rng.uniform(-3, 3, 7)).rx(1, rng.uniform(-3, 3, 7))
    if gate == "cx10":
        b.cx(1, 0)
    elif gate == "cx":
        b.cx(0, 1)
    elif gate in ("ry", "rx", "rz", "p"):
        b.add(gate, (1,), rng.uniform(-2 * np.pi, 2 * np.pi, 7))
    else:
        b.add(gate, (1,))
    circ = b.build()
    native = manila.prepare(circ)[0]
    assert {g.name for g in native.gates} <= {"rz", "sx", "x", "cx"}
    _equal_up_to_phase(unitary(native), unitary(circ))


@pytest.mark.parametrize("gate2", ["cx", "ecr", "cz"])
def test_two_qubit_rewrites_on_one_way_couplings(gate2: str, manila: DeviceNoise) -> None:
    """cx both ways and cz, on a device with ``gate2`` only from physical qubit 1 to 0."""
    one_way = replace(manila.calibration, two_qubit_gate=gate2, coupling=frozenset({(1, 0)}))
    gates = (
        Gate("h", (0,)),
        Gate("cz", (0, 1)),
        Gate("cx", (0, 1)),
        Gate("ry", (1,), np.array(0.3)),
        Gate("cx", (1, 0)),
        Gate("rx", (0,), np.array(-1.1)),
    )
    circ = CircuitBatch(2, 1, gates)
    native = to_native(circ, one_way, (0, 1))
    assert {g.name for g in native.gates} <= {"rz", "sx", "x", gate2}
    assert {g.qubits for g in native.gates if g.name == gate2} <= (
        {(1, 0), (0, 1)} if gate2 == "cz" else {(1, 0)}
    )
    qc = qiskit.QuantumCircuit(2)
    qc.h(0)
    qc.cz(0, 1)
    qc.cx(0, 1)
    qc.ry(0.3, 1)
    qc.cx(1, 0)
    qc.rx(-1.1, 0)
    _equal_up_to_phase(qi.Operator(to_qiskit(native, 0)).data[None], qi.Operator(qc).data[None])


def test_qiskit_transpile_level0_makes_the_same_noisy_gates(
    manila: DeviceNoise, rng: np.random.Generator
) -> None:
    backend = manila.calibration.backend
    b = CircuitBuilder(2, 1)
    for name in ("ry", "rx", "rz", "p", "h", "x", "y", "z", "sx"):
        for q in (0, 1):
            b.add(name, (q,), 0.7 if name in ("ry", "rx", "rz", "p") else None)
    b.cx(0, 1).cx(1, 0)
    circ = b.build()
    layout = (3, 2)
    ours = from_native(to_native(circ, manila.calibration, layout), backend.num_qubits, layout)
    assert noisy_wires(ours[0]) == noisy_wires(transpiled(circ, backend, layout)[0])


# ------------------------------------------------------------------ layout


def test_first_placement_layouts(rng: np.random.Generator) -> None:
    first = DeviceNoise.from_backend("FakeManilaV2", placement="first")
    cal = first.calibration
    assert default_layout(uu_dagger_circuit(0.1, 0.2), cal, "first") == (0,)
    assert default_layout(vqc_circuit([[0.1, 0.2]], np.zeros(4)), cal, "first") == (0, 1)
    # a ring has no placement on a line: the first chain, and its uncoupled cx is an error
    ring = sel_circuit(rng, 2)
    assert default_layout(ring, cal, "first") == (0, 1, 2, 3)
    with pytest.raises(ParameterError, match=r"cx\(3, 0\) runs on \(3, 0\), not coupled"):
        probabilities(ring, first)
    # a given layout: logical qubit i on layout[i]; shorter circuits use its first entries
    dev = DeviceNoise.from_backend("FakeManilaV2", layout=(3, 4, 2))
    assert dev.prepare(vqc_circuit([[0.1, 0.2]], np.zeros(4)))[1].layout == (3, 4)


def _estimated_error(circ: CircuitBatch, layout: tuple[int, ...], backend: object) -> float:
    """The documented layout score, from the backend's target and properties directly."""
    target, props = backend.target, backend.properties()  # type: ignore[attr-defined]
    sx_count = {"ry": 2, "rx": 2, "h": 1, "x": 1, "y": 1, "sx": 1}
    total = 0.0
    for g in circ.gates:
        if g.name == "cx":
            pair = tuple(layout[q] for q in g.qubits)
            total += min(target["cx"][q].error for q in (pair, pair[::-1]) if q in target["cx"])
        else:
            total += sx_count.get(g.name, 0) * target["sx"][(layout[g.qubits[0]],)].error
    for q in layout:
        qp = props.qubit_property(q)
        total += (qp["prob_meas1_prep0"][0] + qp["prob_meas0_prep1"][0]) / 2
    return total


@pytest.mark.parametrize("name", ["uu_dagger", "vqc"])
def test_best_placement_has_the_least_estimated_error(
    name: str, manila: DeviceNoise, rng: np.random.Generator
) -> None:
    backend = manila.calibration.backend
    circ = circuits(rng, 3)[name]
    edges = {tuple(sorted(e)) for e in backend.coupling_map.get_edges()}
    candidates = (
        [(q,) for q in range(backend.num_qubits)]
        if circ.num_qubits == 1
        else [e for e in edges] + [e[::-1] for e in edges]
    )
    scores = {c: _estimated_error(circ, c, backend) for c in candidates}
    best = min(sorted(scores), key=lambda c: scores[c])
    assert manila.layout_for(circ) == best
    assert default_layout(circ, manila.calibration) == best


def test_layout_changes_the_result_by_the_qubits_calibration(rng: np.random.Generator) -> None:
    circ = vqc_circuit(rng.uniform(0, 3, (5, 2)), rng.uniform(-3, 3, 4))
    a = probabilities(circ, DeviceNoise.from_backend("FakeManilaV2", layout=(0, 1)))
    b = probabilities(circ, DeviceNoise.from_backend("FakeManilaV2", layout=(2, 3)))
    assert np.abs(a - b).max() > 1e-3  # qubit 2 reads out far worse than qubit 0
    assert np.abs(a - probabilities(circ)).max() > 1e-3


# ------------------------------------------------------------------ parsing and errors


def test_parse_device_noise() -> None:
    dev = parse_noise("device:FakeManilaV2,layout:1-2,route:swap,readout:symmetric")
    assert isinstance(dev, DeviceNoise) and isinstance(dev, NoiseSpec)
    assert (dev.device, dev.layout, dev.route, dev.readout_model) == (
        "FakeManilaV2",
        (1, 2),
        "swap",
        "symmetric",
    )
    assert parse_noise(dev.label()) == dev
    assert parse_noise("device:fakemanilav2").label() == "device:FakeManilaV2"
    first = parse_noise("device:FakeManilaV2,layout:first")
    assert first.placement == "first" and parse_noise(first.label()) == first
    assert not dev.is_ideal


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("device:FakeNowhere", "device='FakeNowhere' is invalid: an IBM fake backend, one of"),
        ("device:FakeCairoV2", "one of cx, ecr, cz (this one has cx, delay, ecr"),
        ("device:FakeManilaV2,depolarizing:0.1", "does not combine with a channel"),
        ("device:FakeManilaV2,layout:0-0", "layout=(0, 0) is invalid: distinct"),
        ("device:FakeManilaV2,layout:0-9", "layout=(0, 9) is invalid: qubits in [0, 4]"),
        ("device:FakeManilaV2,layout:a-b", "layout='a-b' is invalid"),
        ("device:FakeManilaV2,layout:worst", "layout='worst' is invalid"),
        ("device:FakeManilaV2,route:teleport", "route='teleport' is invalid"),
        ("device:FakeManilaV2,readout:0.1", "readout='0.1' is invalid"),
    ],
)
def test_bad_device_noise(text: str, message: str) -> None:
    with pytest.raises(ParameterError) as err:
        parse_noise(text)
    assert message in str(err.value)
    if "FakeNowhere" in text:
        assert "FakeManilaV2" in str(err.value) and "FakeMelbourneV2" in str(err.value)


def test_misuse_is_an_error(manila: DeviceNoise) -> None:
    with pytest.raises(ParameterError, match="prepare"):
        manila.channels_after(Gate("ry", (0,), np.array(0.1)))  # not a native gate
    with pytest.raises(ParameterError, match="prepare"):
        manila.channels_after(Gate("sx", (0,)))  # no layout bound yet
    with pytest.raises(ParameterError, match="channels_after"):
        manila.kraus()
    with pytest.raises(ParameterError, match="at least 4 qubits"):
        DeviceNoise.from_backend("FakeManilaV2", layout=(0, 1)).prepare(
            CircuitBuilder(4, 1).h(3).build()
        )
    with pytest.raises(ParameterError, match="at most 5 qubits"):
        manila.prepare(CircuitBuilder(6, 1).h(5).build())


# ------------------------------------------------------------------ classifiers and shadows


def test_classifiers_and_shadow_detector_take_device_noise(
    manila: DeviceNoise, rng: np.random.Generator
) -> None:
    from qdcnn.quantum.direction import UUDirectionClassifier
    from qdcnn.quantum.execute import run_probabilities
    from qdcnn.quantum.uu_dagger import fidelity
    from qdcnn.quantum.vqc import VQCClassifier, basis_probabilities

    X = rng.normal(0, 1, (60, 2))
    y = (X[:, 0] > 0).astype(int) * 2
    uu = UUDirectionClassifier(shots=None).fit(X, y)
    p = uu.circuit_probabilities(X[:5], noise=manila)
    theta = uu.slope_angles(X[:5])
    ref = run_probabilities(uu_dagger_circuit(uu.centroid_, theta.T.ravel()), noise=manila)[:, 0]
    np.testing.assert_allclose(p, np.stack([ref[:5], ref[5:]], axis=1), atol=1e-15)
    assert np.abs(p - uu.circuit_probabilities(X[:5])).max() > 1e-4

    vqc = VQCClassifier(maxiter=10, shots=None).fit(X, y)
    noisy = vqc.basis_probabilities(X[:5], noise=manila)
    assert noisy.shape == (5, 4) and np.abs(noisy - vqc.basis_probabilities(X[:5])).max() > 1e-4
    assert vqc.predict(X[:5], noise=manila).shape == (5,)
    assert basis_probabilities(np.zeros((1, 2)), np.zeros(4), noise=manila).shape == (1, 4)

    from qdcnn.data.synthetic import generate_scene
    from qdcnn.vision.shadows import ShadowConfig, detect_shadows_uu

    scene = generate_scene("track2", seed=3)
    cfg = ShadowConfig(centroid=120.0, shots=None)
    det = detect_shadows_uu(scene.image, cfg, noise=manila)
    ideal = detect_shadows_uu(scene.image, cfg)
    assert det.block_scores.shape == ideal.block_scores.shape
    assert np.abs(det.block_scores - ideal.block_scores).max() > 1e-4
    # each block's score is the device-noise P(0) of its UU-dagger circuit
    from qdcnn.quantum.uu_dagger import value_to_angle

    blocks = det.block_values.ravel()[:20]
    np.testing.assert_allclose(
        fidelity(value_to_angle(120.0), value_to_angle(blocks), shots=None, noise=manila),
        det.block_scores.ravel()[:20],
        atol=1e-12,
    )


# ------------------------------------------------------------------ NoiseSpec unchanged


def _old_density_matrix(circuit: CircuitBatch, spec: NoiseSpec) -> np.ndarray:
    """The density-matrix loop as it was before the GateNoise protocol (verbatim logic)."""
    from qdcnn.quantum.simulator import _gate_unitary

    n = circuit.num_qubits
    rho = np.zeros((circuit.batch_size, 2**n, 2**n), dtype=np.complex128)
    rho[:, 0, 0] = 1.0
    kraus = spec.kraus()
    kraus_on = [] if kraus is None else [embed(kraus, q, n) for q in range(n)]
    for g in circuit.gates:
        u = _gate_unitary(g, n)
        rho = u @ rho @ np.conj(np.swapaxes(u, 1, 2))
        for q in g.qubits if kraus_on else ():
            k = kraus_on[q]
            rho = np.einsum("kij,bjl,kml->bim", k, rho, k.conj(), optimize=True)
    return rho


@pytest.mark.parametrize("channel", list(noise_mod.CHANNELS))
def test_noise_spec_results_are_unchanged(channel: str, rng: np.random.Generator) -> None:
    from qdcnn.quantum.simulator import density_matrix

    spec = NoiseSpec(channel, 0.23, readout=0.07)
    for circ in (
        vqc_circuit(rng.uniform(0, 3, (9, 2)), rng.uniform(-3, 3, 4)),
        uu_dagger_circuit(0.4, rng.uniform(0, 3, 9)),
        sel_circuit(rng, 3, layers=1),
    ):
        old = _old_density_matrix(circ, spec)
        # up to 2 qubits the same arithmetic as before, bit for bit; larger registers now
        # apply each channel to the touched qubit only (the same numbers to round-off)
        same = np.testing.assert_array_equal if circ.num_qubits <= 2 else _close
        same(density_matrix(circ, spec), old)
        probs = np.clip(np.einsum("bii->bi", old).real, 0.0, None)
        a = spec.readout_matrix()
        t = probs.reshape((probs.shape[0],) + (2,) * circ.num_qubits)
        for q in range(circ.num_qubits):
            t = np.moveaxis(
                np.tensordot(t, a, axes=([circ.num_qubits - q], [1])), -1, circ.num_qubits - q
            )
        old_probs = t.reshape(probs.shape)
        old_probs = old_probs / old_probs.sum(axis=1, keepdims=True)
        same(probabilities(circ, spec), old_probs)


def _close(a: np.ndarray, b: np.ndarray) -> None:
    np.testing.assert_allclose(a, b, atol=1e-14, rtol=0)


def test_qubit_table_reports_the_calibration(manila: DeviceNoise) -> None:
    cal = manila.calibration
    target, props = cal.backend.target, cal.backend.properties()
    rows = cal.qubit_table((2, 0))
    assert [r["qubit"] for r in rows] == [2, 0]
    for r in rows:
        q = r["qubit"]
        assert r["t1_us"] == pytest.approx(target.qubit_properties[q].t1 * 1e6, rel=1e-12)
        assert r["t2_us"] == pytest.approx(target.qubit_properties[q].t2 * 1e6, rel=1e-12)
        assert r["sx_error"] == target["sx"][(q,)].error
        assert r["sx_ns"] == pytest.approx(target["sx"][(q,)].duration * 1e9, rel=1e-12)
        assert r["readout_p1_given_0"] == props.qubit_property(q)["prob_meas1_prep0"][0]
        assert r["readout_p0_given_1"] == props.qubit_property(q)["prob_meas0_prep1"][0]
    assert len(cal.qubit_table()) == 5


def test_the_hybrid_head_circuit_runs_under_device_noise_as_its_expanded_form() -> None:
    """Rot lowers to RZ RY RZ: the head's circuit equals the same circuit written that way."""
    from qdcnn.quantum.circuits import CircuitBuilder
    from qdcnn.quantum.noise_text import parse_noise
    from qdcnn.quantum.simulator import probabilities
    from qdcnn.quantum.templates import entangler_ranges, head_circuit

    rng = np.random.default_rng(5)
    x = rng.uniform(-np.pi, np.pi, (6, 4))
    w = rng.uniform(0, 2 * np.pi, (2, 4, 3))
    noise = parse_noise("device:FakeMelbourneV2,route:swap")  # layer 2 has cx(0, 2)
    head = probabilities(head_circuit(x, w), noise)
    b = CircuitBuilder(4, 6)
    for q in range(4):
        b.ry(q, x[:, q])
    for layer, r in zip(range(2), entangler_ranges(4, 2), strict=True):
        for q in range(4):
            phi, theta, omega = w[layer, q]
            b.rz(q, phi).ry(q, theta).rz(q, omega)
        for q in range(4):
            b.cx(q, (q + r) % 4)
    expanded = probabilities(b.build("expanded"), noise)
    np.testing.assert_allclose(head, expanded, atol=1e-12)
    ideal = probabilities(head_circuit(x, w))
    assert np.abs(head - ideal).max() > 1e-4  # the device's noise does change the result
