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
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from qdcnn.errors import ParameterError
from qdcnn.quantum.gates import I2, X, Y, Z

Kraus = NDArray[np.complex128]


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


def check_probability(name: str, p: float) -> float:
    """Return ``p`` as float if it is in [0, 1], else raise :class:`ParameterError`."""
    number = isinstance(p, int | float) and not isinstance(p, bool)
    if not number or not math.isfinite(p) or not 0 <= p <= 1:
        raise ParameterError(name, p, "a probability in [0, 1]")
    return float(p)


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

    def readout_matrix(self) -> NDArray[np.float64]:
        """``A[measured, prepared]`` for one qubit."""
        e = self.readout
        return np.array([[1 - e, e], [e, 1 - e]])

    def label(self) -> str:
        parts = [] if self.channel is None else [f"{self.channel}:{self.p:g}"]
        if self.readout:
            parts.append(f"readout:{self.readout:g}")
        return ",".join(parts) or "ideal"


def parse_noise(text: str) -> NoiseSpec:
    """Parse ``"CHANNEL:P"`` (optionally ``",readout:E"``) into a :class:`NoiseSpec`.

    Examples
    --------
    >>> parse_noise("bit-flip:0.1")
    NoiseSpec(channel='bit-flip', p=0.1, readout=0.0)
    """
    channel: str | None = None
    p = 0.0
    readout = 0.0
    for part in filter(None, (t.strip() for t in text.split(","))):
        name, sep, value = part.partition(":")
        if not sep:
            raise ParameterError("noise", text, "CHANNEL:P, e.g. depolarizing:0.1")
        try:
            v = float(value)
        except ValueError:
            raise ParameterError("noise", text, f"a number after '{name}:'") from None
        if name == "readout":
            readout = v
        else:
            channel, p = check_channel(name), v
    return NoiseSpec(channel, p, readout)
