"""Fast exact decisions of the block-wise UU-dagger shadow detector (issue 22).

The detector's exact score of a block is the UU-dagger fidelity of its mean, looked up
by block sum in the joined RY state tables (:class:`~qdcnn.vision.shadows.StateLookup`),
and a block is shadow when the score reaches the threshold. For one centroid the
fidelity falls monotonically with the distance between the block mean and the centroid,
so the passing sums of each block size form one interval around the centroid:
:func:`band_bounds` finds its two ends by evaluating the detector's own score formula on a
few sums around the analytic band edges, and the decision of every block is then one
comparison of its sum with its size's interval: the decisions of the score formula itself.

:func:`row_compression` serves the median filter of the expanded block mask: the mask is
constant over each block's rows, so the rows farther than the filter radius from a
block boundary all have the same filtered row and one of them is enough.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn.quantum.uu_dagger import (
    VALUE_SCALE,
    band_halfwidth,
    overlap_fidelity,
    ry_state_table,
    value_to_angle,
)

#: Sums evaluated on either side of each analytic band edge.
_WINDOW = 3
#: Scores this close to the threshold at a window's ends leave the band to the slow path.
_MARGIN = 1e-12


@lru_cache(maxsize=4)
def joined_state_tables(
    sizes: tuple[int, ...],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The :func:`~qdcnn.quantum.uu_dagger.ry_state_table` of each block size, joined."""
    tables = [ry_state_table(n) for n in sizes]
    cos_half = np.concatenate([t[0] for t in tables])
    sin_half = np.concatenate([t[1] for t in tables])
    cos_half.setflags(write=False)
    sin_half.setflags(write=False)
    return cos_half, sin_half


@lru_cache(maxsize=8)
def _windows(sizes: tuple[int, ...], starts: tuple[int, ...]) -> tuple[NDArray[Any], ...]:
    """Per size: ``n`` (float), the last sum, the window steps (low window counting up
    towards the centroid, high window counting down towards it), the table's two ends and
    the offset of each size's table."""
    n = np.asarray(sizes, dtype=np.float64)[:, None]
    top = (VALUE_SCALE * n).astype(np.intp)[:, :, None]
    steps = np.arange(-_WINDOW, _WINDOW + 1)
    steps = np.stack([steps, -steps])  # (2, W): outer end first in both windows
    ends = np.concatenate([np.zeros_like(top[:, :, 0]), top[:, :, 0]], axis=1)  # (S, 2)
    offset = np.asarray(starts, dtype=np.intp)[:, None, None]
    out = (n, top, steps, ends, offset, np.arange(2 * len(sizes)))
    for arr in out:
        arr.setflags(write=False)
    return out


@lru_cache(maxsize=4)
def band_bounds(
    sizes: tuple[int, ...], starts: tuple[int, ...], centroid: float, threshold: float
) -> tuple[NDArray[np.intp], NDArray[np.uint64]] | None:
    """First block sum whose exact score reaches ``threshold``, per block size, and how
    many sums after it do too (all of them up to the last that does).

    A block of size ``sizes[i]`` and sum ``k`` passes exactly when
    ``0 <= k - first[i] <= width[i]`` (:data:`numpy.uint64` arithmetic makes that one
    comparison). Cached: a given or trained centroid finds its band once for all frames.
    Returns ``None`` when the two ends cannot be certified (a
    band narrower than the windows, or a score within :data:`_MARGIN` of the threshold at
    a window's end); the caller then thresholds the scores themselves.

    Each end is searched in a window of ``2 * _WINDOW + 1`` sums around the analytic
    edge ``n * (centroid -+ halfwidth)``, with the scores computed exactly as the
    detector computes them (:func:`~qdcnn.quantum.uu_dagger.overlap_fidelity` of the
    looked-up states). Read from the outer end inwards, the scores in each window must
    not fall, the outer end must fail by more than the margin (or be the table's end)
    and the inner end pass by more than it. The fidelity is unimodal in the block mean,
    so every sum between the two inner ends passes, every sum beyond the outer ends
    fails, and in the windows the decisions change once.
    """
    n, top, steps, ends, offset, rows = _windows(sizes, starts)
    half = band_halfwidth(threshold) * (VALUE_SCALE / np.pi)
    edges = np.floor(n * np.array([centroid - half, centroid + half]))
    edges[:, 1] += 1.0  # ceil of the upper edge, give or take a sum the window covers
    ks = edges.astype(np.intp)[:, :, None] + steps
    np.maximum(ks, 0, out=ks)
    np.minimum(ks, top, out=ks)
    cos_half, sin_half = joined_state_tables(sizes)
    index = ks + offset
    scores = overlap_fidelity(
        float(value_to_angle(centroid)), cos_half.take(index), sin_half.take(index)
    )
    rising = scores[:, :, 1:] >= scores[:, :, :-1]
    outer_fails = (scores[:, :, 0] < threshold - _MARGIN) | (ks[:, :, 0] == ends)
    if not (
        rising.all()
        and outer_fails.all()
        and (scores[:, :, -1] > threshold + _MARGIN).all()
        and (ks[:, 0, -1] < ks[:, 1, -1]).all()
    ):
        return None
    first = (scores >= threshold).argmax(axis=2)  # first passing sum from the outer end
    low, high = ks.reshape(rows.size, -1)[rows, first.ravel()].reshape(len(sizes), 2).T
    low = np.ascontiguousarray(low)  # a column of a (sizes, 2) array: the kernels read it faster
    low.setflags(write=False)
    width = (high - low).astype(np.uint64)
    width.setflags(write=False)
    return low, width


def row_compression(
    row_of: NDArray[np.intp], ksize: int
) -> tuple[NDArray[np.intp], NDArray[np.intp]] | None:
    """Rows of a block-constant mask that a ``ksize`` median filter needs, and where each
    full row's filtered row is; ``None`` if no block is taller than ``ksize``.

    With radius ``r = ksize // 2``, a block of ``h > 2r + 1`` rows keeps its first ``r``
    rows, one middle row and its last ``r`` rows. Every row within ``r`` of a boundary
    keeps its window of rows (its neighbours' rows it sees are kept too, replicated
    borders included), and every other row's window lies inside its block, as the kept
    middle row's does. Returns ``(block of each kept row, kept row of each full row)``.
    """
    radius = ksize // 2
    keep = 2 * radius + 1
    n = row_of.size
    starts = np.flatnonzero(np.concatenate([[True], row_of[1:] != row_of[:-1]]))
    heights = np.diff(np.append(starts, n))
    if heights.max() <= keep:
        return None
    kept = np.minimum(heights, keep)
    kept_starts = np.concatenate([[0], np.cumsum(kept)[:-1]])
    pos = np.arange(n) - np.repeat(starts, heights)  # row within its block
    height = np.repeat(heights, heights)
    inner = np.where(pos >= height - radius, np.minimum(height, keep) - (height - pos), radius)
    row_map = np.repeat(kept_starts, heights) + np.where(pos < radius, pos, inner)
    kept_block = np.repeat(row_of[starts], kept)
    kept_block.setflags(write=False)
    row_map.setflags(write=False)
    return kept_block, row_map
