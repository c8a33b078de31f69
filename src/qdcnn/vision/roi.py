"""Regions of interest given as polygons relative to the frame size."""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import NDArray


def polygon_pixels(
    shape: tuple[int, ...], polygon: Sequence[tuple[float, float]]
) -> NDArray[np.int32]:
    """Convert a relative polygon ``[(x / W, y / H), ...]`` to pixel vertices for ``shape``."""
    h, w = shape[:2]
    rel = np.asarray(polygon, dtype=np.float64)
    return np.round(rel * [w - 1, h - 1]).astype(np.int32)


def polygon_mask(
    shape: tuple[int, ...], polygon: Sequence[tuple[float, float]]
) -> NDArray[np.bool_]:
    """Boolean mask of a relative polygon on a frame of ``shape`` (``(H, W)`` or ``(H, W, C)``).

    Examples
    --------
    >>> m = polygon_mask((4, 4), [(0, 0), (1, 0), (1, 1), (0, 1)])
    >>> bool(m.all())
    True
    """
    mask = np.zeros(shape[:2], dtype=np.uint8)
    cv2.fillPoly(mask, [polygon_pixels(shape, polygon)], 1)
    return mask.astype(bool)


def roi_rows(polygon: Sequence[tuple[float, float]]) -> tuple[float, float]:
    """Top and bottom row of a relative polygon, as fractions of the height.

    Examples
    --------
    >>> roi_rows([(0.0, 1.0), (0.3, 0.45), (0.7, 0.45), (1.0, 1.0)])
    (0.45, 1.0)
    """
    ys = [float(y) for _, y in polygon]
    return min(ys), max(ys)
