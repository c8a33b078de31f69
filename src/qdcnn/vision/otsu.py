"""Otsu's two-class threshold of float values, as :func:`skimage.filters.threshold_otsu`.

The per-image shadow calibration splits a few thousand block means with Otsu's method
on 256 bins spanning their range. scikit-image computes it through :func:`numpy.histogram`
with a generic bin search and several layers of checks, which cost about as much as the
rest of the detector. :func:`otsu_threshold` repeats the same arithmetic (numpy's uniform
bin edges and index correction, scikit-image's float32 counts) in a handful of array
operations, so it returns the identical threshold (tested against scikit-image).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray


@lru_cache(maxsize=4)
def _bin_positions(nbins: int) -> NDArray[np.float64]:
    positions = np.arange(nbins + 1, dtype=np.float64)
    positions.setflags(write=False)
    return positions


def uniform_histogram(
    values: NDArray[np.float64], nbins: int, first: float, last: float
) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Counts and edges of ``np.histogram(values, nbins, range=(first, last))``.

    ``values`` must lie in ``[first, last]`` with ``first < last`` (the case of a
    histogram over the values' own range). The edges are :func:`numpy.linspace`'s and
    each value falls in the bin ``i`` with ``edges[i] <= value < edges[i + 1]`` (the
    last bin closed), as numpy assigns it: a scaled position, within one bin of the
    answer, then one correction step against the edges each way.
    """
    step = (last - first) / nbins
    edges = _bin_positions(nbins) * step
    edges += first
    edges[-1] = last
    upper = np.append(edges[1:-1], np.inf)  # the last bin is closed
    index = np.subtract(values, first)
    index *= nbins / (last - first)
    bins = index.astype(np.intp)
    np.minimum(bins, nbins - 1, out=bins)
    bins -= values < edges.take(bins)
    bins += values >= upper.take(bins)
    return np.bincount(bins, minlength=nbins), edges


def otsu_threshold(
    values: NDArray[np.float64], nbins: int = 256, span: tuple[float, float] | None = None
) -> float:
    """Otsu's threshold of 1-D float64 ``values`` on ``nbins`` bins over their range.

    Equal to ``skimage.filters.threshold_otsu(values, nbins)`` (a bin centre; values at
    or below it form the lower class). Constant input returns its value. ``span`` is
    ``(values.min(), values.max())`` when the caller has it already.
    """
    first, last = span if span is not None else (float(values.min()), float(values.max()))
    if first == last:
        return first
    hist, edges = uniform_histogram(values, nbins, first, last)
    counts = hist.astype(np.float32)
    centres = (edges[:-1] + edges[1:]) / 2.0
    weight1 = counts.cumsum()
    weight2 = counts[::-1].cumsum()[::-1]
    moment = counts * centres
    mean1 = moment.cumsum() / weight1
    mean2 = (moment[::-1].cumsum() / weight2[::-1])[::-1]
    variance12 = weight1[:-1] * weight2[1:] * (mean1[:-1] - mean2[1:]) ** 2
    return float(centres[int(np.argmax(variance12))])
