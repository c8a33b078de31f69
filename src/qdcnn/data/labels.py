"""Direction classes and labels from recorded steering.

Class indices are fixed across qdcnn: 0 = left, 1 = straight, 2 = right.
Steering follows Udacity's convention: in [-1, 1], negative is left.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from qdcnn.config import LabelConfig
from qdcnn.errors import InputError, ParameterError

DIRECTIONS: tuple[str, str, str] = ("left", "straight", "right")
LEFT, STRAIGHT, RIGHT = 0, 1, 2

_DEFAULTS = LabelConfig()


def _check_settings(window: int, max_gap_s: float, threshold: float | None = None) -> None:
    if isinstance(window, bool) or not isinstance(window, int | np.integer) or window < 0:
        raise ParameterError("window", window, "an integer >= 0 (frames on each side)")
    if not isinstance(max_gap_s, int | float) or math.isnan(max_gap_s) or max_gap_s <= 0:
        raise ParameterError("max_gap_s", max_gap_s, "a number of seconds > 0")
    if threshold is not None and not (isinstance(threshold, int | float) and 0 <= threshold < 1):
        raise ParameterError("threshold", threshold, "a number in [0, 1)")


def _as_series(
    steering: ArrayLike, timestamps: ArrayLike | None
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    x = np.asarray(steering, dtype=np.float64)
    if x.ndim != 1:
        raise ParameterError("steering", f"<array of shape {x.shape}>", "a 1-D array")
    if not np.all(np.isfinite(x)):
        bad = int(np.count_nonzero(~np.isfinite(x)))
        raise ParameterError("steering", f"<{bad} non-finite values>", "finite numbers")
    if timestamps is None:
        return x, None
    t = np.asarray(timestamps, dtype=np.float64)
    if t.shape != x.shape:
        raise ParameterError(
            "timestamps", f"<array of shape {t.shape}>", f"one per steering value {x.shape}"
        )
    if not np.all(np.isfinite(t)):
        raise ParameterError("timestamps", "<non-finite values>", "finite seconds")
    return x, t


def smooth_steering(
    steering: ArrayLike,
    timestamps: ArrayLike | None = None,
    *,
    window: int = _DEFAULTS.window,
    max_gap_s: float = _DEFAULTS.max_gap_s,
) -> NDArray[np.float64]:
    """Centred moving mean of steering that never mixes frames across a recording break.

    Keyboard-driven recordings (Udacity) are spiky: mid-bend frames often read 0.
    Averaging each frame with its neighbours gives the direction the car is taking.

    Parameters
    ----------
    steering : array_like, shape (N,)
        Steering per frame.
    timestamps : array_like, shape (N,), optional
        Seconds per frame. The series is split into segments wherever the time
        step exceeds ``max_gap_s`` or goes backwards; without timestamps it is
        one segment.
    window : int
        Frames on each side: the mean is over up to ``2 * window + 1`` frames,
        only the available ones at segment edges. 0 returns the input.
    max_gap_s : float
        Largest time step, in seconds, inside one segment.

    Returns
    -------
    ndarray of float64, shape (N,)
        The smoothed steering.

    Examples
    --------
    >>> smooth_steering([0.0, 0.0, 0.9, 0.0, 0.0], window=1).round(2).tolist()
    [0.0, 0.3, 0.3, 0.3, 0.0]
    >>> smooth_steering([1.0, 1.0, -1.0, -1.0], [0.0, 0.1, 5.0, 5.1], window=1).tolist()
    [1.0, 1.0, -1.0, -1.0]
    """
    _check_settings(window, max_gap_s)
    x, t = _as_series(steering, timestamps)
    n = x.size
    if n == 0 or window == 0:
        return x.copy()
    idx = np.arange(n)
    if t is None:
        start = np.zeros(n, dtype=np.int64)
        stop = np.full(n, n, dtype=np.int64)
    else:
        step = np.diff(t)
        breaks = np.flatnonzero((step > max_gap_s) | (step < 0)) + 1  # first index of a segment
        bounds = np.concatenate(([0], breaks, [n]))
        seg = np.searchsorted(breaks, idx, side="right")
        start, stop = bounds[seg], bounds[seg + 1]
    lo = np.maximum(idx - window, start)
    hi = np.minimum(idx + window + 1, stop)
    # Segments are contiguous, so one cumulative sum serves all of them.
    csum = np.concatenate(([0.0], np.cumsum(x)))
    return (csum[hi] - csum[lo]) / (hi - lo)


def direction_labels(
    steering: ArrayLike,
    timestamps: ArrayLike | None = None,
    *,
    window: int = _DEFAULTS.window,
    max_gap_s: float = _DEFAULTS.max_gap_s,
    threshold: float = _DEFAULTS.threshold,
) -> NDArray[np.int64]:
    """Direction class per frame from steering: LEFT (0), STRAIGHT (1) or RIGHT (2).

    The steering is smoothed with :func:`smooth_steering`; a smoothed value below
    ``-threshold`` is left, above ``threshold`` right, anything else straight.

    Examples
    --------
    >>> direction_labels([-0.5, 0.0, 0.5], window=0).tolist()
    [0, 1, 2]
    """
    _check_settings(window, max_gap_s, threshold)
    smooth = smooth_steering(steering, timestamps, window=window, max_gap_s=max_gap_s)
    labels = np.full(smooth.shape, STRAIGHT, dtype=np.int64)
    labels[smooth < -threshold] = LEFT
    labels[smooth > threshold] = RIGHT
    return labels


def _as_labels(labels: ArrayLike | Sequence[int]) -> NDArray[np.int64]:
    arr = np.asarray(labels)
    if arr.size and (
        not np.issubdtype(arr.dtype, np.integer) or arr.min() < 0 or arr.max() >= len(DIRECTIONS)
    ):
        raise ParameterError("labels", f"<{arr.dtype} array>", "class indices 0, 1 or 2")
    return arr.astype(np.int64).ravel()


def class_balance(labels: ArrayLike) -> dict[str, int]:
    """Count the labels of each direction; every name in ``DIRECTIONS`` is present.

    Examples
    --------
    >>> class_balance([0, 1, 1])
    {'left': 1, 'straight': 2, 'right': 0}
    """
    counts = np.bincount(_as_labels(labels), minlength=len(DIRECTIONS))
    return {name: int(c) for name, c in zip(DIRECTIONS, counts, strict=True)}


def check_labels_usable(labels: ArrayLike, *, source: str) -> None:
    """Raise :class:`InputError` when labels hold fewer than two classes.

    With a single class a constant guess scores 1.0, so accuracy says nothing.

    Parameters
    ----------
    labels : array_like of int
        Direction classes.
    source : str
        What the labels came from (a recording path), used in the message.
    """
    counts = class_balance(labels)
    n = sum(counts.values())
    present = [name for name, c in counts.items() if c]
    if n == 0:
        raise InputError(source, "no labels: there is nothing to evaluate")
    if len(present) < 2:
        raise InputError(
            source,
            f"all {n} labels are {present[0]!r}: accuracy would be meaningless "
            "(a constant guess scores 1.0); use a recording with turns or a smaller threshold",
        )
