"""Overlays a person can check: lane segments, fitted lines and direction; shadow masks.

Colours follow the paper's Fig. 4 (two groups in orange and blue). All drawing is done
with OpenCV on a copy of the RGB frame; nothing here reads or writes files.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn.config import LaneConfig
from qdcnn.errors import InputError, ParameterError
from qdcnn.vision.camera import CameraGeometry
from qdcnn.vision.grouping import LaneFeatures
from qdcnn.vision.roi import polygon_pixels

GROUP_COLOURS: tuple[tuple[int, int, int], tuple[int, int, int]] = ((255, 140, 0), (30, 120, 255))
_LEFT_OUT_COLOUR = (150, 150, 150)  # segments in neither line (grouping's inner_lines)
LINE_COLOURS: tuple[tuple[int, int, int], tuple[int, int, int]] = ((255, 210, 0), (0, 220, 255))
MIDDLE_COLOUR = (0, 230, 0)
ROI_COLOUR = (255, 255, 255)
TEXT_COLOUR = (255, 255, 0)
CAMERA_COLOUR = (255, 0, 255)  # horizon, vanishing point and hood line of a CameraGeometry

_Point = Callable[[float, float], tuple[int, int]]  # frame pixel to canvas pixel


def draw_lane_overlay(
    image: NDArray[np.uint8],
    segments: NDArray[np.float64],
    features: LaneFeatures,
    direction: str | None = None,
    *,
    roi: Sequence[tuple[float, float]] | None = LaneConfig().roi,
    scale: int = 1,
    columns: tuple[int, int] = (0, 1),
    camera: CameraGeometry | None = None,
) -> NDArray[np.uint8]:
    """Draw the lane stage's result on a copy of the frame.

    Shows the ROI outline (white), the Hough segments coloured by group (left orange,
    right blue), each group's fitted line ``x = a * y + b`` over the ROI's rows (yellow,
    cyan), for image-split the vertical split line (thin green) and the centre line
    between the two fitted lines (green), and a caption: method, status, the classifier's
    two inputs (``columns`` of ``features.features``; the paper's two slopes by default)
    and ``direction`` when given.

    Parameters
    ----------
    image : (H, W, 3) or (H, W) uint8 array
        The frame the segments come from (RGB, or grey).
    segments : (N, 4) array
        ``x1, y1, x2, y2`` per segment, in the order of ``features.labels``.
    features : LaneFeatures
        Result of :func:`qdcnn.vision.grouping.group_segments` for these segments.
    direction : str, optional
        Predicted direction to print (e.g. ``"left"``).
    roi : sequence of (x, y), optional
        Relative ROI polygon to outline; None draws none.
    scale : int
        Integer upscaling of the output (1 to 8) so small frames stay legible.
    columns : (int, int)
        Entries of ``features.features`` the caption shows, by name (the feature mode's
        columns, :func:`qdcnn.vision.grouping.mode_columns`).
    camera : CameraGeometry, optional
        What ``--lanes auto`` chose for the recording: its horizon (dashed magenta), its
        vanishing point (a magenta cross) and the hood's top (thin magenta), and a caption
        line saying whether the horizon was estimated or the preset's.

    Returns
    -------
    (H * scale, W * scale, 3) uint8 RGB array
    """
    canvas = _rgb_copy(image)
    if isinstance(scale, bool) or not isinstance(scale, int) or not 1 <= scale <= 8:
        raise ParameterError("scale", scale, "an integer in [1, 8]")
    seg = np.asarray(segments, dtype=np.float64).reshape(-1, 4)
    if len(seg) != len(features.labels):
        raise InputError(
            "segments", f"{len(seg)} segments but {len(features.labels)} labels in features"
        )
    h, w = canvas.shape[:2]
    canvas = _upscaled(canvas, scale)
    thin, pt = scale, _block_centre(scale)
    rows = _draw_roi(canvas, roi, (h, w), pt, thin)
    if features.method == "image-split":
        xc = 0.5 * (w - 1)
        _dashed(canvas, pt(xc, rows[0]), pt(xc, rows[1]), MIDDLE_COLOUR, thin, 4 * scale)
    if camera is not None:
        _draw_camera(canvas, camera, (h, w), pt, thin, scale)
    for (x1, y1, x2, y2), group in zip(seg, features.labels, strict=True):
        colour = GROUP_COLOURS[int(group)] if group in (0, 1) else _LEFT_OUT_COLOUR
        cv2.line(canvas, pt(x1, y1), pt(x2, y2), colour, 2 * scale, cv2.LINE_AA)
    _draw_fits(canvas, features, rows, pt, thin)
    _draw_captions(canvas, features, columns, direction, camera, h, pt, scale)
    return canvas


def _block_centre(scale: int) -> _Point:
    """Frame pixel ``(x, y)`` to the canvas upscaled ``scale`` times."""

    def pt(x: float, y: float) -> tuple[int, int]:
        # pixel centres map to the centre of the upscaled block
        return round((x + 0.5) * scale - 0.5), round((y + 0.5) * scale - 0.5)

    return pt


def _upscaled(canvas: NDArray[np.uint8], scale: int) -> NDArray[np.uint8]:
    if scale == 1:
        return canvas
    h, w = canvas.shape[:2]
    return np.asarray(
        cv2.resize(canvas, (w * scale, h * scale), interpolation=cv2.INTER_NEAREST),
        dtype=np.uint8,
    )


def _draw_roi(
    canvas: NDArray[np.uint8],
    roi: Sequence[tuple[float, float]] | None,
    shape: tuple[int, int],
    pt: _Point,
    thin: int,
) -> tuple[float, float]:
    """Outline the ROI (if any); return its top and bottom rows (the frame's without one)."""
    h, w = shape
    if roi is None:
        return 0.0, float(h - 1)
    poly = polygon_pixels((h, w), roi).astype(np.float64)
    outline = np.array([pt(x, y) for x, y in poly], dtype=np.int32)
    cv2.polylines(canvas, [outline], True, ROI_COLOUR, thin, cv2.LINE_AA)
    return float(poly[:, 1].min()), float(poly[:, 1].max())


def _draw_fits(
    canvas: NDArray[np.uint8],
    features: LaneFeatures,
    rows: tuple[float, float],
    pt: _Point,
    thin: int,
) -> None:
    """Each group's fitted line ``x = a * y + b`` over ``rows`` (and image-split's centre)."""
    y_top, y_bottom = rows
    fits = list(zip(features.lines, LINE_COLOURS, strict=False))
    if features.method == "image-split":
        fits.append((features.middle_line, MIDDLE_COLOUR))
    for line, colour in fits:
        if line is None:
            continue
        a, b = line
        cv2.line(
            canvas,
            pt(a * y_top + b, y_top),
            pt(a * y_bottom + b, y_bottom),
            colour,
            thin,
            cv2.LINE_AA,
        )


def _draw_captions(
    canvas: NDArray[np.uint8],
    features: LaneFeatures,
    columns: tuple[int, int],
    direction: str | None,
    camera: CameraGeometry | None,
    h: int,
    pt: _Point,
    scale: int,
) -> None:
    """Method and status, the classifier's two inputs, the camera's horizon and the
    direction."""
    if len(columns) != 2 or not all(0 <= c < len(features.features) for c in columns):
        raise ParameterError("columns", columns, f"two indices below {len(features.features)}")
    names = features.feature_names
    inputs = "  ".join(
        (names[c] if c < len(names) else f"feature {c}")
        + (" -" if np.isnan(features.features[c]) else f" {features.features[c]:+.2f}")
        for c in columns
    )
    font_scale = 0.33 * scale
    thickness = max(1, scale // 2)
    captions = [(f"{features.method} {features.status}", 10), (inputs, 20)]
    if camera is not None:
        origin = "estimated" if camera.source == "estimated" else "preset"
        captions.append((f"horizon {camera.horizon:.0%} ({origin})", h - 4))
    for text, row in captions:
        # long feature names shrink to the frame's width rather than run off it
        width = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, font_scale, thickness)[0][0]
        fit = min(font_scale, font_scale * (canvas.shape[1] - 6 * scale) / max(width, 1))
        cv2.putText(
            canvas,
            text,
            pt(3, row),
            cv2.FONT_HERSHEY_SIMPLEX,
            fit,
            TEXT_COLOUR,
            thickness,
            cv2.LINE_AA,
        )
    if direction is not None:
        cv2.putText(
            canvas,
            str(direction),
            pt(3, 34),
            cv2.FONT_HERSHEY_SIMPLEX,
            1.4 * font_scale,
            TEXT_COLOUR,
            max(1, scale),
            cv2.LINE_AA,
        )


def _draw_camera(
    canvas: NDArray[np.uint8],
    camera: CameraGeometry,
    shape: tuple[int, int],
    pt: _Point,
    thin: int,
    scale: int,
) -> None:
    h, w = shape
    y = camera.horizon * (h - 1)
    _dashed(canvas, pt(0, y), pt(w - 1, y), CAMERA_COLOUR, thin, 6 * scale)
    xv, yv = camera.vanishing_point[0] * (w - 1), camera.vanishing_point[1] * (h - 1)
    arm = max(3.0, 0.02 * w)
    cv2.line(canvas, pt(xv - arm, yv), pt(xv + arm, yv), CAMERA_COLOUR, 2 * thin, cv2.LINE_AA)
    cv2.line(canvas, pt(xv, yv - arm), pt(xv, yv + arm), CAMERA_COLOUR, 2 * thin, cv2.LINE_AA)
    if camera.hood_rows is not None:
        xs = np.linspace(0, w - 1, len(camera.hood_rows))
        pts = np.array([pt(x, r * (h - 1)) for x, r in zip(xs, camera.hood_rows, strict=True)])
        cv2.polylines(canvas, [pts.astype(np.int32)], False, CAMERA_COLOUR, thin, cv2.LINE_AA)


def draw_shadow_overlay(
    image: NDArray[np.uint8],
    mask: NDArray[np.bool_],
    color: tuple[int, int, int] = (255, 0, 255),
    alpha: float = 0.45,
) -> NDArray[np.uint8]:
    """Tint the shadow pixels of a frame: ``out = (1 - alpha) * image + alpha * color`` on the mask.

    Parameters
    ----------
    image : (H, W, 3) or (H, W) uint8 array
        RGB (or grey) frame.
    mask : (H, W) bool array
        True on shadow pixels.
    color : (r, g, b)
        Tint colour (default magenta).
    alpha : float
        Opacity of the tint in [0, 1].

    Returns
    -------
    (H, W, 3) uint8 RGB array
        Pixels outside the mask are unchanged.

    Examples
    --------
    >>> img = np.zeros((2, 2, 3), np.uint8)
    >>> m = np.array([[True, False], [False, False]])
    >>> draw_shadow_overlay(img, m, (200, 0, 100), 0.5)[0, 0].tolist()
    [100, 0, 50]
    """
    canvas = _rgb_copy(image)
    mask = np.asarray(mask)
    if mask.dtype != np.bool_ or mask.shape != canvas.shape[:2]:
        raise InputError(
            "mask",
            f"expected a bool array of shape {canvas.shape[:2]}, got {mask.dtype} {mask.shape}",
        )
    if not (isinstance(alpha, int | float) and 0.0 <= alpha <= 1.0):
        raise ParameterError("alpha", alpha, "a number in [0, 1]")
    if len(color) != 3 or not all(0 <= int(c) <= 255 for c in color):
        raise ParameterError("color", color, "three integers in [0, 255]")
    tint = np.asarray(color, dtype=np.float64)
    blended = (1.0 - alpha) * canvas[mask].astype(np.float64) + alpha * tint
    canvas[mask] = np.clip(np.round(blended), 0, 255).astype(np.uint8)
    return canvas


def _rgb_copy(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8:
        kind = getattr(image, "dtype", type(image).__name__)
        raise InputError("image", f"expected a uint8 array, got {kind}")
    if image.ndim == 2:
        return np.asarray(cv2.cvtColor(image, cv2.COLOR_GRAY2RGB), dtype=np.uint8)
    if image.ndim == 3 and image.shape[2] == 3:
        return np.ascontiguousarray(image).copy()
    raise InputError("image", f"expected shape (H, W, 3) or (H, W), got {image.shape}")


def _dashed(
    canvas: NDArray[np.uint8],
    start: tuple[int, int],
    end: tuple[int, int],
    colour: tuple[int, int, int],
    thickness: int,
    dash: int,
) -> None:
    length = max(float(np.hypot(end[0] - start[0], end[1] - start[1])), 1.0)
    for i in range(int(length // (2 * dash)) + 1):
        t0, t1 = 2 * i * dash / length, min((2 * i + 1) * dash / length, 1.0)
        if t0 >= 1.0:
            break
        p0 = (int(start[0] + t0 * (end[0] - start[0])), int(start[1] + t0 * (end[1] - start[1])))
        p1 = (int(start[0] + t1 * (end[0] - start[0])), int(start[1] + t1 * (end[1] - start[1])))
        cv2.line(canvas, p0, p1, colour, thickness)
