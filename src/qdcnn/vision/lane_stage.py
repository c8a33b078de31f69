"""Shadow removal and lane segments of one frame on reused buffers: the per-frame fast path.

:func:`lane_segments` returns exactly what
``detect_segments(remove_shadows(image, mask, region), config)`` returns (``region`` the
lane ROI's mask, :func:`qdcnn.vision.lanes.detect_segments`,
:func:`qdcnn.vision.removal.remove_shadows` with ``"road-fill"``), without building the
corrected frame. Canny sees the grey frame, and a road-filled pixel's grey value is the
grey value of the fill colour, so the fill is applied to the grey ROI window alone: the
colour frame is neither copied nor filled, and only the ROI window is converted to grey.

Everything that depends only on the frame size and the ROI (the window, the band of
rows the ROI spans, the ROI masks) is computed once per size, and the grey window, the
smoothing buffers, the Canny output and the edge map are reused from frame to frame
(one set per thread, so concurrent callers do not share them). Settings the fast path
does not cover (colour or marking edges, a working width other than the frame's) take
the reference path.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn.config import LaneConfig
from qdcnn.errors import InputError
from qdcnn.vision.lanes import (
    _check_frame,
    _roi_window,
    _segments_from_edges,
    detect_segments,
    smooth_between,
)
from qdcnn.vision.metrics import as_shadow_mask
from qdcnn.vision.removal import fill_where, lit_medians, remove_shadows
from qdcnn.vision.roi import polygon_mask

#: Plans kept per thread (one per frame size and ROI); older ones are dropped beyond it.
_MAX_PLANS = 8
_local = threading.local()


@dataclass
class _Plan:
    """What one frame size and ROI need, computed once, and the buffers reused per frame."""

    rows: slice  # the ROI window (bounding box plus the smoothing margin)
    cols: slice
    band: slice  # the rows the ROI spans (where shadow removal can change pixels)
    band_in_window: slice  # the same rows counted from the window's first row
    region: NDArray[np.bool_]  # the ROI mask on the band's rows
    roi: NDArray[np.uint8]  # the ROI mask (0 or 255) on the window
    edges: NDArray[np.uint8]  # the frame's edge map; zero outside the window, always
    grey: NDArray[np.uint8]  # the window, grey
    spare: NDArray[np.uint8]  # second smoothing buffer
    canny: NDArray[np.uint8]
    target: NDArray[np.bool_]  # shadow pixels of the ROI on the band


def _plan(shape: tuple[int, int], config: LaneConfig) -> _Plan:
    polygon = tuple((float(x), float(y)) for x, y in config.roi)
    key = (shape, polygon, config.smoothing_margin)
    plans: dict[tuple[object, ...], _Plan] = getattr(_local, "plans", None) or {}
    _local.plans = plans
    plan = plans.get(key)
    if plan is None:
        if len(plans) >= _MAX_PLANS:
            plans.clear()
        plan = plans[key] = _new_plan(shape, polygon, config.smoothing_margin)
    return plan


def _new_plan(
    shape: tuple[int, int], polygon: tuple[tuple[float, float], ...], margin: int | None
) -> _Plan:
    rows, cols = _roi_window(shape, polygon, margin)
    region = polygon_mask(shape, polygon)
    # the ROI's bounding rows, as remove_shadows finds them
    _, y, _, h = cv2.boundingRect(region.view(np.uint8))
    band = slice(y, y + h)
    window = np.zeros(shape, dtype=np.uint8)[rows, cols].shape
    start = rows.start if h else 0
    return _Plan(
        rows=rows,
        cols=cols,
        band=band,
        band_in_window=slice(y - start, y - start + h),
        region=np.ascontiguousarray(region[band]),
        roi=np.ascontiguousarray(region[rows, cols].astype(np.uint8) * np.uint8(255)),
        edges=np.zeros(shape, dtype=np.uint8),
        grey=np.empty(window, dtype=np.uint8),
        spare=np.empty(window, dtype=np.uint8),
        canny=np.empty(window, dtype=np.uint8),
        target=np.empty((h, shape[1]), dtype=bool),
    )


def fast_path_applies(config: LaneConfig) -> bool:
    """Whether :func:`lane_segments` takes the fast path for these settings (grey Canny
    on the frame at its own size)."""
    return config.marks == "none" and config.edge_channels == "grey"


def lane_segments(
    image: NDArray[np.uint8], config: LaneConfig, shadow_mask: NDArray[np.bool_] | None = None
) -> NDArray[np.float64]:
    """Hough segments of ``image`` after road-fill shadow removal inside the ROI.

    Equal to :func:`~qdcnn.vision.lanes.detect_segments` of
    ``remove_shadows(image, shadow_mask, polygon_mask(image.shape, config.roi))`` (of
    ``image`` itself when ``shadow_mask`` is None), computed as the module docstring says.

    Parameters
    ----------
    image : (H, W, 3) or (H, W) uint8 array
    config : LaneConfig
    shadow_mask : (H, W) bool array, optional
        The frame's shadow mask (:func:`qdcnn.vision.shadows.detect_shadows_uu`).
    """
    _check_frame(image)
    shape = (int(image.shape[0]), int(image.shape[1]))
    if shadow_mask is not None:
        shadow_mask = as_shadow_mask(shadow_mask, source="shadow_mask")
        if shadow_mask.shape != shape:
            raise InputError(
                "shadow_mask", f"mask shape {shadow_mask.shape} differs from image shape {shape}"
            )
    work = config.work_width
    if not fast_path_applies(config) or (work is not None and work != shape[1]):
        corrected = image
        if shadow_mask is not None:
            corrected = remove_shadows(image, shadow_mask, polygon_mask(shape, config.roi))
        return detect_segments(corrected, config)
    plan = _plan(shape, config)
    if plan.grey.size:
        _grey_window(image, shadow_mask, plan)
        smoothed = smooth_between(plan.grey, plan.spare, config)
        cv2.Canny(smoothed, config.canny_low, config.canny_high, edges=plan.canny)
        np.bitwise_and(plan.canny, plan.roi, out=plan.edges[plan.rows, plan.cols])
    return _segments_from_edges(plan.edges, config, image.shape)


def _grey_window(
    image: NDArray[np.uint8], shadow_mask: NDArray[np.bool_] | None, plan: _Plan
) -> None:
    """``plan.grey``: the grey ROI window of the frame after road-fill shadow removal."""
    window = image[plan.rows, plan.cols]
    if image.ndim == 3:
        cv2.cvtColor(window, cv2.COLOR_RGB2GRAY, dst=plan.grey)
    else:
        np.copyto(plan.grey, window)
    if shadow_mask is None or plan.region.size == 0:
        return
    target = plan.target
    pixels = image[plan.band].reshape(target.shape[0], target.shape[1], -1)
    medians = lit_medians(pixels, plan.region, shadow_mask[plan.band], target)
    if medians is None:
        return
    value = np.rint(medians).astype(np.uint8)
    if image.ndim == 3:
        fill = cv2.cvtColor(value.reshape(1, 1, 3), cv2.COLOR_RGB2GRAY)[0, 0]
    else:
        fill = value[0]
    fill_where(plan.grey[plan.band_in_window], target[:, plan.cols], fill)
