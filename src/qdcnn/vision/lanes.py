"""Lane preprocessing: smoothing, Canny edges inside the road ROI, and Hough line segments.

Implements the road-detection steps of the paper's Algorithm 2 and the settings of
Sec. III-A (NOTES 5): greyscale, median filter (5) and Gaussian blur (5x5, sigma 0)
iterated ``smoothing_iterations`` times, Canny 50/175, the ROI polygon, and
``cv2.HoughLinesP(rho=1, theta=pi/180, threshold=8, minLineLength=2, maxLineGap=25)``.
Shadow removal (if any) happens before this stage: pass the corrected image.

The ROI is applied to the Canny output, not to the grey image, so the polygon's own
border never shows up as an edge. With ``LaneConfig.smoothing_margin`` set (default 8 px)
only the ROI's bounding box plus that margin is smoothed, which is what keeps the paper's
30 iterations near 2 ms at 320x160.

Thirty iterations of median 5 + Gaussian 5x5 behave like one Gaussian of sigma ~6 px, so
Canny's high threshold (175, on the L1 Sobel gradient) is reached only by edges of nearly
full contrast, at any frame size; on the Udacity recordings no edge survives.
:meth:`LaneConfig.udacity` keeps every other paper setting and uses 1 iteration.

Named options (not the paper's; the defaults leave the paper's stage unchanged):

- ``work_width``: the frame is resized to this width before smoothing, Canny and Hough, and
  the segments are scaled back to the frame's pixels, so apertures, Hough lengths and gaps
  are relative to the frame size (:func:`working_frame`).
- ``marks``: Canny runs on a mask of white and yellow markings
  (:func:`qdcnn.vision.marks.marking_mask`) instead of the grey frame.
- ``max_segment_angle`` and ``vp_tolerance``: segments too steep, or whose line misses the
  vanishing point, are dropped (:func:`_filter_segments`).

References
----------
.. [1] QDCNN paper, ``shared/paper/qdcnn-paper.tex``, Sec. II-A-3, Alg. 2 and Sec. III-A.
.. [2] J. Canny, "A computational approach to edge detection", IEEE TPAMI 8(6), 1986.
.. [3] J. Matas, C. Galambos, J. Kittler, "Robust detection of lines using the progressive
   probabilistic Hough transform", CVIU 78(1), 2000.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn._validation import check_input_shape
from qdcnn.config import LaneConfig
from qdcnn.errors import InputError, ParameterError
from qdcnn.vision.marks import marking_mask_u8
from qdcnn.vision.roi import polygon_mask

_DEFAULT = LaneConfig()


def _check_frame(image: NDArray[np.uint8]) -> None:
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8:
        kind = getattr(image, "dtype", type(image).__name__)
        raise InputError("image", f"expected a uint8 array, got {kind}")
    check_input_shape("image", image, "H,W,3|H,W")


def to_grey(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Return the greyscale version of an RGB uint8 frame (a 2-D frame is returned as is).

    Parameters
    ----------
    image : (H, W, 3) or (H, W) uint8 array
        RGB frame, or an already grey frame.

    Returns
    -------
    (H, W) uint8 array
    """
    _check_frame(image)
    if image.ndim == 2:
        return image
    return np.asarray(cv2.cvtColor(image, cv2.COLOR_RGB2GRAY), dtype=np.uint8)


def smooth(grey: NDArray[np.uint8], config: LaneConfig = _DEFAULT) -> NDArray[np.uint8]:
    """Median filter then Gaussian blur, repeated ``config.smoothing_iterations`` times.

    Works with two ping-pong buffers (no allocation per iteration); a colour frame is
    filtered channel by channel (OpenCV's own handling of 3-channel input).

    Parameters
    ----------
    grey : (H, W) or (H, W, 3) uint8 array
    config : LaneConfig

    Returns
    -------
    uint8 array of the same shape
        A new array; ``grey`` is not modified.
    """
    a = np.array(grey, dtype=np.uint8, copy=True, order="C")
    if config.smoothing_iterations == 0:
        return a
    return smooth_between(a, np.empty_like(a), config)


def smooth_between(
    a: NDArray[np.uint8], b: NDArray[np.uint8], config: LaneConfig = _DEFAULT
) -> NDArray[np.uint8]:
    """:func:`smooth` of ``a`` computed in the two buffers ``a`` and ``b`` (same shape,
    C-contiguous): both are overwritten, and the one holding the result is returned."""
    ksize = (config.blur_ksize, config.blur_ksize)
    for _ in range(config.smoothing_iterations):
        if config.median_ksize > 1:
            cv2.medianBlur(a, config.median_ksize, dst=b)
            a, b = b, a
        cv2.GaussianBlur(a, ksize, config.blur_sigma, dst=b)
        a, b = b, a
    return a


