"""Direction classes and labels from recorded steering, in the unit it was recorded in.

Class indices are fixed across qdcnn: 0 = left, 1 = straight, 2 = right.
Negative steering is left in every unit.

Steering units
--------------
``norm``
    A normalised steering command in [-1, 1] (Udacity's simulator, CARLA's ``steer``).
    The Udacity simulator maps +-1 to its largest road-wheel angle, 25 degrees.
``rad``, ``deg``
    The steering-WHEEL angle of a real car in radians or degrees, as its CAN bus
    reports it (Udacity's real-car challenge data, comma.ai logs): up to about
    +-1.5 turns (+-3 pi rad, +-540 deg) at full lock.

The default label thresholds of the three units mean the same road-wheel angle:
0.05 of the simulator's 25 degrees is 1.25 degrees at the road wheels, which a
typical passenger-car steering ratio of 15:1 turns into 18.75 degrees (0.327 rad)
at the steering wheel (:data:`DEFAULT_THRESHOLDS`). Pass a threshold to override.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

# The class names and indices live in qdcnn.classes; re-exported here for callers.
from qdcnn._validation import check_shape
from qdcnn.classes import DIRECTIONS, LEFT, RIGHT, STRAIGHT
from qdcnn.config import LabelConfig
from qdcnn.errors import InputError, ParameterError

_DEFAULTS = LabelConfig()

#: Units a recording's steering can be in; ``"auto"`` asks :func:`infer_steering_unit`.
_STEERING_UNITS: tuple[str, ...] = ("auto", "norm", "rad", "deg")
#: Largest road-wheel angle of the Udacity simulator, reached at steering +-1.
_SIMULATOR_MAX_ROAD_WHEEL_DEG = 25.0
#: Steering-wheel turn per road-wheel turn of a typical passenger car.
_STEERING_RATIO = 15.0
#: The simulator's label threshold on steering in [-1, 1] (1.25 degrees of road wheel).
_NORM_THRESHOLD = 0.05
_WHEEL_DEG = _NORM_THRESHOLD * _SIMULATOR_MAX_ROAD_WHEEL_DEG * _STEERING_RATIO  # 18.75
#: Default label threshold per unit: the same 1.25 degree road-wheel angle in each.
DEFAULT_THRESHOLDS: dict[str, float] = {
    "norm": _NORM_THRESHOLD,
    "rad": math.radians(_WHEEL_DEG),
    "deg": _WHEEL_DEG,
}
#: Largest |steering| a unit can hold: a full command; +-2.5 steering-wheel turns (any car).
_UNIT_LIMITS: dict[str, float] = {"norm": 1.0, "rad": 5 * math.pi, "deg": 900.0}
#: ``auto`` reads values beyond +-1.5 turns (+-3 pi: full lock of a typical car) as degrees.
AUTO_RAD_MAX = 3 * math.pi
#: Steering-wheel angle sensors report multiples of 0.1 degree (written in radians here).
_WHEEL_SENSOR_STEP_RAD = math.radians(0.1)
_UNIT_NAMES = {
    "norm": "normalised steering in [-1, 1]",
    "rad": "steering-wheel angle in radians",
    "deg": "steering-wheel angle in degrees",
}


def _check_settings(
    window: int, max_gap_s: float, threshold: float | None = None, unit: str = "norm"
) -> None:
    if isinstance(window, bool) or not isinstance(window, int | np.integer) or window < 0:
        raise ParameterError("window", window, "an integer >= 0 (frames on each side)")
    if not isinstance(max_gap_s, int | float) or math.isnan(max_gap_s) or max_gap_s <= 0:
        raise ParameterError("max_gap_s", max_gap_s, "a number of seconds > 0")
    if unit not in _UNIT_LIMITS:
        raise ParameterError("unit", unit, "one of " + ", ".join(map(repr, _UNIT_LIMITS)))
    limit = _UNIT_LIMITS[unit]
    if threshold is not None and not (
        isinstance(threshold, int | float)
        and not isinstance(threshold, bool)
        and 0 <= threshold < limit
    ):
        where = "[0, 1)" if unit == "norm" else f"[0, {limit:g}) {unit}"
        raise ParameterError("threshold", threshold, f"a number in {where}")


@dataclass(frozen=True)
class SteeringUnit:
    """The unit of a recording's steering and how it was decided.

    Attributes
    ----------
    unit : str
        ``"norm"``, ``"rad"`` or ``"deg"``.
    requested : str
        What was asked for: ``"auto"`` or the unit itself.
    reason : str
        Why this unit, for people (the evidence ``auto`` used, or ``"given"``).
    assumed : bool
        ``auto`` found no evidence either way and fell back to ``norm``; callers
        should print ``reason`` as a note so the user can pass the unit.
    """

    unit: str = "norm"
    requested: str = "norm"
    reason: str = "given"
    assumed: bool = False

    @property
    def limit(self) -> float:
        """Largest |steering| this unit can hold (:data:`_UNIT_LIMITS`)."""
        return _UNIT_LIMITS[self.unit]

    @property
    def default_threshold(self) -> float:
        """The label threshold of this unit (:data:`DEFAULT_THRESHOLDS`)."""
        return DEFAULT_THRESHOLDS[self.unit]

    def describe(self) -> str:
        """One line: the unit and why, e.g. ``rad (steering-wheel angle in radians): ...``."""
        return f"{self.unit} ({_UNIT_NAMES[self.unit]}): {self.reason}"


@dataclass(frozen=True)
class Quantile:
    """A label threshold taken from the data: the ``percent``-th percentile of
    ``|smoothed steering|`` over the TRAINING frames (written ``pNN``, e.g. ``p33``).

    It is resolved in a unit-free scale (:func:`unit_free_steering`), so recordings in
    different units pool, then converted into each recording's own unit.

    Examples
    --------
    >>> Quantile.parse("p33"), str(Quantile(12.5))
    (Quantile(percent=33.0), 'p12.5')
    >>> Quantile.parse("0.2") is None
    True
    """

    percent: float

    def __post_init__(self) -> None:
        if not _QUANTILE_LOW <= self.percent <= _QUANTILE_HIGH:
            raise ParameterError("threshold", str(self), _QUANTILE_RANGE)

    def __str__(self) -> str:
        return f"p{self.percent:g}"

    @classmethod
    def parse(cls, text: str) -> Quantile | None:
        """``pNN`` as a :class:`Quantile`, ``None`` for text without the ``p``.

        Raises :class:`ParameterError` for ``p`` followed by no number or one outside 1..99.
        """
        if not text.startswith("p"):
            return None
        try:
            percent = float(text[1:])
        except ValueError:
            raise ParameterError("threshold", text, _QUANTILE_RANGE) from None
        if not math.isfinite(percent) or not _QUANTILE_LOW <= percent <= _QUANTILE_HIGH:
            raise ParameterError("threshold", text, _QUANTILE_RANGE)
        return cls(percent)


_QUANTILE_LOW, _QUANTILE_HIGH = 1.0, 99.0
_QUANTILE_RANGE = "pNN with NN a percentile in 1..99"


def unit_free_steering(
    steering: ArrayLike,
    timestamps: ArrayLike | None,
    unit: SteeringUnit,
    *,
    window: int = _DEFAULTS.window,
    max_gap_s: float = _DEFAULTS.max_gap_s,
) -> NDArray[np.float64]:
    """``|smoothed steering|`` in multiples of the unit's default threshold.

    1.0 is the same road-wheel angle (1.25 degrees) in every unit
    (:data:`DEFAULT_THRESHOLDS`), so values of recordings in different units compare
    and pool. A threshold ``t`` on this scale is ``t * unit.default_threshold`` in a
    recording's own unit.

    Examples
    --------
    >>> unit_free_steering([0.1, -0.05], None, SteeringUnit("norm"), window=0).tolist()
    [2.0, 1.0]
    """
    smooth = smooth_steering(steering, timestamps, window=window, max_gap_s=max_gap_s)
    return np.abs(smooth) / unit.default_threshold


def unit_disagreement(name: str, unit: SteeringUnit, skipped_beyond: int, total: int) -> str | None:
    """A note when a GIVEN unit disagrees with the values, else ``None``.

    ``skipped_beyond`` rows of ``total`` had ``|steering|`` beyond the unit's limit
    (``unit.limit``: 1 for ``norm``) and were skipped by the loader; with an ``auto``
    unit the inference already weighed them, so there is no note.
    """
    if unit.requested == "auto" or skipped_beyond == 0:
        return None
    return (
        f"{name}: {skipped_beyond} of {total} rows have |steering| beyond the {unit.unit} "
        f"limit {unit.limit:g} and were skipped; is unit={unit.unit} right for this recording?"
    )


def check_steering_unit(value: object) -> str:
    """``value`` if it is one of :data:`_STEERING_UNITS`, else :class:`ParameterError`."""
    if not isinstance(value, str) or value not in _STEERING_UNITS:
        raise ParameterError("steering_unit", value, "one of " + ", ".join(_STEERING_UNITS))
    return value


def resolve_steering_unit(
    requested: str, steering: ArrayLike, *, simulator_names: bool = False
) -> SteeringUnit:
    """The unit to use: ``requested`` itself, or :func:`infer_steering_unit` for ``"auto"``."""
    check_steering_unit(requested)
    if requested == "auto":
        return infer_steering_unit(steering, simulator_names=simulator_names)
    return SteeringUnit(requested, requested, "given", False)


def infer_steering_unit(steering: ArrayLike, *, simulator_names: bool = False) -> SteeringUnit:
    """Decide the unit of recorded steering from the evidence in the data (conservative).

    The rules, in order (the first that applies decides):

    1. ``simulator_names`` (the frames have Udacity simulator names,
       ``center_YYYY_MM_DD_HH_MM_SS_mmm.jpg``): ``norm``; the simulator writes
       nothing else.
    2. At least ``max(3, 1 %)`` of the values beyond +-1: an angle, since a
       normalised command cannot be there; ``deg`` if as many are beyond
       :data:`AUTO_RAD_MAX` (+-1.5 wheel turns), else ``rad``. Fewer such values are
       treated as bad rows of a ``norm`` recording, never as evidence.
    3. At least 10 non-zero values and 20 % of them whole multiples of 0.1 degree
       written in radians (:data:`_WHEEL_SENSOR_STEP_RAD`, the resolution of
       steering-wheel angle sensors): ``rad``. A normalised command lands on such a
       multiple with probability about 1e-5 per value.
    4. A value at exactly +-1 (a normalised command saturating): ``norm``.
    5. Otherwise ``norm`` with ``assumed=True``: the data do not say, and the caller
       prints a note so the user can pass ``rad`` or ``deg``.

    A steering-wheel angle in degrees that stays within +-1 degree, or in radians
    without sensor quantisation and within +-1 rad, cannot be told from ``norm``:
    rule 5 then assumes ``norm``.

    Parameters
    ----------
    steering : array_like, shape (N,)
        The recorded values (non-finite ones are ignored).
    simulator_names : bool
        Whether the frames carry Udacity simulator file names.

    Examples
    --------
    >>> infer_steering_unit([0.0, -0.25, 1.0]).reason
    'values reach exactly +-1 (a normalised command saturating)'
    >>> infer_steering_unit([2.5, -4.0, 3.1, 0.2]).unit
    'rad'
    >>> infer_steering_unit([12.0, -30.0, 45.5, 0.5]).unit
    'deg'
    """
    x = np.asarray(steering, dtype=np.float64).ravel()
    x = np.abs(x[np.isfinite(x)])
    if simulator_names:
        return SteeringUnit("norm", "auto", "Udacity simulator image names (center_YYYY_...)")
    needed = max(3, math.ceil(0.01 * x.size))
    beyond_one = int(np.count_nonzero(x > 1.0))
    if beyond_one >= needed:
        beyond_rad = int(np.count_nonzero(x > AUTO_RAD_MAX))
        if beyond_rad >= needed:
            return SteeringUnit(
                "deg", "auto", f"{beyond_rad} values beyond +-{AUTO_RAD_MAX:.2f} (1.5 wheel turns)"
            )
        return SteeringUnit("rad", "auto", f"{beyond_one} values beyond +-1, up to {x.max():g}")
    nonzero = x[(x > 0) & (x <= 1.0)]  # the few values beyond 1 here are bad rows
    steps = nonzero / _WHEEL_SENSOR_STEP_RAD
    on_step = int(np.count_nonzero(np.abs(steps - np.round(steps)) < 1e-6))
    if nonzero.size >= 10 and on_step >= 0.2 * nonzero.size:
        return SteeringUnit(
            "rad",
            "auto",
            f"{on_step} of {nonzero.size} non-zero values are whole multiples of 0.1 degree "
            "in radians (a steering-wheel angle sensor)",
        )
    if np.any(x == 1.0):
        return SteeringUnit(
            "norm", "auto", "values reach exactly +-1 (a normalised command saturating)"
        )
    return SteeringUnit(
        "norm",
        "auto",
        "assumed normalised [-1, 1]: the values do not show their unit; "
        "pass steering unit rad or deg if they are steering-wheel angles",
        assumed=True,
    )


def _as_series(
    steering: ArrayLike, timestamps: ArrayLike | None
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    x = np.asarray(steering, dtype=np.float64)
    check_shape("steering", x, "N", "a 1-D array")
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
    threshold: float | None = None,
    unit: str = "norm",
) -> NDArray[np.int64]:
    """Direction class per frame from steering: LEFT (0), STRAIGHT (1) or RIGHT (2).

    The steering is smoothed with :func:`smooth_steering`; a smoothed value below
    ``-threshold`` is left, above ``threshold`` right, anything else straight.
    ``threshold`` is in ``unit`` (``"norm"``, ``"rad"`` or ``"deg"``); ``None`` is
    the unit's default (:data:`DEFAULT_THRESHOLDS`, 0.05 for ``norm``).

    Examples
    --------
    >>> direction_labels([-0.5, 0.0, 0.5], window=0).tolist()
    [0, 1, 2]
    >>> direction_labels([-0.5, 0.0, 0.5], window=0, unit="rad").tolist()  # 0.327 rad
    [0, 1, 2]
    """
    _check_settings(window, max_gap_s, threshold, unit)
    limit = DEFAULT_THRESHOLDS[unit] if threshold is None else float(threshold)
    smooth = smooth_steering(steering, timestamps, window=window, max_gap_s=max_gap_s)
    labels = np.full(smooth.shape, STRAIGHT, dtype=np.int64)
    labels[smooth < -limit] = LEFT
    labels[smooth > limit] = RIGHT
    return labels


@dataclass(frozen=True)
class DirectionLabels:
    """Direction labels with the settings that produced them.

    Attributes
    ----------
    labels : ndarray of int64, shape (N,)
        LEFT (0), STRAIGHT (1) or RIGHT (2) per frame.
    unit : SteeringUnit
        The steering unit (and how it was decided).
    threshold : float
        The threshold used, in ``unit.unit``.
    threshold_source : str
        ``"default"`` (the unit's :data:`DEFAULT_THRESHOLDS`) or ``"given"``.
    window, max_gap_s : int, float
        The smoothing settings.
    """

    labels: NDArray[np.int64]
    unit: SteeringUnit
    threshold: float
    threshold_source: str
    window: int
    max_gap_s: float

    def counts(self) -> dict[str, int]:
        """:func:`class_balance` of the labels."""
        return class_balance(self.labels)

    def describe(self) -> str:
        """One line for people, e.g. ``labels: steering in rad, threshold 0.327 rad (default)``."""
        unit = self.unit.unit
        shown = f"{self.threshold:g}" if unit == "norm" else f"{self.threshold:.4g} {unit}"
        return (
            f"labels: steering in {unit} ({self.unit.reason}), threshold {shown} "
            f"({self.threshold_source}), smoothed over +-{self.window} frames"
        )

    def to_dict(self) -> dict[str, object]:
        """Plain values for JSON output."""
        return {
            "steering_unit": self.unit.unit,
            "steering_unit_reason": self.unit.reason,
            "steering_unit_assumed": self.unit.assumed,
            "label_threshold": self.threshold,
            "label_threshold_source": self.threshold_source,
            "label_window": self.window,
            "label_max_gap_s": self.max_gap_s,
        }


def label_directions(
    steering: ArrayLike,
    timestamps: ArrayLike | None = None,
    *,
    unit: str | SteeringUnit = "norm",
    threshold: float | None = None,
    window: int = _DEFAULTS.window,
    max_gap_s: float = _DEFAULTS.max_gap_s,
) -> DirectionLabels:
    """:func:`direction_labels` that also says which unit and threshold produced them.

    Parameters
    ----------
    steering, timestamps : array_like
        As for :func:`smooth_steering`.
    unit : str or SteeringUnit
        ``"norm"``, ``"rad"``, ``"deg"``, ``"auto"`` (:func:`infer_steering_unit` on
        the values alone) or a decided :class:`SteeringUnit` (``Recording.unit``).
    threshold : float, optional
        In the unit; ``None`` takes the unit's default (:data:`DEFAULT_THRESHOLDS`).
    window, max_gap_s
        Smoothing, as for :func:`smooth_steering`.

    Examples
    --------
    >>> out = label_directions([-0.5, 0.0, 0.5], unit="deg", window=0)
    >>> out.labels.tolist(), out.threshold
    ([1, 1, 1], 18.75)
    """
    decided = unit if isinstance(unit, SteeringUnit) else resolve_steering_unit(unit, steering)
    labels = direction_labels(
        steering,
        timestamps,
        window=window,
        max_gap_s=max_gap_s,
        threshold=threshold,
        unit=decided.unit,
    )
    used = decided.default_threshold if threshold is None else float(threshold)
    source = "default" if threshold is None else "given"
    return DirectionLabels(labels, decided, used, source, int(window), float(max_gap_s))


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
