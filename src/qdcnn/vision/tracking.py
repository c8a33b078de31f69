"""Temporal tracking of the two fitted lane lines across a recording's frames (not the paper's).

The paper decides every frame alone (Alg. 2). In a recording the lane lines move little
from one frame to the next, so a line lost in one frame (a car in front of it, a worn
marking, glare) can be carried from the last frames, and a fit thrown off by clutter can be
recognised as a jump. :class:`LaneTracker` keeps, per side, the line's x at two rows
(:data:`_TRACK_ROWS` of the height) and updates them with each frame's fit:

``"ema"``
    An exponential moving average, ``state += alpha * (measured - state)``.
``"kalman"``
    A constant-velocity Kalman filter per side on the two x values (state: positions and
    velocities; process noise a random acceleration of ``0.3 %`` of the width per frame,
    measurement noise ``2 %`` of the width).

A measurement more than :data:`GATE` of the width from the track at either row (``ema``)
or outside the 99.9 % ellipse of the predicted measurement (``kalman``) is rejected as an
outlier. A missing or rejected line keeps its track for up to ``track_hold`` frames; after
that a missing line is dropped and a line rejected that often starts a new track. The
output :class:`~qdcnn.vision.grouping.LaneFeatures` has the tracked lines, the status they
give ("ok" when both sides are tracked) and the features recomputed from them.

References
----------
.. [1] R. E. Kalman, "A new approach to linear filtering and prediction problems",
   J. Basic Eng. 82(1), 1960.
.. [2] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, "Estimation with Applications to Tracking
   and Navigation", Wiley 2001, Sec. 6.3 (white-noise acceleration model).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from qdcnn.config import GroupingConfig
from qdcnn.vision.grouping import LaneFeatures, check_rows, feature_values, pair_status

#: rows (relative to the height) at which a line's x is tracked
_TRACK_ROWS = (0.5, 0.95)
#: an "ema" measurement this far (fraction of the width) from the track is an outlier
GATE = 0.15
#: "kalman": random acceleration and measurement noise, as fractions of the width
_KALMAN_Q, _KALMAN_R = 0.003, 0.02
#: "kalman": squared Mahalanobis distance beyond which a measurement is rejected (chi2, 2 dof)
_KALMAN_GATE = 13.8

_Line = tuple[float, float]


@dataclass
class _SideTrack:
    """The track of one side: x at the two rows (and for Kalman velocities, covariance)."""

    state: NDArray[np.float64] | None = None
    cov: NDArray[np.float64] | None = None
    missed: int = 0
    rejected: int = 0
    pending: list[NDArray[np.float64]] = field(default_factory=list)


class LaneTracker:
    """Tracks the left and right lines of consecutive frames (module docstring).

    Parameters
    ----------
    config : GroupingConfig
        ``track`` ("ema" or "kalman"; "none" passes frames through), ``track_alpha``,
        ``track_hold`` and ``extra_features`` (recomputed from the tracked lines).

    Examples
    --------
    >>> from qdcnn.vision.grouping import group_segments
    >>> tracker = LaneTracker(GroupingConfig(track="ema", track_alpha=0.5))
    >>> seg = np.array([[100.0, 60, 40, 150], [220, 60, 280, 150]])
    >>> first = tracker.update(group_segments(seg, (160, 320)))
    >>> lost = tracker.update(group_segments(seg[:1], (160, 320)))  # right line missing
    >>> lost.status, bool(np.allclose(lost.features, first.features))
    ('ok', True)
    """

    def __init__(self, config: GroupingConfig) -> None:
        self.config = config
        self._shape: tuple[int, int] | None = None
        self._sides = [_SideTrack(), _SideTrack()]

    def reset(self) -> None:
        """Forget both tracks (a new recording, or frames of another size)."""
        self._shape = None
        self._sides = [_SideTrack(), _SideTrack()]

    def update(self, lanes: LaneFeatures) -> LaneFeatures:
        """Fold one frame's fitted lines into the tracks; return the tracked result."""
        if self.config.track == "none":
            return lanes
        if self._shape != lanes.shape:
            self.reset()
            self._shape = lanes.shape
        h, w = lanes.shape
        rows = (_TRACK_ROWS[0] * (h - 1), _TRACK_ROWS[1] * (h - 1))
        lines: list[_Line | None] = []
        for side, line in zip(self._sides, lanes.lines, strict=True):
            measured = None if line is None else _to_points(line, rows)
            state = self._step(side, measured, w)
            lines.append(None if state is None else _to_line(state, rows))
        return _with_lines(lanes, lines, self.config)

    def _step(
        self, side: _SideTrack, measured: NDArray[np.float64] | None, w: int
    ) -> NDArray[np.float64] | None:
        hold = self.config.track_hold
        if self.config.track == "kalman":
            return _kalman_step(side, measured, w, hold)
        if side.state is None:
            side.state = measured
            side.missed = 0
            return side.state
        if measured is not None and np.max(np.abs(measured - side.state)) <= GATE * w:
            side.state = side.state + self.config.track_alpha * (measured - side.state)
            side.missed = side.rejected = 0
            return side.state
        if measured is not None:
            side.rejected += 1
            if side.rejected > hold:  # the line really moved: start again from it
                side.state, side.missed, side.rejected = measured, 0, 0
                return side.state
        side.missed += 1
        if side.missed > hold:
            side.state = None
            side.missed = side.rejected = 0
        return side.state