@lru_cache(maxsize=32)
def roi_mask(shape: tuple[int, int], polygon: tuple[tuple[float, float], ...]) -> NDArray[np.uint8]:
    """Read-only uint8 mask (0 or 255) of a relative ROI polygon on a frame of ``shape``."""
    mask = polygon_mask(shape, polygon).astype(np.uint8) * np.uint8(255)
    mask.setflags(write=False)
    return mask


@lru_cache(maxsize=32)
def _roi_window(
    shape: tuple[int, int], polygon: tuple[tuple[float, float], ...], margin: int | None
) -> tuple[slice, slice]:
    """Rows and columns of the ROI's bounding box grown by ``margin`` (whole frame if None)."""
    h, w = shape
    if margin is None:
        return slice(0, h), slice(0, w)
    ys, xs = np.nonzero(roi_mask(shape, polygon))
    if ys.size == 0:
        return slice(0, 0), slice(0, 0)
    return (
        slice(max(int(ys.min()) - margin, 0), min(int(ys.max()) + margin + 1, h)),
        slice(max(int(xs.min()) - margin, 0), min(int(xs.max()) + margin + 1, w)),
    )


def paper_roi(width: int = 640, height: int = 480) -> tuple[tuple[float, float], ...]:
    """The paper's ROI ``[(0, h), (80, 380), (380, 380), (w, h)]`` made relative to a frame size.

    The paper gives the polygon in pixels of frames whose size it does not state
    (Sec. III-A); ``width`` x ``height`` is the size assumed for them. The default,
    640x480, is :attr:`LaneConfig.ROI_PRESETS` ``["paper-640x480"]``.

    Examples
    --------
    >>> paper_roi(640, 480) == LaneConfig.ROI_PRESETS["paper-640x480"]
    True
    """
    if width < 381 or height < 381:
        raise ParameterError("width, height", (width, height), "both above 380 pixels")
    w1, h1 = width - 1, height - 1
    return ((0.0, 1.0), (80 / w1, 380 / h1), (380 / w1, 380 / h1), (1.0, 1.0))


def working_frame(image: NDArray[np.uint8], work_width: int | None) -> NDArray[np.uint8]:
    """The frame resized to ``work_width`` pixels wide (aspect kept), or as is for ``None``.

    Shrinking uses OpenCV's area interpolation (each output pixel the mean of the input
    pixels it covers), enlarging bilinear interpolation. The height is
    ``round(H * work_width / W)``, at least 1.

    Examples
    --------
    >>> working_frame(np.zeros((480, 640, 3), np.uint8), 320).shape
    (240, 320, 3)
    """
    if work_width is None or image.shape[1] == work_width:
        return image
    h, w = image.shape[:2]
    height = max(1, round(h * work_width / w))
    interpolation = cv2.INTER_AREA if work_width < w else cv2.INTER_LINEAR
    return np.asarray(cv2.resize(image, (work_width, height), interpolation=interpolation))


def lane_edges(image: NDArray[np.uint8], config: LaneConfig = _DEFAULT) -> NDArray[np.uint8]:
    """Canny edges of the smoothed frame, kept only inside the ROI polygon.

    With ``config.edge_channels == "rgb"`` the three colour channels are smoothed and
    given to ``cv2.Canny`` together; it takes at each pixel the gradient of the channel
    where its magnitude is largest, so an edge seen in any channel counts. With
    ``config.marks`` set, Canny sees the smoothed mask of white and yellow markings
    (255 on a marking, 0 elsewhere) instead. ``config.work_width`` is not applied here:
    :func:`detect_segments` resizes the frame first (:func:`working_frame`).

    Parameters
    ----------
    image : (H, W, 3) or (H, W) uint8 array
        RGB road frame (already shadow-corrected when shadow removal is used), or grey.
    config : LaneConfig
        Smoothing, Canny and ROI settings; the defaults are the paper's (ROI: see
        :class:`qdcnn.config.LaneConfig`). With ``smoothing_margin`` set, only the ROI's
        bounding box plus that margin is smoothed and searched for edges.

    Returns
    -------
    (H, W) uint8 array
        255 on edge pixels inside the ROI, 0 elsewhere.

    Examples
    --------
    >>> import numpy as np
    >>> img = np.full((160, 320, 3), 90, np.uint8)
    >>> int(lane_edges(img).max())
    0
    """
    grey = to_grey(image)
    shape = (int(grey.shape[0]), int(grey.shape[1]))
    polygon = tuple((float(x), float(y)) for x, y in config.roi)
    rows, cols = _roi_window(shape, polygon, config.smoothing_margin)
    edges = np.zeros(shape, dtype=np.uint8)
    # colour Canny (OpenCV): per pixel, the gradient of the channel where it is largest
    source = image if config.edge_channels == "rgb" and image.ndim == 3 else grey
    if config.marks != "none":
        source = image
    window = source[rows, cols]
    if window.size and config.marks != "none":
        window = marking_mask_u8(window, config, width=shape[1])
    if window.size:
        window_edges = np.asarray(
            cv2.Canny(smooth(window, config), config.canny_low, config.canny_high), dtype=np.uint8
        )
        edges[rows, cols] = window_edges & roi_mask(shape, polygon)[rows, cols]
    return edges


