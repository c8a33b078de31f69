"""The same batched circuits as Qiskit ``QuantumCircuit`` objects, run on Qiskit Aer.

Qiskit and qiskit-aer are the optional ``quantum`` extra and are imported only
inside these functions. :func:`run_aer` submits all circuits of a batch in one
``AerSimulator.run`` call.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._optional import require
from qdcnn._validation import check_shots
from qdcnn.quantum.circuits import CircuitBatch
from qdcnn.quantum.noise import NoiseSpec

if TYPE_CHECKING:
    from qdcnn.quantum.device import DeviceNoise

_ONE_QUBIT_GATES = ("ry", "rx", "rz", "p", "h", "x", "y", "z", "u")
#: the one-qubit gates a NoiseSpec channel follows in an Aer noise model (with the native sx)
_NOISY_ONE_QUBIT_GATES: tuple[str, ...] = (*_ONE_QUBIT_GATES, "sx")
#: two-qubit gates of the noise model (each followed by the channel on both qubits)
_TWO_QUBIT_GATES = ("cx", "cz")


def _append_gate(qc: Any, name: str, qubits: tuple[int, ...], params: tuple[float, ...]) -> None:
    """Append one qdcnn gate to the Qiskit circuit ``qc``.

    ``rot(phi, theta, omega)`` becomes Qiskit's ``u(theta, omega, phi)`` with the global
    phase ``-(phi + omega) / 2`` added to ``qc``, so states agree exactly (OpenQASM 3
    export drops the global phase, which no measurement can see).
    """
    if name == "rot":
        phi, theta, omega = params
        qc.u(theta, omega, phi, *qubits)
        qc.global_phase -= (phi + omega) / 2
    else:
        getattr(qc, name)(*params, *qubits)


def to_qiskit(circuit: CircuitBatch, index: int | None = None) -> Any:
    """Build Qiskit circuits: a list of ``B`` circuits, or circuit ``index`` alone.

    Returns
    -------
    list of qiskit.QuantumCircuit or qiskit.QuantumCircuit
    """
    qiskit = require("qiskit", "building Qiskit circuits")
    indices = range(circuit.batch_size) if index is None else [index]
    out = []
    for i in indices:
        qc = qiskit.QuantumCircuit(circuit.num_qubits, name=f"{circuit.name}_{i}")
        for gate in circuit.gates:
            _append_gate(qc, gate.name, gate.qubits, gate.params(i))
        out.append(qc)
    return out if index is None else out[0]


def _aer_noise_model(noise: NoiseSpec, gate_names: tuple[str, ...] = _NOISY_ONE_QUBIT_GATES) -> Any:
    """A qiskit-aer ``NoiseModel`` equal to ``noise`` as qdcnn applies it.

    The channel follows every one-qubit gate in ``gate_names`` (``u`` is qdcnn's
    ``rot``) and, tensored with itself, every ``cx`` and ``cz``; the readout error
    acts on every measured qubit. For a :class:`~qdcnn.quantum.device.DeviceNoise` it is
    the device's model on its physical qubits (:func:`_device_noise_model`).
    """
    from qdcnn.quantum.device import DeviceNoise

    if isinstance(noise, DeviceNoise):
        return _device_noise_model(noise)
    aer_noise = require("qiskit_aer", "Aer noise models").noise
    info = require("qiskit", "Aer noise models").quantum_info
    model = aer_noise.NoiseModel(basis_gates=[*gate_names, *_TWO_QUBIT_GATES])
    kraus = noise.kraus()
    if kraus is not None:
        err = aer_noise.QuantumError(info.Kraus(list(kraus)))
        model.add_all_qubit_quantum_error(err, list(gate_names))
        model.add_all_qubit_quantum_error(err.tensor(err), list(_TWO_QUBIT_GATES))
    if noise.readout:
        model.add_all_qubit_readout_error(aer_noise.ReadoutError(noise.readout_matrix().T))
    return model


def _device_noise_model(noise: DeviceNoise) -> Any:
    """The Aer ``NoiseModel`` of a ``DeviceNoise``, on the device's physical qubits.

    The gate errors are the ones ``NoiseModel.from_backend`` adds for the native gates
    (the same ``QuantumError`` objects qdcnn's Kraus operators come from), and the readout
    errors are the ``DeviceNoise``'s (asymmetric by default, see
    :mod:`qdcnn.quantum.device`).
    """
    aer_noise = require("qiskit_aer", "Aer noise models").noise
    cal = noise.calibration
    model = aer_noise.NoiseModel(basis_gates=list(cal.backend.operation_names))
    for (name, qubits), error in cal.aer_errors.items():
        model.add_quantum_error(error, name, list(qubits))
    for q, a in cal.readout.items():
        model.add_readout_error(aer_noise.ReadoutError(np.asarray(a).T), [q])
    return model


def _on_device(circuits: list[Any], layout: tuple[int, ...], num_qubits: int) -> list[Any]:
    """Place logical circuits on physical qubits ``layout`` of a ``num_qubits``-qubit device."""
    qiskit = require("qiskit", "building Qiskit circuits")
    out = []
    for qc in circuits:
        wide = qiskit.QuantumCircuit(num_qubits, name=qc.name)
        out.append(wide.compose(qc, qubits=list(layout)))
    return out


def run_aer(
    circuit: CircuitBatch,
    *,
    shots: int | None = None,
    noise: NoiseSpec | None = None,
    seed: int | None = None,
    method: str | None = None,
) -> NDArray[np.float64] | NDArray[np.int64]:
    """Run every circuit of the batch on ``AerSimulator`` in one call.

    Parameters
    ----------
    shots : int or None
        ``None`` returns exact probabilities (Aer ``save_probabilities``);
        otherwise counts from ``shots`` measurements per circuit.
    noise : NoiseSpec or None
        Gate and readout noise (exact probabilities ignore readout error, as
        Aer applies it only to measurements). A ``DeviceNoise`` runs the circuit's
        native gates on the device's physical qubits (``layout``) with the device's
        noise model; the outcomes are indexed by logical qubit.
    seed : int or None
        ``seed_simulator`` for reproducible shots.
    method : str or None
        Aer method; default ``statevector`` without noise, ``density_matrix`` with.

    Returns
    -------
    ndarray, shape (B, 2**n)
        Probabilities (float) or counts (int), index = basis state, qubit 0 = LSB.
    """
    aer = require("qiskit_aer", "the Aer backend")
    from qdcnn.quantum.device import DeviceNoise

    noisy = noise is not None and not noise.is_ideal
    sim = aer.AerSimulator(
        method=method or ("density_matrix" if noisy else "statevector"),
        noise_model=_aer_noise_model(noise) if noisy and noise is not None else None,
    )
    n = circuit.num_qubits
    measured = list(range(n))
    if isinstance(noise, DeviceNoise) and noisy:
        # native gates on the device's physical qubits, so its per-qubit errors apply
        native, bound = noise.prepare(circuit)
        assert bound.layout is not None
        measured = list(bound.layout[:n])
        circuits = _on_device(to_qiskit(native), bound.layout[:n], bound.calibration.num_qubits)
    else:
        circuits = to_qiskit(circuit)
    d = 2**n
    if shots is None:
        for qc in circuits:
            qc.save_probabilities(measured)
        result = sim.run(circuits, shots=1, seed_simulator=seed).result()
        return np.array([np.asarray(result.data(i)["probabilities"]) for i in range(len(circuits))])
    check_shots(shots)
    qiskit = require("qiskit", "building Qiskit circuits")
    for qc in circuits:
        qc.add_register(qiskit.ClassicalRegister(n, "meas"))
        qc.measure(measured, list(range(qc.num_clbits - n, qc.num_clbits)))
    result = sim.run(circuits, shots=shots, seed_simulator=seed).result()
    counts = np.zeros((len(circuits), d), dtype=np.int64)
    for i in range(len(circuits)):
        for key, c in result.get_counts(i).items():
            counts[i, int(key.replace(" ", ""), 2)] = c
    return counts
