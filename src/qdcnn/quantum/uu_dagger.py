"""The UU-dagger fidelity test (paper Alg. 1, Eqs. 5-9; NOTES 2).

A value ``v`` in ``[0, scale]`` is encoded as the angle ``theta = pi v / scale``.
The circuit ``RY(-theta_x) RY(theta_c) |0>`` gives ``P(0) = cos^2((theta_c - theta_x)/2)``,
the fidelity ``|<T|C>|^2`` between the centroid state and the test state. qdcnn
uses ``P(0)`` itself as the score (the paper's Alg. 1 speaks of "the square of the
probability"; NOTES 2 takes the fidelity) and calls a value a member of the
centroid's class when the score is at or above a threshold.

With a fixed centroid the test is a band threshold on the value:
``score >= t  <=>  |theta_x - theta_c| <= 2 arccos(sqrt(t))`` (see :func:`band_halfwidth`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from qdcnn.errors import ParameterError
from qdcnn.quantum.circuits import uu_dagger_circuit
from qdcnn.quantum.execute import run_probabilities
from qdcnn.quantum.noise import NoiseSpec

VALUE_SCALE = 255.0


def value_to_angle(values: ArrayLike, scale: float = VALUE_SCALE) -> NDArray[np.float64]:
    """Map values in ``[0, scale]`` to angles ``pi v / scale`` in ``[0, pi]``."""
    return np.asarray(values, dtype=np.float64) * (np.pi / scale)


def angle_to_value(theta: ArrayLike, scale: float = VALUE_SCALE) -> NDArray[np.float64]:
    """Inverse of :func:`value_to_angle`."""
    return np.asarray(theta, dtype=np.float64) * (scale / np.pi)


def fidelity(
    theta_c: ArrayLike,
    theta_x: ArrayLike,
    *,
    shots: int | None = 1024,
    backend: str = "numpy",
    noise: NoiseSpec | None = None,
    rng: int | np.random.Generator | None = None,
) -> NDArray[np.float64]:
    """UU-dagger score ``P(0)`` for each pair of centroid and test angles.

    Parameters
    ----------
    theta_c, theta_x : array_like
        Centroid and test angles (scalars or 1-D arrays of one batch size).
    shots : int or None
        Shots per circuit (paper: 1024); ``None`` for the exact probability.
    backend : {"numpy", "aer"}
        Batched NumPy simulation or Qiskit Aer.
    noise : NoiseSpec or None
        Gate noise after each of the two gates, and readout error.
    rng : int, Generator or None
        Seed or generator for shot sampling.

    Returns
    -------
    ndarray of float64, shape (B,)
        Exact or shot-estimated ``P(0)``.
    """
    circuit = uu_dagger_circuit(theta_c, theta_x)
    return run_probabilities(circuit, shots=shots, noise=noise, backend=backend, rng=rng)[:, 0]


def overlap_fidelity(
    theta_c: float, cos_half_x: NDArray[np.float64], sin_half_x: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Exact noise-free ``P(0)`` of the UU-dagger circuit from the test states' amplitudes.

    ``RY(theta)|0> = (cos theta/2, sin theta/2)`` is real, so the amplitude of ``|0>``
    after ``RY(-theta_x) RY(theta_c)`` is the overlap
    ``<x|c> = cos(theta_x/2) cos(theta_c/2) + sin(theta_x/2) sin(theta_c/2)``, and
    ``P(0) = <x|c>**2``: the statevector result of :func:`fidelity` with ``shots=None``.
    With the amplitudes looked up in an :func:`ry_state_table`, a batch costs two
    products instead of one cosine per circuit (the block-wise shadow detector).

    Parameters
    ----------
    theta_c : float
        Centroid angle.
    cos_half_x, sin_half_x : ndarray
        ``cos(theta_x / 2)`` and ``sin(theta_x / 2)`` of each test angle.

    Returns
    -------
    ndarray of float64, same shape as the amplitudes
    """
    amp = cos_half_x * np.cos(theta_c / 2.0)
    amp += sin_half_x * np.sin(theta_c / 2.0)
    amp *= amp
    return amp


def ry_state_table(
    denominator: int, scale: float = VALUE_SCALE
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Amplitudes of ``RY(theta)|0>`` for every value ``k / denominator`` in ``[0, scale]``.

    Entry ``k`` holds ``cos(theta/2)`` and ``sin(theta/2)`` for
    ``theta = value_to_angle(k / denominator, scale)``, ``k = 0 .. scale * denominator``
    (``scale`` a whole number). The block mean of ``n`` integer pixels is such a value
    with ``denominator = n``, so its encoded state is a table look-up by the block sum.
    """
    if denominator < 1 or not float(scale).is_integer() or scale < 1:
        raise ParameterError("denominator/scale", (denominator, scale), "positive integers")
    half = value_to_angle(np.arange(int(scale) * denominator + 1) / denominator, scale) / 2.0
    return np.cos(half), np.sin(half)


def band_halfwidth(threshold: float) -> float:
    """Half-width in radians of the band of angles whose exact score is ``>= threshold``.

    Examples
    --------
    >>> round(band_halfwidth(0.75), 6) == round(np.pi / 3, 6)
    True
    """
    if not 0.0 <= threshold <= 1.0:
        raise ParameterError("threshold", threshold, "a number in [0, 1]")
    return float(2.0 * np.arccos(np.sqrt(threshold)))


def classify(
    values: ArrayLike,
    centroid: float,
    threshold: float,
    *,
    scale: float = VALUE_SCALE,
    shots: int | None = 1024,
    backend: str = "numpy",
    noise: NoiseSpec | None = None,
    rng: int | np.random.Generator | None = None,
) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
    """Members of the centroid's class: score ``>= threshold``; returns ``(members, scores)``.

    ``values`` and ``centroid`` are in value units ``[0, scale]``.
    """
    scores = fidelity(
        value_to_angle(centroid, scale),
        value_to_angle(np.ravel(values), scale),
        shots=shots,
        backend=backend,
        noise=noise,
        rng=rng,
    )
    shape = np.shape(values)
    return (scores >= threshold).reshape(shape), scores.reshape(shape)
