"""Batched gate matrices in Qiskit's conventions.

Each function takes an array of angles of any shape ``S`` and returns matrices of
shape ``S + (2, 2)``, so one call builds the gate for a whole batch of circuits.

The definitions follow Qiskit's circuit library: ``RY(t) = exp(-i t Y / 2)``,
``RZ(t) = diag(e^{-i t/2}, e^{i t/2})``, ``P(l) = diag(1, e^{i l})``.
``SX = sqrt(X)`` is the native gate of IBM devices (see :mod:`qdcnn.quantum.device`).
Real gates (RY, H, X, Z) are returned as ``float64`` so that circuits made only
of them are simulated in real arithmetic; the others are ``complex128``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

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


PARAMETRIC: dict[str, Callable[[ArrayLike], Matrix]] = {
    "ry": ry,
    "rx": rx,
    "rz": rz,
    "p": phase,
}
CONSTANT: dict[str, Matrix] = {"h": H, "x": X, "y": Y, "z": Z}
CONSTANT["sx"] = SX
