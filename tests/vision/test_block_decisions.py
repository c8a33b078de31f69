"""The fast exact decisions of the shadow detector against the scores they replace."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from qdcnn.quantum.uu_dagger import overlap_fidelity, value_to_angle
from qdcnn.vision.block_decisions import band_bounds, joined_state_tables, row_compression
from qdcnn.vision.shadows import binary_median


def _starts(sizes: tuple[int, ...]) -> tuple[int, ...]:
    return tuple(int(s) for s in np.cumsum([0] + [255 * n + 1 for n in sizes[:-1]]))


def _all_decisions(sizes: tuple[int, ...], centroid: float, threshold: float) -> np.ndarray:
    """Every entry of the joined tables thresholded, as the detector's scores are."""
    cos_half, sin_half = joined_state_tables(sizes)
    scores = overlap_fidelity(float(value_to_angle(centroid)), cos_half, sin_half)
    return scores >= threshold


def _decisions_from_bounds(
    sizes: tuple[int, ...], bounds: tuple[np.ndarray, np.ndarray]
) -> np.ndarray:
    low, width = bounds
    parts = []
    for n, lo, w in zip(sizes, low, width, strict=True):
        k = np.arange(255 * n + 1)
        parts.append((k >= lo) & (k <= lo + int(w)))
    return np.concatenate(parts)


@settings(max_examples=150, deadline=None)
@given(
    sizes=st.lists(st.integers(1, 300), min_size=1, max_size=4, unique=True).map(
        lambda s: tuple(sorted(s))
    ),
    centroid=st.floats(0.0, 255.0),
    threshold=st.one_of(st.floats(0.0, 1.0), st.sampled_from([0.75, 0.9, 0.97, 0.999])),
)
def test_band_bounds_give_the_decisions_of_every_score(
    sizes: tuple[int, ...], centroid: float, threshold: float
) -> None:
    bounds = band_bounds.__wrapped__(sizes, _starts(sizes), centroid, threshold)
    if bounds is None:  # not certified: the detector thresholds the scores instead
        return
    np.testing.assert_array_equal(
        _decisions_from_bounds(sizes, bounds), _all_decisions(sizes, centroid, threshold)
    )


def test_band_bounds_answer_for_the_detectors_settings() -> None:
    """The paper's thresholds and the block sizes of 320x160 and 1280x720 frames are
    certified for every centroid on a fine grid (the fast path is the one taken)."""
    for sizes in ((16, 32), (128, 160, 192, 240)):
        for threshold in (0.75, 0.97):
            for centroid in np.linspace(0.0, 255.0, 97):
                bounds = band_bounds.__wrapped__(sizes, _starts(sizes), float(centroid), threshold)
                assert bounds is not None
                np.testing.assert_array_equal(
                    _decisions_from_bounds(sizes, bounds),
                    _all_decisions(sizes, float(centroid), threshold),
                )


def test_band_bounds_decline_a_band_narrower_than_their_windows() -> None:
    assert band_bounds.__wrapped__((16,), (0,), 100.0, 1.0) is None


@st.composite
def _block_rows(draw: st.DrawFn) -> np.ndarray:
    heights = draw(st.lists(st.integers(1, 14), min_size=1, max_size=12))
    return np.repeat(np.arange(len(heights)), heights).astype(np.intp)


@settings(max_examples=150, deadline=None)
@given(row_of=_block_rows(), ksize=st.sampled_from([3, 5, 7]), seed=st.integers(0, 2**32 - 1))
def test_row_compressed_median_equals_the_full_median(
    row_of: np.ndarray, ksize: int, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    blocks = rng.random((int(row_of[-1]) + 1, 6)) < 0.5
    col_of = np.repeat(np.arange(6), rng.integers(1, 5, 6))
    full = blocks.take(col_of, axis=1).take(row_of, axis=0).astype(np.uint8)
    expected = cv2.medianBlur(full, ksize)
    rows = row_compression(row_of, ksize)
    if rows is None:
        assert np.bincount(row_of).max() <= ksize
        return
    kept_block, row_map = rows
    kept = blocks.take(col_of, axis=1).take(kept_block, axis=0).astype(np.uint8)
    np.testing.assert_array_equal(binary_median(kept, ksize).take(row_map, axis=0), expected)


def test_row_compression_keeps_five_rows_of_tall_blocks() -> None:
    row_of = np.repeat(np.arange(3), [12, 3, 8])
    rows = row_compression(row_of, 5)
    assert rows is not None
    kept_block, row_map = rows
    np.testing.assert_array_equal(kept_block, [0] * 5 + [1] * 3 + [2] * 5)
    assert row_map.tolist() == [0, 1] + [2] * 8 + [3, 4] + [5, 6, 7] + [
        8,
        9,
        10,
        10,
        10,
        10,
        11,
        12,
    ]


@pytest.mark.parametrize("ksize", [3, 5])
def test_row_compression_is_none_when_no_block_is_taller_than_the_filter(ksize: int) -> None:
    assert row_compression(np.repeat(np.arange(4), ksize), ksize) is None
