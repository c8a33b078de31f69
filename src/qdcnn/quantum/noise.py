"""The paper's six one-qubit noise channels as Kraus operators (Sec. II-D; NOTES 7).

A channel acts as ``rho' = sum_i E_i rho E_i^dagger`` (the paper prints
``E^dagger rho E``; NOTES 7 records the erratum). In every simulation qdcnn applies
the channel after every gate, on every qubit the gate touches -- after a ``cx``,
on both qubits -- which is what a Qiskit Aer ``NoiseModel`` does with
``add_all_qubit_quantum_error(error, gates)`` for one-qubit gates and
``error.tensor(error)`` for ``cx``. An optional symmetric readout error flips each
measured bit with probability ``readout``.

Phase damping comes in two forms: ``phase-damping`` is the textbook channel
(Nielsen & Chuang Eq. 8.127, Qiskit's ``phase_damping_error``), and
``phase-damping-paper`` is the paper's printed operators
``sqrt(1-p) Z, sqrt(p)|0><0|, sqrt(p)|1><1|``. Note that the printed form applies
a full ``Z`` at ``p = 0``.

How a simulator reads noise
---------------------------
Every noise object -- :class:`NoiseSpec` here, :class:`qdcnn.quantum.device.DeviceNoise`
for a real device's calibration -- follows the :class:`GateNoise` protocol, and a
simulator needs nothing else from it::

    native, bound = noise.prepare(circuit)      # the gates that run, the noise bound to them
    for gate in native.gates:
        rho = U rho U^dagger                    # the gate itself
        for qubits, kraus in bound.channels_after(gate):
            rho = sum_k K_k rho K_k^dagger      # on ``qubits`` of the circuit
    probs = diag(rho), then bound.readout_matrices(n)[q] on each qubit q

:class:`NoiseSpec` runs the circuit as it is and returns its one channel on every qubit a
gate touches; device noise first rewrites the circuit into the device's native gates
(``rz``, ``sx``, ``x``, ``cx``) on a qubit layout and returns per-gate, per-qubit
calibrated channels. The NumPy density-matrix simulator
(:func:`qdcnn.quantum.simulator.density_matrix`) is written this way, and any other
simulator (for example a PyTorch one) can be: the protocol returns plain NumPy arrays.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Protocol, TypeGuard, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from qdcnn._validation import check_probability
from qdcnn.errors import ParameterError
from qdcnn.quantum.gates import I2, X, Y, Z

if TYPE_CHECKING:
    from qdcnn.quantum.circuits import CircuitBatch, Gate

Kraus = NDArray[np.complex128]
#: ``(qubits, kraus)``: Kraus operators of shape ``(K, 2**k, 2**k)`` acting on the ``k``
#: circuit qubits ``qubits``, ``qubits[0]`` the least significant bit of the operator's
#: row/column index (Qiskit's convention)
Channel = tuple[tuple[int, ...], Kraus]


def _ops(*mats: NDArray[np.generic]) -> Kraus:
    return np.stack(mats).astype(np.complex128)


def bit_flip(p: float) -> Kraus:
    """``E0 = sqrt(1-p) I``, ``E1 = sqrt(p) X``."""
    return _ops(math.sqrt(1 - p) * I2, math.sqrt(p) * X)


def phase_flip(p: float) -> Kraus:
    """``E0 = sqrt(1-p) I``, ``E1 = sqrt(p) Z``."""
    return _ops(math.sqrt(1 - p) * I2, math.sqrt(p) * Z)


def bit_phase_flip(p: float) -> Kraus:
    """``E0 = sqrt(1-p) I``, ``E1 = sqrt(p) Y``."""
    return _ops(math.sqrt(1 - p) * I2, math.sqrt(p) * Y)


def depolarizing(p: float) -> Kraus:
    """``rho -> (1-p) rho + p I/2``: ``sqrt(1-3p/4) I`` and ``sqrt(p/4) X, Y, Z``.

    Equal to Qiskit's ``depolarizing_error(p, 1)``.
    """
    return _ops(math.sqrt(1 - 3 * p / 4) * I2, *(math.sqrt(p / 4) * m for m in (X, Y, Z)))


def amplitude_damping(p: float) -> Kraus:
    """``E0 = [[1, 0], [0, sqrt(1-p)]]``, ``E1 = sqrt(p) |0><1|``.

    Equal to Qiskit's ``amplitude_damping_error(p)``.
    """
    e0 = np.array([[1, 0], [0, math.sqrt(1 - p)]], dtype=np.complex128)
    e1 = np.array([[0, math.sqrt(p)], [0, 0]], dtype=np.complex128)
    return _ops(e0, e1)


def phase_damping(p: float) -> Kraus:
    """Textbook phase damping: ``diag(1, sqrt(1-p))``, ``diag(0, sqrt(p))``.

    Equal to Qiskit's ``phase_damping_error(p)``.
    """
    e0 = np.diag([1.0, math.sqrt(1 - p)]).astype(np.complex128)
    e1 = np.diag([0.0, math.sqrt(p)]).astype(np.complex128)
    return _ops(e0, e1)


def phase_damping_paper(p: float) -> Kraus:
    """The paper's printed phase damping: ``sqrt(1-p) Z``, ``sqrt(p)|0><0|``, ``sqrt(p)|1><1|``."""
    p0 = np.diag([1.0, 0.0]).astype(np.complex128)
    p1 = np.diag([0.0, 1.0]).astype(np.complex128)
    return _ops(math.sqrt(1 - p) * Z, math.sqrt(p) * p0, math.sqrt(p) * p1)


