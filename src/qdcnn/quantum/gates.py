"""Batched gate matrices in Qiskit's conventions.

Each function takes an array of angles of any shape ``S`` and returns matrices of
shape ``S + (2, 2)``, so one call builds the gate for a whole batch of circuits.

The definitions follow Qiskit's circuit library: ``RY(t) = exp(-i t Y / 2)``,
``RZ(t) = diag(e^{-i t/2}, e^{i t/2})``, ``P(l) = diag(1, e^{i l})``. ``Rot`` is
PennyLane's general rotation ``Rot(phi, theta, omega) = RZ(omega) RY(theta) RZ(phi)``,
whose three angles are the last axis of its angle array (``S + (3,)``).
``SX = sqrt(X)`` is the native gate of IBM devices (see :mod:`qdcnn.quantum.device`).
Real gates (RY, H, X, Z) are returned as ``float64`` so that circuits made only
of them are simulated in real arithmetic; the others are ``complex128``.

The two-qubit gates ``cx`` and ``cz`` are permutations and signs of basis states;
:data:`CX` and :data:`CZ` are their matrices on ``(control, target)`` with the
control as qubit 0 (the least significant bit), for reference.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from qdcnn._validation import check_shape

Matrix = NDArray[np.complex128] | NDArray[np.float64]

I2: Matrix = np.eye(2)
X: Matrix = np.array([[0.0, 1.0], [1.0, 0.0]])
Y: Matrix = np.array([[0, -1j], [1j, 0]], dtype=np.complex128)
Z: Matrix = np.array([[1.0, 0.0], [0.0, -1.0]])
H: Matrix = np.array([[1.0, 1.0], [1.0, -1.0]]) / np.sqrt(2.0)
#: ``SX = sqrt(X)``, a native gate of IBM devices (Qiskit's ``SXGate``)
SX: Matrix = np.array([[1 + 1j, 1 - 1j], [1 - 1j, 1 + 1j]], dtype=np.complex128) / 2


def _stack(
    a: NDArray[np.generic], b: NDArray[np.generic], c: NDArray[np.generic], d: NDArray[np.generic]
) -> Matrix:
    out = np.empty((*np.shape(a), 2, 2), dtype=np.result_type(a, b, c, d))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1] = a, b, c, d
    return out


def ry(theta: ArrayLike) -> Matrix:
    """``RY(theta)``: ``[[cos t/2, -sin t/2], [sin t/2, cos t/2]]`` (real)."""
    t = np.asarray(theta, dtype=np.float64) / 2
    c, s = np.cos(t), np.sin(t)
    return _stack(c, -s, s, c)


def rx(theta: ArrayLike) -> Matrix:
    """``RX(theta)``: ``[[cos t/2, -i sin t/2], [-i sin t/2, cos t/2]]``."""
    t = np.asarray(theta, dtype=np.float64) / 2
    c, s = np.cos(t).astype(np.complex128), -1j * np.sin(t)
    return _stack(c, s, s, c)


def rz(theta: ArrayLike) -> Matrix:
    """``RZ(theta)``: ``diag(exp(-i t/2), exp(i t/2))``."""
    t = np.asarray(theta, dtype=np.float64) / 2
    zero = np.zeros_like(t, dtype=np.complex128)
    return _stack(np.exp(-1j * t), zero, zero, np.exp(1j * t))


def phase(lam: ArrayLike) -> Matrix:
    """Phase gate ``P(lambda)``: ``diag(1, exp(i lambda))``."""
    t = np.asarray(lam, dtype=np.float64)
    zero = np.zeros_like(t, dtype=np.complex128)
    return _stack(np.ones_like(zero), zero, zero, np.exp(1j * t))


def rot(angles: ArrayLike) -> Matrix:
    """``Rot(phi, theta, omega) = RZ(omega) RY(theta) RZ(phi)`` for angles ``S + (3,)``.

    PennyLane's ``qml.Rot``; in closed form, with ``c, s = cos(theta/2), sin(theta/2)``,
    ``[[e^{-i(phi+omega)/2} c, -e^{i(phi-omega)/2} s], [e^{-i(phi-omega)/2} s,
    e^{i(phi+omega)/2} c]]``. Equal to Qiskit's ``U(theta, omega, phi)`` times the global
    phase ``e^{-i(phi+omega)/2}``.
    """
    a = np.asarray(angles, dtype=np.float64)
    check_shape("rot angles", a, "*,3", "three angles on the last axis")
    phi, theta, omega = a[..., 0], a[..., 1], a[..., 2]
    c, s = np.cos(theta / 2), np.sin(theta / 2)
    plus, minus = np.exp(-0.5j * (phi + omega)), np.exp(0.5j * (phi - omega))
    return _stack(c * plus, -s * minus, s * np.conj(minus), c * np.conj(plus))


PARAMETRIC: dict[str, Callable[[ArrayLike], Matrix]] = {
    "ry": ry,
    "rx": rx,
    "rz": rz,
    "p": phase,
    "rot": rot,
}
#: number of angles each parametric gate takes (the last axis of a ``rot`` angle array)
ANGLE_COUNT: dict[str, int] = {"ry": 1, "rx": 1, "rz": 1, "p": 1, "rot": 3}
CONSTANT: dict[str, Matrix] = {"h": H, "x": X, "y": Y, "z": Z}
CONSTANT["sx"] = SX

#: ``CX`` with qubit 0 as control and qubit 1 as target (qubit 0 = least significant bit)
CX: Matrix = np.eye(4)[[0, 3, 2, 1]]
#: ``CZ``: ``-1`` on ``|11>``, symmetric in its two qubits
CZ: Matrix = np.diag([1.0, 1.0, 1.0, -1.0])