def _kalman_step(
    side: _SideTrack, measured: NDArray[np.float64] | None, w: int, hold: int
) -> NDArray[np.float64] | None:
    eye = np.eye(2)
    transition = np.block([[eye, eye], [np.zeros((2, 2)), eye]])
    observe = np.hstack([eye, np.zeros((2, 2))])
    q, r = (_KALMAN_Q * w) ** 2, (_KALMAN_R * w) ** 2
    noise = q * np.block([[0.25 * eye, 0.5 * eye], [0.5 * eye, eye]])
    if side.state is None or side.cov is None:
        if measured is None:
            return None
        side.state = np.concatenate([measured, np.zeros(2)])
        side.cov = np.diag([r, r, 10 * q, 10 * q])
        side.missed = side.rejected = 0
        return np.asarray(side.state[:2])
    x = transition @ side.state
    p = transition @ side.cov @ transition.T + noise
    if measured is not None:
        innovation = measured - observe @ x
        s = observe @ p @ observe.T + r * eye
        if float(innovation @ np.linalg.solve(s, innovation)) <= _KALMAN_GATE:
            gain = p @ observe.T @ np.linalg.inv(s)
            side.state = x + gain @ innovation
            side.cov = (np.eye(4) - gain @ observe) @ p
            side.missed = side.rejected = 0
            return np.asarray(side.state[:2])
        side.rejected += 1
        if side.rejected > hold:
            side.state, side.cov = None, None
            return _kalman_step(side, measured, w, hold)
    side.state, side.cov = x, p
    side.missed += 1
    if side.missed > hold:
        side.state, side.cov = None, None
        side.missed = side.rejected = 0
        return None
    return np.asarray(x[:2])


def _to_points(line: _Line, rows: tuple[float, float]) -> NDArray[np.float64]:
    a, b = line
    return np.array([a * rows[0] + b, a * rows[1] + b])


def _to_line(points: NDArray[np.float64], rows: tuple[float, float]) -> _Line:
    a = float(points[1] - points[0]) / (rows[1] - rows[0])
    return a, float(points[0]) - a * rows[0]


def _with_lines(
    lanes: LaneFeatures, lines: list[_Line | None], config: GroupingConfig
) -> LaneFeatures:
    """``lanes`` with tracked lines: status, middle line and features recomputed."""
    h, w = lanes.shape
    status = pair_status(lines, check_rows(lanes.roi_rows, lanes.segments, h))
    left, right = lines
    middle = None
    if left is not None and right is not None:
        middle = (0.5 * (left[0] + right[0]), 0.5 * (left[1] + right[1]))
    values = feature_values(lines, config.extra_features, h, w, lanes.segments, lanes.labels)
    return replace(lanes, features=values, status=status, lines=lines, middle_line=middle)