CHANNELS: dict[str, Callable[[float], Kraus]] = {
    "bit-flip": bit_flip,
    "phase-flip": phase_flip,
    "bit-phase-flip": bit_phase_flip,
    "depolarizing": depolarizing,
    "amplitude-damping": amplitude_damping,
    "phase-damping": phase_damping,
    "phase-damping-paper": phase_damping_paper,
}
#: The six channels of the paper's Fig. 7, phase damping in its textbook form.
PAPER_CHANNELS: tuple[str, ...] = (
    "bit-flip",
    "phase-flip",
    "bit-phase-flip",
    "depolarizing",
    "amplitude-damping",
    "phase-damping",
)


def check_channel(name: str) -> str:
    """Return ``name`` if it is a known channel, else raise :class:`ParameterError`."""
    if name not in CHANNELS:
        raise ParameterError("channel", name, f"one of {', '.join(CHANNELS)}")
    return name


def kraus_operators(channel: str, p: float) -> Kraus:
    """Kraus operators of ``channel`` at strength ``p``, shape ``(k, 2, 2)``."""
    return CHANNELS[check_channel(channel)](check_probability("p", p))


def is_cptp(ops: Kraus, atol: float = 1e-12) -> bool:
    """Whether ``sum_i E_i^dagger E_i = I``.

    A map in Kraus form is completely positive by construction, so this
    completeness relation is what makes it a CPTP channel.
    """
    total = np.einsum("kji,kjl->il", ops.conj(), ops)
    return bool(np.allclose(total, np.eye(ops.shape[-1]), atol=atol))


@runtime_checkable
class GateNoise(Protocol):
    """What a simulator needs from a noise model: the gates that run and what follows each.

    Implemented by :class:`NoiseSpec` (one channel after every gate on every qubit it
    touches) and :class:`qdcnn.quantum.device.DeviceNoise` (a device's calibration).
    """

    @property
    def is_ideal(self) -> bool:
        """True when the model adds no gate noise and no readout error."""
        ...

    def prepare(self, circuit: CircuitBatch) -> tuple[CircuitBatch, GateNoise]:
        """The circuit as it runs under this noise, and the noise bound to that circuit.

        :meth:`channels_after` and :meth:`readout_matrices` are called on the returned
        noise, with the gates of the returned circuit.
        """
        ...

    def channels_after(self, gate: Gate) -> list[Channel]:
        """The channels that act right after ``gate``, in order, as ``(qubits, kraus)``."""
        ...

    def readout_matrices(self, num_qubits: int) -> list[NDArray[np.float64]] | None:
        """Per qubit ``A[measured, prepared]`` (2 x 2, columns sum to 1), or ``None`` for none."""
        ...

    def label(self) -> str:
        """Short text that names the noise, e.g. ``depolarizing:0.1``."""
        ...


def is_noise(value: object) -> TypeGuard[GateNoise]:
    """Whether ``value`` is a noise model: an object that follows :class:`GateNoise`
    (:class:`NoiseSpec`, device noise, or any other class with its members)."""
    return isinstance(value, GateNoise)


@dataclass(frozen=True)
class NoiseSpec:
    """Noise applied in a simulation: a channel after every gate, plus readout error.

    Attributes
    ----------
    channel : str or None
        A name from :data:`CHANNELS`, or ``None`` for no gate noise.
    p : float
        Channel strength in [0, 1].
    readout : float
        Probability that a measured bit is flipped, in [0, 1].
    """

    channel: str | None = None
    p: float = 0.0
    readout: float = 0.0

    def __post_init__(self) -> None:
        if self.channel is not None:
            check_channel(self.channel)
        check_probability("p", self.p)
        check_probability("readout", self.readout)

    @property
    def is_ideal(self) -> bool:
        """True when neither gate noise nor readout error is present."""
        return self.channel is None and self.readout == 0.0

    def kraus(self) -> Kraus | None:
        """Gate-noise Kraus operators, or ``None`` without a channel."""
        return None if self.channel is None else kraus_operators(self.channel, self.p)

    @cached_property
    def _shared_kraus(self) -> Kraus | None:
        ops = self.kraus()
        if ops is not None:
            ops.setflags(write=False)  # one array is handed out for every gate
        return ops

    def prepare(self, circuit: CircuitBatch) -> tuple[CircuitBatch, NoiseSpec]:
        """The circuit runs as it is; see :class:`GateNoise`."""
        return circuit, self

    def channels_after(self, gate: Gate) -> list[Channel]:
        """The channel on each qubit ``gate`` touches (on both qubits of a ``cx``).

        The Kraus array is the same object for every gate (read-only), so a simulator may
        cache what it derives from it by identity.
        """
        ops = self._shared_kraus
        return [] if ops is None else [((q,), ops) for q in gate.qubits]

    def readout_matrices(self, num_qubits: int) -> list[NDArray[np.float64]] | None:
        """:meth:`readout_matrix` on every qubit, or ``None`` without readout error."""
        return None if self.readout == 0.0 else [self.readout_matrix()] * num_qubits

    def readout_matrix(self) -> NDArray[np.float64]:
        """``A[measured, prepared]`` for one qubit."""
        e = self.readout
        return np.array([[1 - e, e], [e, 1 - e]])

    def label(self) -> str:
        parts = [] if self.channel is None else [f"{self.channel}:{self.p:g}"]
        if self.readout:
            parts.append(f"readout:{self.readout:g}")
        return ",".join(parts) or "ideal"