def _segments_from_edges(
    edges: NDArray[np.uint8],
    config: LaneConfig = _DEFAULT,
    frame_shape: tuple[int, ...] | None = None,
) -> NDArray[np.float64]:
    """Probabilistic Hough segments of an edge map, as an ``(N, 4)`` array ``x1, y1, x2, y2``.

    Each segment is oriented so that ``y1 <= y2`` (top end first; ``x1 <= x2`` on ties),
    which makes descriptors independent of the order OpenCV reports the ends in. When
    ``frame_shape`` (the ``(H, W)`` of the frame the edges were computed for, at another
    size) is given, the segments are scaled to its pixels (pixel centres map to pixel
    centres). Then :func:`_filter_segments` applies the angle and vanishing-point filters.
    """
    found = cv2.HoughLinesP(
        edges,
        config.hough_rho,
        config.hough_theta,
        config.hough_threshold,
        minLineLength=config.hough_min_line_length,
        maxLineGap=config.hough_max_line_gap,
    )
    if found is None:
        return np.empty((0, 4), dtype=np.float64)
    seg = found.reshape(-1, 4).astype(np.float64)
    shape = edges.shape[:2]
    if frame_shape is not None and tuple(frame_shape[:2]) != tuple(shape):
        kx = frame_shape[1] / shape[1]
        ky = frame_shape[0] / shape[0]
        seg = (seg + 0.5) * np.array([kx, ky, kx, ky]) - 0.5
        shape = (int(frame_shape[0]), int(frame_shape[1]))
    flip = (seg[:, 1] > seg[:, 3]) | ((seg[:, 1] == seg[:, 3]) & (seg[:, 0] > seg[:, 2]))
    seg[flip] = seg[flip][:, [2, 3, 0, 1]]
    return _filter_segments(seg, shape, config)


def _filter_segments(
    segments: NDArray[np.float64], shape: tuple[int, ...], config: LaneConfig = _DEFAULT
) -> NDArray[np.float64]:
    """Drop segments by angle and by position relative to the vanishing point.

    - ``min_segment_angle`` / ``max_segment_angle``: the angle from the horizontal, in
      degrees, must lie between them (defaults 0 and 90 keep every segment).
    - ``vp_tolerance`` (with ``vanishing_point`` ``(xv, yv)`` relative to the frame): the
      segment's lower end must lie below the vanishing point's row, and its line
      ``x = a * y + b`` must cross that row within ``vp_tolerance * W`` pixels of ``xv``.

    Parameters
    ----------
    segments : (N, 4) array
        ``x1, y1, x2, y2`` with ``y1 <= y2``, in the pixels of a frame of ``shape``.
    shape : tuple
        ``(H, W)`` of that frame.
    config : LaneConfig

    Returns
    -------
    (M, 4) array
        The kept rows, in order.
    """
    seg = segments
    if len(seg) == 0:
        return seg
    if config.min_segment_angle > 0 or config.max_segment_angle < 90:
        steep = np.degrees(np.arctan2(seg[:, 3] - seg[:, 1], np.abs(seg[:, 2] - seg[:, 0])))
        keep = (steep >= config.min_segment_angle) & (steep <= config.max_segment_angle)
        seg = seg[keep]
    if config.vp_tolerance is not None and config.vanishing_point is not None and len(seg):
        h, w = int(shape[0]), int(shape[1])
        xv = float(config.vanishing_point[0]) * (w - 1)
        yv = float(config.vanishing_point[1]) * (h - 1)
        dy = seg[:, 3] - seg[:, 1]
        flat = dy <= 1e-9
        a = (seg[:, 2] - seg[:, 0]) / np.where(flat, 1.0, dy)
        miss = np.abs(seg[:, 0] + a * (yv - seg[:, 1]) - xv)
        keep = ~flat & (seg[:, 3] > yv) & (miss <= config.vp_tolerance * w)
        seg = seg[keep]
    return seg


def detect_segments(image: NDArray[np.uint8], config: LaneConfig = _DEFAULT) -> NDArray[np.float64]:
    """Line segments of a road frame: :func:`lane_edges` followed by ``cv2.HoughLinesP``.

    Parameters
    ----------
    image : (H, W, 3) or (H, W) uint8 array
        RGB road frame (already shadow-corrected when shadow removal is used), or grey.
    config : LaneConfig

    Returns
    -------
    (N, 4) float64 array
        Rows ``x1, y1, x2, y2`` in the frame's pixels with ``y1 <= y2``; shape ``(0, 4)``
        when no segment is found. With ``config.work_width`` set, the edges and the Hough
        transform are computed at that width and the segments scaled back.
    """
    _check_frame(image)
    work = working_frame(image, config.work_width)
    return _segments_from_edges(lane_edges(work, config), config, image.shape)
