"""Camera-aware ROI: horizon, vanishing point and hood of a recording, estimated from its frames.

The paper's ROI is a fixed polygon in the pixels of its own frames (Sec. III-A); drawn for
one camera it keeps the roadside, or cuts out the road, on another. :func:`estimate_camera`
looks at a few frames of a recording (:func:`sample_indices`: up to 40 of its first 600)
and finds:

Vanishing point and horizon
    Per frame: Canny edges of the lightly smoothed grey frame at a 320-pixel working width,
    ``cv2.HoughLinesP`` segments between 15 and 75 degrees from the horizontal, split into
    left borders (``dx/dy < 0``, going down to the left) and right borders (``dx/dy > 0``).
    Every pair of one left and one right segment proposes their lines' intersection; a
    segment supports a proposal when its line passes within 1.5 % of the width of it at
    its row and the segment lies below it. The proposal with the largest geometric mean of
    the left and right support (total segment length) wins, so that one marking seen as
    many parallel segments, which meet anywhere along it, cannot win alone. This is
    RANSAC with every minimal sample tried (deterministic). The point is then refined by
    weighted least squares on its supporting segments: a line ``x = a y + b`` passes
    through ``(x0, y0)`` when ``b = x0 - y0 a``, a linear regression of ``b`` on ``a``
    whose residual is the line's horizontal miss at the point's row. A frame counts when
    each side's support is at least 15 % of the frame height. The horizon is the median
    row of the counted frames' points (a camera without roll: lines on the ground plane
    meet on the horizon), the vanishing point the median point.
Hood
    Per column, the highest of: pixels connected to the bottom edge whose grey level
    changes by less than 2 levels (standard deviation) across the frames, and a
    near-horizontal outline low in the frame that is at the same place in 90 % of the
    frames (a glossy bonnet reflects the scene but keeps its outline); see
    :func:`_detect_hood`.

:func:`camera_roi` builds the ROI from them: a trapezoid whose sides are lines through
points ``curve_margin`` of the width either side of the vanishing point on the horizon,
widening by ``side_slope`` pixels per pixel downwards (2.5: the borders of a 3.5 m lane
seen from 1.5 m up with square pixels have slopes near 1.2), from ``top_gap`` below the
horizon down to the bottom edge, with a notch above the hood. :func:`apply_camera` puts it
(and the vanishing point) into a :class:`qdcnn.config.LaneConfig`.

Nothing here fails on a bad recording: when no horizon can be found (night, a wall, a
covered lens), when the static region covers more than half the frame, or when frames
change size, :class:`CameraGeometry` carries a one-line note per problem and the preset's
ROI (``source == "preset"``), never an empty ROI.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import median_filter

from qdcnn.config import LaneConfig
from qdcnn.errors import InputError, ParameterError
from qdcnn.vision.lanes import to_grey, working_frame
from qdcnn.vision.roi import polygon_mask

#: frames :func:`sample_indices` takes by default, and the span of the recording they cover
_CAMERA_FRAMES, _CAMERA_SPAN = 40, 600
#: working width of the estimate (pixels)
_WORK_WIDTH = 320
#: segments counted as lane borders: degrees from the horizontal
_BORDER_ANGLES = (15.0, 75.0)
#: a segment supports a vanishing point when its line passes this close (fraction of width)
_SUPPORT_TOLERANCE = 0.015
#: each side's support (total segment length) needed, as a fraction of the frame height
_MIN_SUPPORT = 0.15
#: a pixel is static when its grey level's standard deviation across frames is below this
_STATIC_STD = 2.0
#: columns at which the hood's top row is kept (evenly spaced, both edges included)
_HOOD_COLUMNS = 17
#: the ROI stops this far (fraction of the height) above the hood
_HOOD_MARGIN = 0.02
_MAX_BORDERS = 40  # longest segments per side tried as proposals
#: estimated ROI: top edge below the horizon and half-width on it (fractions of H and W)
_ROI_TOP_GAP, _ROI_CURVE_MARGIN = 0.04, 0.15
#: estimated ROI side slope per side: SCALE * (the own lane's border slope) + ADD, clipped
_ROI_SLOPE_SCALE, _ROI_SLOPE_ADD, _ROI_SLOPES = 1.25, 0.3, (1.0, 5.0)


@dataclass(frozen=True)
class CameraGeometry:
    """What :func:`estimate_camera` found for a recording, and the ROI built from it.

    Attributes
    ----------
    shape : (int, int)
        ``(H, W)`` of the frames it was estimated on.
    horizon : float
        Row of the horizon relative to the height (``y / (H - 1)``).
    vanishing_point : (float, float)
        ``(x, y)`` of the vanishing point relative to the frame; ``y == horizon``.
    hood_rows : tuple of float or None
        Top row of the static hood (relative) at :data:`_HOOD_COLUMNS` evenly spaced
        columns, 1.0 where there is none; ``None`` when no hood was found.
    roi : tuple of (x, y)
        The ROI polygon (relative), never empty.
    source : {"estimated", "preset"}
        Whether the horizon came from the frames or, failing that, from the preset.
    frames_used : int
        Frames whose vanishing point counted.
    frames_seen : int
        Frames looked at.
    horizon_spread : float
        Median absolute deviation of the counted frames' horizon rows (relative); NaN
        when none counted.
    notes : tuple of str
        One line per problem met (and the fallback taken).
    """

    shape: tuple[int, int]
    horizon: float
    vanishing_point: tuple[float, float]
    hood_rows: tuple[float, ...] | None
    roi: tuple[tuple[float, float], ...]
    source: Literal["estimated", "preset"]
    frames_used: int
    frames_seen: int
    horizon_spread: float = float("nan")
    notes: tuple[str, ...] = ()

    @property
    def hood_top(self) -> float | None:
        """Highest row of the hood (relative), or None without a hood."""
        return None if self.hood_rows is None else float(min(self.hood_rows))

    def describe(self) -> str:
        """One line saying what was chosen, e.g. for ``qdcnn evaluate`` to print."""
        where = (
            f"estimated from {self.frames_used} of {self.frames_seen} frames"
            if self.source == "estimated"
            else "the preset's (not found)"
        )
        hood = "no hood" if self.hood_top is None else f"hood from row {self.hood_top:.0%}"
        h, w = self.shape
        return (
            f"camera {w}x{h}: horizon at {self.horizon:.0%} of the height ({where}), "
            f"vanishing point x {self.vanishing_point[0]:.0%}, {hood}; "
            f"ROI of {len(self.roi)} vertices from row {min(y for _, y in self.roi):.0%}"
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-serialisable values."""
        return {
            "shape": list(self.shape),
            "horizon": self.horizon,
            "vanishing_point": list(self.vanishing_point),
            "hood_rows": None if self.hood_rows is None else list(self.hood_rows),
            "roi": [list(p) for p in self.roi],
            "source": self.source,
            "frames_used": self.frames_used,
            "frames_seen": self.frames_seen,
            "horizon_spread": self.horizon_spread,
            "notes": list(self.notes),
        }


