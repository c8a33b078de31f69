"""Group Hough segments into two lane lines and return their slopes (the paper's features).

The paper (Sec. II-A-3, II-C and III-A; NOTES 5) reduces the Hough segments of a frame to
two lines with one of three methods, fits a line to each group and feeds the two slopes,
a 2x1 vector, to the direction decision. The methods here:

``"image-split"``
    A segment belongs to the left group when its midpoint is left of the frame's vertical
    midline ``x = (W - 1) / 2``, else to the right group.
``"kmeans"``
    ``sklearn.cluster.KMeans(2)`` on segment descriptors (below).
``"spectral"``
    ``sklearn.cluster.SpectralClustering(2, affinity="nearest_neighbors")`` on the same
    descriptors, with ``n_neighbors = min(10, N - 1)``.

Segment descriptor (k-means and spectral): ``[xm / W, cos(2 theta) / 2, sin(2 theta) / 2]``
where ``xm`` is the midpoint's x and ``theta`` the segment's angle from the image vertical.
The doubled angle makes the descriptor continuous (a segment at +89 and one at -89 degrees
are neighbours) and independent of which end comes first; halving it gives the orientation
part the same spread (1) as the position part.

Slope definition
----------------
Each group gets the least-squares line ``x = a * y + b`` through its segments' endpoints
(pixel coordinates, y pointing down, each endpoint weighted by its segment's length).
The feature is ``a = dx/dy``: 0 for a vertical line, finite for every non-horizontal
line. On a straight road the left lane line has ``a < 0`` and the right one ``a > 0``.
A group whose endpoints all lie on one row has no such line (missing, NaN).
The left line is the group whose segment midpoints have the smaller mean x; a single
group goes to the side of the midline its mean x is on.

Missing lines, and pairs that cannot be a road
-----------------------------------------------
Every frame gets a status: "ok" (two lines that can border a road), "one-line" or
"no-lines"; missing slopes are NaN. Two fitted lines that cannot be the borders of a road
seen from the car get "crossed" (they meet between the top and the bottom row of the
region of interest) or "wrong-side" (the left line lies right of the right one over the
whole region, or leans right, ``a > 0``, while the right one leans left, ``a < 0``: such
lines converge downwards, a road's converge upwards). Their slopes are kept (the
decision is made as for any two lines) and the status flags the frame
(:func:`pair_status`).

k-means and spectral clustering always return two clusters, so a frame showing one road
edge (e.g. the two borders of one kerb) would give two slopes of the same line:
when one line fits all the segments within ``merge_tolerance`` (3 % of the width by
default) the frame counts as "one-line". ``merge_tolerance=None`` turns this off.

Extra features and feature modes (not the paper's)
--------------------------------------------------
Named extras (``extra_features``) are appended after the two slopes, all from the two
fitted lines except the last one; x positions are relative to the width, minus 0.5
(0 = the frame's centre column):

``"intercepts"``, ``"angles"``, ``"vanishing-point-offset"``
    Where each line meets the bottom row; ``atan(dx/dy)``; x of the lines' intersection.
``"far-offsets"``
    x of each line at the far row ``FAR_ROW`` (``far_left``, ``far_right``). Both move
    left in a left bend and right in a right bend; on a straight road they are mirror
    images, so the UU-dagger rule can compare them as it compares the two slopes.
``"road-centre"``
    x of the centre line (the mean of the two lines) at ``FAR_ROW`` and at ``NEAR_ROW``.
``"near-vanishing-point-offset"``
    The vanishing-point offset of two lines fitted to the near segments only (lower end at
    or below ``NEAR_PART``), the road's direction just ahead of the car.

A feature mode (:attr:`qdcnn.config.GroupingConfig.FEATURE_MODES`) names the two columns
a 2-input classifier uses; :func:`mode_columns` gives their indices.

References
----------
.. [1] QDCNN paper, ``shared/paper/qdcnn-paper.tex``, Sec. II-A-3, II-C, III-A.
.. [2] S. Lloyd, "Least squares quantization in PCM", IEEE Trans. Inf. Theory 28(2), 1982.
.. [3] A. Ng, M. Jordan, Y. Weiss, "On spectral clustering: analysis and an algorithm",
   NIPS 2001.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from qdcnn._threads import single_thread
from qdcnn._validation import has_shape
from qdcnn.config import GroupingConfig
from qdcnn.errors import InputError, ParameterError

#: The lane groupings of the paper (Sec. II-A-3), in the paper's order.
GROUPINGS: tuple[str, ...] = ("image-split", "kmeans", "spectral")
EXTRA_FEATURES: dict[str, tuple[str, ...]] = {
    # x where each line crosses the bottom row, relative to the width (x / (W - 1))
    "intercepts": ("intercept_left", "intercept_right"),
    # atan(dx/dy) in radians: the slopes mapped to (-pi/2, pi/2)
    "angles": ("angle_left", "angle_right"),
    # x of the two lines' intersection relative to the width (x / (W - 1)), minus 0.5
    "vanishing-point-offset": ("vanishing_point_offset",),
    # x of each line at the far row FAR_ROW, relative to the width, minus 0.5
    "far-offsets": ("far_left", "far_right"),
    # x of the centre line (mean of the two lines) at FAR_ROW and at NEAR_ROW, minus 0.5
    "road-centre": ("centre_far", "centre_near"),
    # the vanishing-point offset of lines fitted to the near segments only (NEAR_PART)
    "near-vanishing-point-offset": ("near_vanishing_point_offset",),
}
#: far and near rows of "far-offsets" and "road-centre", relative to the height (y / (H - 1))
FAR_ROW, NEAR_ROW = 0.5, 0.9
#: "near-vanishing-point-offset" uses the segments whose lower end is at or below this row
NEAR_PART = 0.7
_SLOPE_NAMES: tuple[str, str] = ("slope_left", "slope_right")
Status = Literal["ok", "one-line", "no-lines", "crossed", "wrong-side"]
_SPECTRAL_NEIGHBOURS = 10
#: segments fitting one line within this fraction of the width are one line (group_segments)
_MERGE_TOLERANCE = 0.03
#: label of segments that ``inner_lines`` leaves out of both lines
LEFT_OUT = 2
#: inner_lines: segments whose lines cross the reference row this close (fraction of the
#: width) belong to one line; a line needs this share of its side's segment length
_INNER_BAND, _INNER_SHARE = 0.04, 0.2
#: inner_lines: the reference row (relative), near the bottom where lines are far apart
_INNER_ROW = 0.9
#: inner_lines: largest dx/dy of a border leaning the wrong way for its side
_INNER_LEAN = 0.1


@dataclass
class LaneFeatures:
    """Two-line summary of one frame's segments.

    Attributes
    ----------
    features : (2 + k,) float64 array
        ``[slope_left, slope_right]`` (dx/dy, see the module docstring), then any extra
        features in the order asked for; NaN where a line is missing.
    status : {"ok", "one-line", "no-lines", "crossed", "wrong-side"}
        Whether both lines, one line or none could be fitted, and whether two lines can
        border a road (:func:`pair_status`).
    n_segments : int
        Number of segments given.
    lines : list of two ((a, b) or None)
        Fitted ``x = a * y + b`` per group, left first.
    labels : (n_segments,) int64 array
        Group of each segment: 0 = left line, 1 = right line, 2 (:data:`LEFT_OUT`) = in
        neither line (only with ``inner_lines``).
    method : str
        Grouping method used.
    feature_names : tuple of str
        Name of each entry of ``features``.
    shape : tuple of int
        ``(H, W)`` of the frame.
    middle_line : (a, b) or None
        The centre line between the two fitted lines (their average), drawn by the
        image-split overlay; None unless both lines exist.
    segments : (n_segments, 4) array or None
        The segments that were grouped (``labels`` gives each one's group).
    roi_rows : (float, float) or None
        Top and bottom row of the region of interest, relative to the height (0: the top
        row, 1: the bottom one), where two lines must not cross; ``None``: the rows the
        segments span.
    """

    features: NDArray[np.float64]
    status: Status
    n_segments: int
    lines: list[tuple[float, float] | None]
    labels: NDArray[np.int64]
    method: str
    feature_names: tuple[str, ...] = _SLOPE_NAMES
    shape: tuple[int, int] = (0, 0)
    middle_line: tuple[float, float] | None = field(default=None)
    segments: NDArray[np.float64] | None = field(default=None, repr=False)
    roi_rows: tuple[float, float] | None = None


def feature_names(extra_features: Sequence[str] = ()) -> tuple[str, ...]:
    """Names of the feature columns for ``extra_features`` (the two slopes first)."""
    _check_extras(extra_features)
    return _SLOPE_NAMES + tuple(n for extra in extra_features for n in EXTRA_FEATURES[extra])


def mode_columns(features: str, extra_features: Sequence[str] = ()) -> tuple[int, int]:
    """Indices of a feature mode's two columns in the vector of ``extra_features``.

    Parameters
    ----------
    features : str
        A key of :attr:`qdcnn.config.GroupingConfig.FEATURE_MODES` (``"slopes"`` is the
        paper's two slopes).
    extra_features : sequence of str
        The extras the feature vector was computed with.

    Examples
    --------
    >>> mode_columns("far-offsets", ("angles", "far-offsets"))
    (4, 5)
    """
    if features not in GroupingConfig.FEATURE_MODES:
        allowed = ", ".join(map(repr, GroupingConfig.FEATURE_MODES))
        raise ParameterError("features", features, f"one of {allowed}")
    names = feature_names(extra_features)
    wanted, needed = GroupingConfig.FEATURE_MODES[features]
    missing = [n for n in wanted if n not in names]
    if missing:
        raise ParameterError(
            "extra_features", tuple(extra_features), f"to include {needed} for {features!r}"
        )
    return names.index(wanted[0]), names.index(wanted[1])


def fit_line(segments: NDArray[np.float64]) -> tuple[float, float] | None:
    """Length-weighted least-squares line ``x = a * y + b`` through the segments' endpoints.

    Parameters
    ----------
    segments : (N, 4) array
        Rows ``x1, y1, x2, y2``.

    Returns
    -------
    (a, b) or None
        None when there is no segment, or when all endpoints lie on one row (horizontal).

    Examples
    --------
    >>> fit_line(np.array([[10.0, 0.0, 20.0, 10.0], [30.0, 20.0, 40.0, 30.0]]))
    (1.0, 10.0)
    """
    if len(segments) == 0:
        return None
    x = np.concatenate([segments[:, 0], segments[:, 2]])
    y = np.concatenate([segments[:, 1], segments[:, 3]])
    length = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
    w = np.concatenate([length, length]) + 1e-12  # a zero-length segment still counts a little
    w /= w.sum()
    ym = float(w @ y)
    xm = float(w @ x)
    dy = y - ym
    var_y = float(w @ (dy * dy))
    if var_y < 1e-9:
        return None
    a = float(w @ (dy * (x - xm))) / var_y
    return a, xm - a * ym


def pair_status(lines: Sequence[tuple[float, float] | None], rows: tuple[float, float]) -> Status:
    """The status of a frame's two fitted lines (left first) over the rows ``rows`` (pixels).

    "no-lines" or "one-line" when lines are missing; for two lines "crossed" when they meet
    between the two rows (the left line is left of the right one at one row and not at
    the other), "wrong-side" when the left line is not left of the right one at either
    row, or when the left line leans right (``a > 0``) and the right one leans left
    (``a < 0``); else "ok".

    Examples
    --------
    >>> pair_status([(-0.667, 140.0), (0.667, 180.0)], (60.0, 159.0))
    'ok'
    >>> pair_status([(-3.93, 500.0), (4.22, -300.0)], (60.0, 159.0))
    'crossed'
    >>> pair_status([(0.3, 40.0), (-0.3, 280.0)], (60.0, 159.0))
    'wrong-side'
    """
    left, right = lines[0], lines[1]
    if left is None or right is None:
        return "no-lines" if left is None and right is None else "one-line"
    gaps = [(right[0] - left[0]) * y + right[1] - left[1] for y in rows]
    if (gaps[0] > 0) != (gaps[1] > 0):
        return "crossed"
    if gaps[0] <= 0 or (left[0] > 0 and right[0] < 0):
        return "wrong-side"
    return "ok"


def check_rows(
    roi_rows: tuple[float, float] | None, segments: NDArray[np.float64] | None, height: int
) -> tuple[float, float]:
    """The pixel rows :func:`pair_status` checks: the ROI's, or the rows the segments span."""
    if roi_rows is not None:
        return roi_rows[0] * (height - 1), roi_rows[1] * (height - 1)
    if segments is None or len(segments) == 0:
        return 0.0, float(height - 1)
    ys = segments[:, [1, 3]]
    return float(ys.min()), float(ys.max())


def segment_descriptors(segments: NDArray[np.float64], width: int) -> NDArray[np.float64]:
    """Clustering descriptors ``[xm / W, cos(2 theta) / 2, sin(2 theta) / 2]`` per segment.

    ``theta`` is the angle from the image vertical (``atan2(dx, dy)``), so the descriptor
    does not depend on which end of the segment comes first.
    """
    dx = segments[:, 2] - segments[:, 0]
    dy = segments[:, 3] - segments[:, 1]
    theta2 = 2.0 * np.arctan2(dx, dy)
    xm = 0.5 * (segments[:, 0] + segments[:, 2]) / max(width, 1)
    return np.column_stack([xm, 0.5 * np.cos(theta2), 0.5 * np.sin(theta2)])


def group_segments(
    segments: NDArray[np.float64],
    shape: tuple[int, ...],
    method: str = "image-split",
    *,
    seed: int = 0,
    extra_features: Sequence[str] = (),
    merge_tolerance: float | None = _MERGE_TOLERANCE,
    inner_lines: bool = False,
    roi_rows: tuple[float, float] | None = None,
) -> LaneFeatures:
    """Split segments into a left and a right group, fit a line to each, return the slopes.

    Parameters
    ----------
    segments : (N, 4) array
        Hough segments ``x1, y1, x2, y2`` in pixels (:func:`qdcnn.vision.lanes.detect_segments`).
    shape : tuple
        ``(H, W)`` (or ``(H, W, C)``) of the frame the segments come from.
    method : {"image-split", "kmeans", "spectral"}
        Grouping method (module docstring).
    seed : int
        Random state of k-means and spectral clustering.
    extra_features : sequence of str
        Named features appended after the two slopes (not the paper's): any of
        ``"intercepts"``, ``"angles"``, ``"vanishing-point-offset"``.
    merge_tolerance : float or None
        When both lines are fitted but one line through all the segments fits them too,
        i.e. the length-weighted RMS distance of the endpoints to it is below
        ``merge_tolerance * W`` pixels, the two groups are one line seen twice (k-means
        and spectral always return two clusters, e.g. the two borders of one painted
        stripe): that single line is kept and the status is "one-line". ``None`` never
        merges (two groups always give two slopes).
    inner_lines : bool
        Keep only each group's innermost line (not the paper's; :func:`inner_line_labels`):
        the segments of other lines on that side (the far edge of the other lane, a kerb,
        a parked car) get label :data:`LEFT_OUT` and no part in the fit.
    roi_rows : (float, float) or None
        Top and bottom row of the region of interest relative to the height; two lines
        that cross between them are "crossed" (:func:`pair_status`). ``None``: the rows
        the segments span (a road's lines meet at the vanishing point, above the region
        and above the segments, but often inside the frame).

    Returns
    -------
    LaneFeatures
        Status "no-lines" when no line can be fitted, "one-line" when only one can
        (e.g. one segment, all segments on one side for image-split, or merged groups),
        "crossed" or "wrong-side" when two lines cannot border a road.

    Examples
    --------
    >>> seg = np.array([[100.0, 60, 40, 150], [220, 60, 280, 150]])
    >>> f = group_segments(seg, (160, 320))
    >>> f.status, np.round(f.features, 3).tolist()
    ('ok', [-0.667, 0.667])
    """
    if method not in GROUPINGS:
        raise ParameterError("method", method, "'image-split', 'kmeans' or 'spectral'")
    seg, h, w = _checked_segments(segments, shape, merge_tolerance)
    labels = _left_right_labels(seg, method, seed, w)
    if inner_lines:
        labels = _inner_line_labels(seg, labels, h, w)
    lines: list[tuple[float, float] | None] = [fit_line(seg[labels == g]) for g in (0, 1)]
    if merge_tolerance is not None and lines[0] is not None and lines[1] is not None:
        labels, lines = _merge_one_line(seg, labels, lines, merge_tolerance * w, w)
    values = feature_values(lines, extra_features, h, w, seg, labels)
    return LaneFeatures(
        features=values,
        status=pair_status(lines, check_rows(roi_rows, seg, h)),
        n_segments=len(seg),
        lines=lines,
        labels=labels.astype(np.int64),
        method=method,
        feature_names=feature_names(extra_features),
        shape=(h, w),
        middle_line=_middle_line(lines),
        segments=seg,
        roi_rows=roi_rows,
    )


def _checked_segments(
    segments: NDArray[np.float64], shape: tuple[int, ...], merge_tolerance: float | None
) -> tuple[NDArray[np.float64], int, int]:
    """Check :func:`group_segments`' inputs; the segments as ``(N, 4)`` floats, H and W."""
    seg = np.asarray(segments, dtype=np.float64)
    if seg.size == 0:
        seg = seg.reshape(0, 4)
    if not has_shape(seg, "N,4") or not np.isfinite(seg).all():
        raise InputError("segments", f"expected a finite (N, 4) array, got shape {seg.shape}")
    if len(shape) < 2 or shape[0] < 1 or shape[1] < 1:
        raise InputError("shape", f"expected (H, W), got {tuple(shape)}")
    if merge_tolerance is not None and not (
        isinstance(merge_tolerance, int | float) and 0.0 <= merge_tolerance <= 1.0
    ):
        raise ParameterError("merge_tolerance", merge_tolerance, "None or a number in [0, 1]")
    return seg, int(shape[0]), int(shape[1])


def _left_right_labels(
    seg: NDArray[np.float64], method: str, seed: int, w: int
) -> NDArray[np.int64]:
    """Group 0 (left) or 1 (right) per segment, by ``method``."""
    mid_x = 0.5 * (seg[:, 0] + seg[:, 2])
    centre = 0.5 * (w - 1)
    if method == "image-split":
        return (mid_x >= centre).astype(np.int64)
    labels = _cluster(segment_descriptors(seg, w), method, seed)
    # left group first: order clusters by their mean midpoint x
    groups = [g for g in (0, 1) if np.any(labels == g)]
    if len(groups) == 2:
        if mid_x[labels == 0].mean() > mid_x[labels == 1].mean():
            labels = 1 - labels
    elif len(groups) == 1:
        labels = np.full(len(seg), int(mid_x.mean() >= centre), dtype=np.int64)
    return labels


def _merge_one_line(
    seg: NDArray[np.float64],
    labels: NDArray[np.int64],
    lines: list[tuple[float, float] | None],
    tolerance_px: float,
    w: int,
) -> tuple[NDArray[np.int64], list[tuple[float, float] | None]]:
    """The labels and lines after merging both groups into one line when one line fits all
    the kept segments within ``tolerance_px`` (unchanged when it does not)."""
    kept = labels < LEFT_OUT
    merged = _one_line(seg[kept], tolerance_px)
    if merged is None:
        return labels, lines
    mid_x = 0.5 * (seg[:, 0] + seg[:, 2])
    slot = int(mid_x[kept].mean() >= 0.5 * (w - 1))
    one: list[tuple[float, float] | None] = [None, None]
    one[slot] = merged
    return np.where(kept, slot, LEFT_OUT).astype(np.int64), one


def _middle_line(lines: list[tuple[float, float] | None]) -> tuple[float, float] | None:
    """The centre line between the two fitted lines (None unless both are fitted)."""
    left, right = lines
    if left is None or right is None:
        return None
    return (0.5 * (left[0] + right[0]), 0.5 * (left[1] + right[1]))


def _inner_line_labels(
    segments: NDArray[np.float64], labels: NDArray[np.int64], h: int, w: int
) -> NDArray[np.int64]:
    """Labels with every segment but those of each side's innermost line set to LEFT_OUT.

    A side's border runs down and outwards (left: ``dx/dy < 0``, right: ``dx/dy > 0``, up
    to :data:`_INNER_LEAN` the other way), so segments leaning the other way (car and
    shadow outlines) are left out first. Per side, each remaining segment's line
    ``x = a y + b`` is read at the row :data:`_INNER_ROW` of the height; sorted by that
    crossing, segments closer than :data:`_INNER_BAND` of the width to their neighbour form
    one line. The side keeps the line nearest the frame's centre among those holding at
    least :data:`_INNER_SHARE` of the side's segment length (the own lane's border: a double
    centre line is one line, the far border of the other lane, a kerb or a parked car's
    outline another).
    """
    out = labels.copy()
    if len(segments) == 0:
        return out
    dy = segments[:, 3] - segments[:, 1]
    a = (segments[:, 2] - segments[:, 0]) / np.where(dy > 1e-9, dy, np.inf)
    cross = segments[:, 0] + a * (_INNER_ROW * (h - 1) - segments[:, 1])
    cross = np.where(dy > 1e-9, cross, 0.5 * (segments[:, 0] + segments[:, 2]))
    length = np.hypot(segments[:, 2] - segments[:, 0], dy)
    for side in (0, 1):
        leaning = a < _INNER_LEAN if side == 0 else a > -_INNER_LEAN
        out[(labels == side) & ~leaning] = LEFT_OUT
        idx = np.flatnonzero((labels == side) & leaning)
        if idx.size < 2:
            continue
        # innermost first: the left side from the right, the right side from the left
        order = idx[np.argsort(-cross[idx] if side == 0 else cross[idx])]
        gaps = np.abs(np.diff(cross[order])) > _INNER_BAND * w
        line_of = np.concatenate([[0], np.cumsum(gaps)])
        weight = np.bincount(line_of, weights=length[order] + 1e-9)
        chosen = int(np.argmax(weight >= _INNER_SHARE * weight.sum()))
        out[order[line_of != chosen]] = LEFT_OUT
    return out


def _check_extras(extra_features: Sequence[str]) -> None:
    if isinstance(extra_features, str):
        raise ParameterError("extra_features", extra_features, "a sequence of names, not a string")
    for extra in extra_features:
        if extra not in EXTRA_FEATURES:
            allowed = ", ".join(map(repr, EXTRA_FEATURES))
            raise ParameterError("extra_features", extra, f"one of {allowed}")


def _cluster(descriptors: NDArray[np.float64], method: str, seed: int) -> NDArray[np.int64]:
    """Labels 0/1 from k-means or spectral clustering; all zeros when two groups make no sense."""
    n = len(descriptors)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    if len(np.unique(descriptors.round(12), axis=0)) < 2:
        return np.zeros(n, dtype=np.int64)
    if n == 2:
        return np.array([0, 1], dtype=np.int64)
    from sklearn.cluster import KMeans, SpectralClustering

    # on a few dozen points scikit-learn's thread pools cost far more than the work
    # (KMeans: about 20 ms per call with 2 threads against 0.7 ms with 1)
    with single_thread(), warnings.catch_warnings():
        # small or disconnected neighbour graphs are expected here, and handled
        warnings.simplefilter("ignore")
        if method == "kmeans":
            model = KMeans(n_clusters=2, n_init=1, random_state=seed)
        else:
            model = SpectralClustering(
                n_clusters=2,
                affinity="nearest_neighbors",
                n_neighbors=min(_SPECTRAL_NEIGHBOURS, n - 1),
                assign_labels="kmeans",
                random_state=seed,
            )
        labels = model.fit_predict(descriptors)
    return np.asarray(labels, dtype=np.int64)


def _one_line(segments: NDArray[np.float64], tolerance_px: float) -> tuple[float, float] | None:
    """The line through all segments when it fits them within the tolerance (weighted RMS)."""
    line = fit_line(segments)
    if line is None:
        return None
    x = np.concatenate([segments[:, 0], segments[:, 2]])
    y = np.concatenate([segments[:, 1], segments[:, 3]])
    length = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
    w = np.concatenate([length, length]) + 1e-12
    residual = (x - (line[0] * y + line[1])) / np.hypot(1.0, line[0])  # distance to the line
    rms = float(np.sqrt((w @ (residual * residual)) / w.sum()))
    return line if rms < tolerance_px else None


def _x_at(line: tuple[float, float] | None, row: float, h: int, w: int) -> float:
    """x of ``line`` at relative row ``row``, relative to the width, minus 0.5 (NaN if none)."""
    if line is None:
        return float("nan")
    return (line[0] * row * (h - 1) + line[1]) / max(w - 1, 1) - 0.5


def _crossing_offset(
    left: tuple[float, float] | None, right: tuple[float, float] | None, w: int
) -> float:
    """x of the two lines' intersection relative to the width, minus 0.5 (NaN if none)."""
    if left is None or right is None or abs(left[0] - right[0]) <= 1e-9:
        return float("nan")
    y = (right[1] - left[1]) / (left[0] - right[0])
    return (left[0] * y + left[1]) / max(w - 1, 1) - 0.5


def feature_values(
    lines: Sequence[tuple[float, float] | None],
    extra_features: Sequence[str],
    h: int,
    w: int,
    segments: NDArray[np.float64] | None = None,
    labels: NDArray[np.int64] | None = None,
) -> NDArray[np.float64]:
    """The feature vector of two lines ``[left, right]`` (module docstring).

    ``segments`` and ``labels`` are needed only by ``"near-vanishing-point-offset"``.
    """
    nan = float("nan")
    values = [line[0] if line is not None else nan for line in lines]
    left, right = lines
    for extra in extra_features:
        if extra == "intercepts":
            values += [
                (line[0] * (h - 1) + line[1]) / max(w - 1, 1) if line is not None else nan
                for line in lines
            ]
        elif extra == "angles":
            values += [float(np.arctan(line[0])) if line is not None else nan for line in lines]
        elif extra == "vanishing-point-offset":
            values.append(_crossing_offset(left, right, w))
        elif extra == "far-offsets":
            values += [_x_at(left, FAR_ROW, h, w), _x_at(right, FAR_ROW, h, w)]
        elif extra == "road-centre":
            values += [
                0.5 * (_x_at(left, row, h, w) + _x_at(right, row, h, w))
                for row in (FAR_ROW, NEAR_ROW)
            ]
        else:  # near-vanishing-point-offset
            near_lines: list[tuple[float, float] | None] = [None, None]
            if segments is not None and labels is not None and len(segments):
                near = np.maximum(segments[:, 1], segments[:, 3]) >= NEAR_PART * (h - 1)
                near_lines = [fit_line(segments[near & (labels == g)]) for g in (0, 1)]
            values.append(_crossing_offset(near_lines[0], near_lines[1], w))
    return np.asarray(values, dtype=np.float64)
