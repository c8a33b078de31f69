"""Compiled step of road-fill shadow removal (issue 22), with Numba.

Before a region's shadow pixels are filled, its pixels are split into shadow and lit
ones and the lit ones' levels are counted per channel (their medians are the fill). The
NumPy path builds two masks and runs one masked OpenCV histogram per channel, four
passes over the region's rows; :func:`lit_levels` does it in one. Counts are integers:
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
    which are written to ``target`` (bool, ``(H, W)``)."""
    h, w, channels = pixels.shape
    counts = np.zeros((channels, 256), np.intp)
    shaded = 0
    for r in range(h):
        for c in range(w):
            inside = region[r, c] and shadow[r, c]
            target[r, c] = inside
            if inside:
                shaded += 1
            elif region[r, c]:
                for k in range(channels):
                    counts[k, pixels[r, c, k]] += 1
    return counts, shaded