def sample_indices(
    n_frames: int, count: int = _CAMERA_FRAMES, span: int = _CAMERA_SPAN
) -> NDArray[np.intp]:
    """Indices of up to ``count`` frames spread evenly over the first ``span`` of a recording.

    Examples
    --------
    >>> sample_indices(1000, 5, 401).tolist()
    [0, 100, 200, 300, 400]
    >>> sample_indices(3).tolist()
    [0, 1, 2]
    """
    for name, value, lo in (("n_frames", n_frames, 0), ("count", count, 1), ("span", span, 1)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < lo:
            raise ParameterError(name, value, f"an integer >= {lo}")
    last = min(int(n_frames), int(span)) - 1
    if last < 0:
        return np.zeros(0, dtype=np.intp)
    k = min(int(count), last + 1)
    return np.unique(np.round(np.linspace(0, last, k)).astype(np.intp))


def camera_roi(
    shape: tuple[int, ...],
    horizon: float,
    vp_x: float = 0.5,
    hood_rows: Sequence[float] | None = None,
    *,
    top_gap: float = 0.04,
    side_slope: float | tuple[float, float] = 2.5,
    curve_margin: float = 0.15,
) -> tuple[tuple[float, float], ...]:
    """ROI polygon (relative, clockwise from the bottom left) for a camera geometry.

    Parameters
    ----------
    shape : tuple
        ``(H, W)`` of the frames (the side slope is in pixels, so the aspect matters).
    horizon : float
        Horizon row relative to the height.
    vp_x : float
        Vanishing point column relative to the width.
    hood_rows : sequence of float, optional
        Top row of the hood (relative) at evenly spaced columns, 1.0 where none.
    top_gap : float
        The ROI's top edge is this far (fraction of the height) below the horizon.
    side_slope : float or (float, float)
        Horizontal pixels the ROI widens by per pixel downwards, on each side (or
        ``(left, right)``).
    curve_margin : float
        Half-width of the ROI on the horizon row, as a fraction of the width (room for
        bends, whose lines vanish beside the straight-ahead vanishing point).

    Returns
    -------
    tuple of (x, y)

    Examples
    --------
    >>> roi = camera_roi((480, 640), 0.40)
    >>> [tuple(round(v, 4) for v in p) for p in roi][:3]
    [(0.0, 1.0), (0.0, 0.5868), (0.275, 0.44)]
    """
    h, w = int(shape[0]), int(shape[1])
    if not (0.0 <= horizon < 0.95 and -0.5 <= vp_x <= 1.5):
        raise ParameterError("horizon, vp_x", (horizon, vp_x), "a horizon in [0, 0.95)")
    aspect = (h - 1) / max(w - 1, 1)
    y_top = min(horizon + top_gap, 0.97)
    slope_l, slope_r = _side_slopes(side_slope)
    left_top = vp_x - curve_margin - slope_l * (y_top - horizon) * aspect
    right_top = vp_x + curve_margin + slope_r * (y_top - horizon) * aspect
    y_left = horizon + (vp_x - curve_margin) / (slope_l * aspect)
    y_right = horizon + (1.0 - vp_x - curve_margin) / (slope_r * aspect)
    top = [(max(left_top, 0.0), y_top), (min(right_top, 1.0), y_top)]
    left = [(0.0, y_left)] if y_top < y_left < 1.0 else []
    right = [(1.0, y_right)] if y_top < y_right < 1.0 else []
    if hood_rows is None:
        bottom_right: list[tuple[float, float]] = [(1.0, 1.0)]
        bottom_left: list[tuple[float, float]] = [(0.0, 1.0)]
        notch: list[tuple[float, float]] = []
    else:
        rows = np.minimum(np.asarray(hood_rows, dtype=np.float64) - _HOOD_MARGIN, 1.0)
        xs = np.linspace(0.0, 1.0, rows.size)
        side_rows = [y for _, y in left + right] or [y_top]
        if rows.min() <= max(side_rows) + 0.01:
            plain = camera_roi(
                shape,
                horizon,
                vp_x,
                None,
                top_gap=top_gap,
                side_slope=(slope_l, slope_r),
                curve_margin=curve_margin,
            )
            return _clipped_roi(shape, plain, rows)
        pts = [(float(x), float(y)) for x, y in zip(xs, rows, strict=True)]
        bottom_right, notch, bottom_left = [pts[-1]], pts[-2:0:-1], [pts[0]]
    polygon = bottom_left + left + top + right + bottom_right + notch
    return tuple((round(x, 6), round(y, 6)) for x, y in polygon)


def _side_slopes(side_slope: float | tuple[float, float]) -> tuple[float, float]:
    """:func:`camera_roi`'s ``side_slope`` as checked ``(left, right)`` slopes."""
    if isinstance(side_slope, tuple):
        slope_l, slope_r = float(side_slope[0]), float(side_slope[1])
    else:
        slope_l = slope_r = float(side_slope)
    if not all(0.1 <= float(v) <= 20.0 for v in (slope_l, slope_r)):
        raise ParameterError("side_slope", side_slope, "pixels per pixel in [0.1, 20]")
    return slope_l, slope_r


def _clipped_roi(
    shape: tuple[int, ...], polygon: tuple[tuple[float, float], ...], hood_rows: NDArray[Any]
) -> tuple[tuple[float, float], ...]:
    """The polygon minus everything below the hood line, traced back into a polygon."""
    h, w = int(shape[0]), int(shape[1])
    mask = polygon_mask((h, w), polygon).astype(np.uint8)
    limit = np.interp(np.arange(w) / max(w - 1, 1), np.linspace(0, 1, hood_rows.size), hood_rows)
    rows = np.arange(h)[:, None] / max(h - 1, 1)
    mask[rows > limit[None, :]] = 0
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    if not contours:
        return ()
    biggest = max(contours, key=cv2.contourArea)
    approx = cv2.approxPolyDP(biggest, 1.0, True)[:, 0, :].astype(np.float64)
    rel = approx / [max(w - 1, 1), max(h - 1, 1)]
    return tuple((round(float(x), 6), round(float(y), 6)) for x, y in rel)


def apply_camera(config: LaneConfig, geometry: CameraGeometry) -> LaneConfig:
    """``config`` with the ROI and vanishing point of ``geometry``."""
    return replace(config, roi=geometry.roi, vanishing_point=geometry.vanishing_point)


def border_segments(grey: NDArray[np.uint8], below_row: int = 0) -> NDArray[np.float64]:
    """Hough segments of a grey working frame that may be lane borders (module docstring).

    Rows above ``below_row`` are ignored. Returns ``(N, 4)`` with ``y1 <= y2``.
    """
    h, w = grey.shape
    edges = cv2.Canny(cv2.GaussianBlur(cv2.medianBlur(grey, 5), (5, 5), 0), 50, 150)
    edges[: max(int(0.1 * h), below_row)] = 0
    found = cv2.HoughLinesP(
        edges, 1, np.pi / 180, 20, minLineLength=max(4, round(0.05 * w)), maxLineGap=3
    )
    if found is None:
        return np.zeros((0, 4))
    seg = found.reshape(-1, 4).astype(np.float64)
    flip = seg[:, 1] > seg[:, 3]
    seg[flip] = seg[flip][:, [2, 3, 0, 1]]
    angle = np.degrees(np.arctan2(seg[:, 3] - seg[:, 1], np.abs(seg[:, 2] - seg[:, 0])))
    return seg[(angle >= _BORDER_ANGLES[0]) & (angle <= _BORDER_ANGLES[1])]


@dataclass(frozen=True)
class VanishingPoint:
    """One frame's vanishing point (pixels of the frame it was found in).

    ``left_support`` / ``right_support``: total length (pixels) of the supporting left and
    right segments; ``left_slope`` / ``right_slope``: ``|dx/dy|`` of the innermost
    supporting borders (the length-weighted lower quartile per side: the own lane's).
    """

    x: float
    y: float
    left_support: float
    right_support: float
    left_slope: float
    right_slope: float


def vanishing_point(segments: NDArray[np.float64], shape: tuple[int, int]) -> VanishingPoint | None:
    """Vanishing point of lane-border segments (module docstring), in their pixels.

    Returns
    -------
    VanishingPoint or None
        None without a left and a right segment.
    """
    h, w = shape
    dy = segments[:, 3] - segments[:, 1]
    a = (segments[:, 2] - segments[:, 0]) / np.maximum(dy, 1e-9)
    b = segments[:, 0] - a * segments[:, 1]
    length = np.hypot(segments[:, 2] - segments[:, 0], dy)
    bottom = segments[:, 3]
    left, right = np.flatnonzero(a < 0), np.flatnonzero(a > 0)
    if left.size == 0 or right.size == 0:
        return None
    left = left[np.argsort(-length[left])][:_MAX_BORDERS]
    right = right[np.argsort(-length[right])][:_MAX_BORDERS]
    li, ri = (g.ravel() for g in np.meshgrid(left, right, indexing="ij"))
    y = (b[ri] - b[li]) / (a[li] - a[ri])
    x = a[li] * y + b[li]
    ok = (y >= 0) & (y < h) & (x > -0.5 * w) & (x < 1.5 * w)
    if not ok.any():
        return None
    x, y = x[ok], y[ok]
    tol = _SUPPORT_TOLERANCE * w
    miss = np.abs(a[None, :] * y[:, None] + b[None, :] - x[:, None])
    inlier = (miss <= tol) & (bottom[None, :] > y[:, None] + 2.0)
    support = inlier * length[None, :]
    lsum = support[:, a < 0].sum(axis=1)
    rsum = support[:, a > 0].sum(axis=1)
    best = int(np.argmax(np.sqrt(lsum * rsum)))
    keep = inlier[best]
    # refine: b = x0 - y0 * a over the supporting segments, weighted by length
    design = np.column_stack([np.ones(int(keep.sum())), -a[keep]])
    sw = np.sqrt(length[keep])
    coef, *_ = np.linalg.lstsq(design * sw[:, None], b[keep] * sw, rcond=None)
    x0, y0 = float(coef[0]), float(coef[1])
    if not (np.isfinite(x0) and np.isfinite(y0) and 0 <= y0 < h):
        x0, y0 = float(x[best]), float(y[best])
    slopes = [
        _weighted_quantile(np.abs(a[keep & side]), length[keep & side], 0.25)
        for side in (a < 0, a > 0)
    ]
    return VanishingPoint(x0, y0, float(lsum[best]), float(rsum[best]), *slopes)


def _weighted_quantile(
    values: NDArray[np.float64], weights: NDArray[np.float64], q: float
) -> float:
    if values.size == 0:
        return float("nan")
    order = np.argsort(values)
    cum = np.cumsum(weights[order])
    return float(values[order][min(int(np.searchsorted(cum, q * cum[-1])), values.size - 1)])


def _detect_hood(
    greys: NDArray[np.uint8], static_std: float = _STATIC_STD
) -> tuple[NDArray[np.float64] | None, float, list[str]]:
    """The car's hood in a stack of grey frames of one recording: its top row per column.

    Two kinds of evidence, per column, the higher one wins:

    - static pixels connected to the bottom edge: grey level standard deviation across the
      frames below ``static_std`` (a matt bonnet; also a covered part of the lens, which
      the caller must not take for a hood when it is over half the frame). When most of
      the frame is static (90 % of the pixels: night, a car that never moves) this
      evidence is not used, with a note;
    - a persistent outline: near-horizontal edges (Canny, within 30 degrees of the
      horizontal, dilated by one pixel) present at the same place in at least 90 % of the
      frames, in the bottom 35 % of the frame (a glossy bonnet reflects the scene, so its
      pixels change, but its outline stays). Only the widest run of adjacent columns that
      have one counts, and only when it spans at least 30 % of the width; lane lines of a
      long straight road persist too, but they are steeper than 30 degrees.

    Parameters
    ----------
    greys : (K, H, W) uint8 array
        Frames of one recording, same size, K >= 3.
    static_std : float
        Largest standard deviation (grey levels) of a static pixel.

    Returns
    -------
    rows : (W,) float array or None
        Top row of the hood per column (relative; 1.0 where none), None when no hood.
    fraction : float
        Fraction of the frame the hood region covers.
    notes : list of str
    """
    _, h, w = greys.shape
    notes: list[str] = []
    std = greys.astype(np.float32).std(axis=0)
    static = cv2.morphologyEx(
        (std < static_std).astype(np.uint8), cv2.MORPH_CLOSE, np.ones((5, 1), np.uint8)
    )
    moving = static[::-1] == 0
    run = np.where(moving.any(axis=0), np.argmax(moving, axis=0), h).astype(np.float64)
    run[run < max(2, round(0.02 * h))] = 0
    if float(np.mean(std < static_std)) > 0.9:
        # a frozen scene: static pixels say nothing about a hood
        notes.append("frames hardly change (night, a car standing still, a covered lens?)")
        run[:] = 0
    outline = _persistent_outline(greys)
    top = np.minimum(h - run, outline)  # first hood row per column (h: none)
    top = cv2.medianBlur(top.astype(np.float32)[None, :], 5)[0] if w >= 5 else top
    depth = h - top
    fraction = float(depth.sum()) / (h * w)
    if fraction < 0.005:
        return None, fraction, notes
    return np.minimum(top / max(h - 1, 1), 1.0), fraction, notes


def _persistent_outline(greys: NDArray[np.uint8]) -> NDArray[np.float64]:
    """Per column, the first row of a persistent near-horizontal edge low in the frame."""
    k, h, w = greys.shape
    count = np.zeros((h, w), np.float32)
    flat = np.tan(np.radians(30.0))
    dilate = np.ones((3, 3), np.uint8)
    for grey in greys:
        blurred = cv2.GaussianBlur(grey, (5, 5), 0)
        gx = cv2.Sobel(blurred, cv2.CV_32F, 1, 0)
        gy = cv2.Sobel(blurred, cv2.CV_32F, 0, 1)
        edge = (cv2.Canny(blurred, 30, 90) > 0) & (np.abs(gx) <= flat * np.abs(gy))
        count += cv2.dilate(edge.astype(np.uint8), dilate)
    persistent = count >= 0.9 * k
    persistent[: int(0.65 * h)] = False
    found = persistent.any(axis=0)
    rows = np.where(found, np.argmax(persistent, axis=0), h).astype(np.float64)
    rows = median_filter(rows, size=max(3, round(0.05 * w) | 1), mode="nearest")
    found = rows < h
    # keep the widest run of adjacent columns whose outline rows join up (one curve)
    joined = found[1:] & found[:-1] & (np.abs(np.diff(rows)) <= max(2.0, 0.06 * h))
    breaks = np.flatnonzero(~joined) + 1
    starts = np.concatenate([[0], breaks])
    stops = np.concatenate([breaks, [w]])
    starts, stops = starts[found[starts]], stops[found[starts]]
    if starts.size == 0:
        return np.full(w, float(h))
    i = int(np.argmax(stops - starts))
    if stops[i] - starts[i] < 0.3 * w:
        return np.full(w, float(h))
    out = np.full(w, float(h))
    out[starts[i] : stops[i]] = rows[starts[i] : stops[i]]
    return out


def estimate_camera(
    frames: Sequence[NDArray[np.uint8]],
    preset: LaneConfig | None = None,
    *,
    min_frames: int = 3,
) -> CameraGeometry:
    """Horizon, vanishing point, hood and ROI of a recording from some of its frames.

    Parameters
    ----------
    frames : sequence of (H, W, 3) or (H, W) uint8 arrays
        Frames of one recording (e.g. those of :func:`sample_indices`); frames of another
        size than the first are left out, with a note.
    preset : LaneConfig, optional
        What to fall back on: its ROI and vanishing point (default
        :meth:`LaneConfig.dashcam`).
    min_frames : int
        Counted frames needed (and at least a quarter of the frames seen).

    Returns
    -------
    CameraGeometry
    """
    base = preset or LaneConfig.dashcam()
    if len(frames) == 0:
        raise InputError("frames", "no frames to estimate the camera from")
    notes: list[str] = []
    shape, same = _same_size_frames(frames, notes)
    greys = np.stack([to_grey(working_frame(f, _WORK_WIDTH)) for f in same])
    hood, fraction, hood_notes = (None, 0.0, []) if len(greys) < 3 else _detect_hood(greys)
    notes += hood_notes
    if fraction > 0.5:
        notes.append(
            f"the static region at the bottom covers {fraction:.0%} of the frame (over half: "
            "a hood that big, or a covered lens?): using the preset's ROI"
        )
        return _preset_geometry(base, shape, None, len(same), notes)
    wh, ww = greys.shape[1:]
    points = _vanishing_points(greys, hood)
    hood_rows = None if hood is None else _sample_profile(hood)
    needed = max(min_frames, int(np.ceil(0.25 * len(greys))))
    if len(points) < needed:
        notes.append(
            f"no horizon found: lane borders met in {len(points)} of {len(greys)} frames "
            f"(needed {needed}; night, a wall, a covered lens?): using the preset's horizon"
        )
        return _preset_geometry(base, shape, hood_rows, len(same), notes)
    pts = np.asarray(points)
    xv = float(np.median(pts[:, 0])) / max(ww - 1, 1)
    yv = float(np.median(pts[:, 1])) / max(wh - 1, 1)
    spread = float(np.median(np.abs(pts[:, 1] / max(wh - 1, 1) - yv)))
    if not 0.05 <= yv <= 0.85:
        notes.append(
            f"horizon estimate at {yv:.0%} of the height is implausible: using the preset's"
        )
        return _preset_geometry(base, shape, hood_rows, len(same), notes)
    roi = _estimated_roi(shape, xv, yv, hood_rows, np.nanmedian(pts[:, 2:4], axis=0))
    if not _usable(shape, roi):
        notes.append("the ROI built from the estimate is empty: using the preset's")
        return _preset_geometry(base, shape, hood_rows, len(same), notes)
    return CameraGeometry(
        shape,
        yv,
        (xv, yv),
        hood_rows,
        roi,
        "estimated",
        len(points),
        len(same),
        spread,
        tuple(notes),
    )


def _same_size_frames(
    frames: Sequence[NDArray[np.uint8]], notes: list[str]
) -> tuple[tuple[int, int], list[NDArray[np.uint8]]]:
    """The first frame's ``(H, W)`` and the frames of that size (a note for the others)."""
    first = frames[0]
    shape = (int(first.shape[0]), int(first.shape[1]))
    same = [f for f in frames if tuple(f.shape[:2]) == shape]
    if len(same) < len(frames):
        notes.append(
            f"{len(frames) - len(same)} of {len(frames)} frames differ in size from the "
            f"first ({shape[1]}x{shape[0]}): left out of the camera estimate"
        )
    return shape, same


def _vanishing_points(
    greys: NDArray[np.uint8], hood: NDArray[np.float64] | None
) -> list[tuple[float, float, float, float]]:
    """``(x, y, left slope, right slope)`` of each frame's well-supported vanishing point
    above the hood (border segments reaching onto the hood are left out)."""
    wh, ww = greys.shape[1:]
    hood_top_px = 0 if hood is None else int(np.floor(hood.min() * (wh - 1)))
    points = []
    for grey in greys:
        seg = border_segments(grey)
        if hood is not None and len(seg):
            cols = np.clip(np.round(seg[:, [0, 2]]).astype(int), 0, ww - 1)
            limit = hood[cols] * (wh - 1)
            seg = seg[(seg[:, [1, 3]] < limit - 1).all(axis=1)]
        found = vanishing_point(seg, (wh, ww)) if len(seg) else None
        if found is not None and min(found.left_support, found.right_support) >= _MIN_SUPPORT * wh:
            if hood is None or found.y < hood_top_px:
                points.append((found.x, found.y, found.left_slope, found.right_slope))
    return points


def _estimated_roi(
    shape: tuple[int, int],
    xv: float,
    yv: float,
    hood_rows: tuple[float, ...] | None,
    inner: NDArray[np.float64],
) -> tuple[tuple[float, float], ...]:
    """The ROI for an estimated vanishing point, its sides following the median inner
    border slopes ``inner`` (left, right; the upper end of _ROI_SLOPES where unknown)."""
    slopes = tuple(
        float(np.clip(_ROI_SLOPE_SCALE * v + _ROI_SLOPE_ADD, *_ROI_SLOPES))
        if np.isfinite(v)
        else _ROI_SLOPES[1]
        for v in inner
    )
    return camera_roi(
        shape,
        yv,
        xv,
        hood_rows,
        top_gap=_ROI_TOP_GAP,
        side_slope=(slopes[0], slopes[1]),
        curve_margin=_ROI_CURVE_MARGIN,
    )


def _sample_profile(rows: NDArray[np.float64]) -> tuple[float, ...]:
    """The hood's top row at _HOOD_COLUMNS columns: the highest row within each column band."""
    w = rows.size
    centres = np.linspace(0, w - 1, _HOOD_COLUMNS)
    half = max(1.0, 0.5 * (w - 1) / (_HOOD_COLUMNS - 1))
    out = []
    for c in centres:
        lo, hi = int(max(0, np.floor(c - half))), int(min(w, np.ceil(c + half) + 1))
        out.append(round(float(rows[lo:hi].min()), 4))
    return tuple(out)


def _usable(shape: tuple[int, int], roi: tuple[tuple[float, float], ...]) -> bool:
    return len(roi) >= 3 and float(polygon_mask(shape, roi).mean()) >= 0.02


def _preset_geometry(
    base: LaneConfig,
    shape: tuple[int, int],
    hood_rows: tuple[float, ...] | None,
    seen: int,
    notes: list[str],
) -> CameraGeometry:
    vp = base.vanishing_point or (0.5, 0.40)
    roi: tuple[tuple[float, float], ...] = tuple(base.roi)
    if hood_rows is not None:
        notched = camera_roi(shape, float(vp[1]), float(vp[0]), hood_rows)
        if _usable(shape, notched):
            roi = notched
    return CameraGeometry(
        shape,
        float(vp[1]),
        (float(vp[0]), float(vp[1])),
        hood_rows,
        roi,
        "preset",
        0,
        seen,
        float("nan"),
        tuple(notes),
    )
