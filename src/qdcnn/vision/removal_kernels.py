"""Compiled step of road-fill shadow removal (issue 22), with Numba.

Before a region's shadow pixels are filled, its pixels are split into shadow and lit
ones and the lit ones' levels are counted per channel (their medians are the fill). The
NumPy path builds two masks and runs one masked OpenCV histogram per channel, four
passes over the region's rows; :func:`lit_levels` does it in two. Counts are integers:
the results are the NumPy path's exactly (``tests/vision/test_removal_kernels.py``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, boundscheck=False)
def lit_levels(pixels: Any, region: Any, shadow: Any, target: Any) -> Any:
    """Level counts ``(C, 256)`` of the lit pixels (in ``region``, not in ``shadow``) per
    channel of ``pixels`` ``(H, W, C)``, and the number of the region's shadow pixels,
    which are written to ``target`` (bool, ``(H, W)``).

    Two passes: the shadow pixels without a branch (vector code), then the counts, into
    four histograms per channel by column modulo 4, summed at the end. A road's lit pixels
    repeat a few levels, and one histogram would make each count wait on the one before
    (251-279 -> 184-207 us on the 279-row band of a 640x480 frame, in turns in one
    process). The masks are bool arrays."""
    h, w, channels = pixels.shape
    shaded = 0
    for r in range(h):
        for c in range(w):
            inside = region[r, c] & shadow[r, c]
            target[r, c] = inside
            shaded += inside
    ways = np.zeros((4 * channels, 256), np.intp)
    for r in range(h):
        for c in range(w):
            if region[r, c] and not target[r, c]:
                way = (c & 3) * channels
                for k in range(channels):
                    ways[way + k, pixels[r, c, k]] += 1
    counts = np.zeros((channels, 256), np.intp)
    for way in range(4):
        counts += ways[way * channels : (way + 1) * channels]
    return counts, shaded


@njit(cache=True, nogil=True, boundscheck=False)
def fill_where(values: Any, where: Any, value: Any) -> None:
    """``values[where] = value`` in place (2-D ``uint8``), as a select per pixel the
    compiler vectorises: about 6 us on the 279 x 640 band of a 640x480 frame, against
    70 us for ``np.copyto(..., where=...)``."""
    h, w = values.shape
    for r in range(h):
        row, marks = values[r], where[r]
        for c in range(w):
            row[c] = value if marks[c] else row[c]
