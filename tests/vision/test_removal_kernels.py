"""The compiled split of a region into shadow and lit pixels equals the NumPy path."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from qdcnn.errors import InputError, ParameterError
from qdcnn.vision.compiled import KERNELS_VARIABLE, compiled
from qdcnn.vision.removal import channel_medians, fill_where, lit_medians, remove_shadows

pytestmark = pytest.mark.skipif(
    compiled("removal_kernels") is None, reason="numba is not installed"
)


@st.composite
def _regions(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    h, w = draw(st.integers(1, 40)), draw(st.integers(1, 40))
    channels = draw(st.sampled_from([1, 3]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    pixels = rng.integers(0, 256, (h, w, channels), dtype=np.uint8)
    region = rng.random((h, w)) < draw(st.sampled_from([0.0, 0.3, 1.0]))
    shadow = rng.random((h, w)) < draw(st.sampled_from([0.0, 0.5, 1.0]))
    return pixels, region, shadow


@settings(max_examples=150, deadline=None)
@given(case=_regions())
def test_lit_medians_equal_the_numpy_path_and_the_gathered_medians(
    case: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    pixels, region, shadow = case
    target = np.ones(region.shape, bool)
    got = lit_medians(pixels, region, shadow, target)
    np.testing.assert_array_equal(target, region & shadow)
    lit = region & ~shadow
    if not target.any() or not lit.any():
        assert got is None
    else:
        assert got is not None
        np.testing.assert_array_equal(got, channel_medians(pixels[lit]))
    with pytest.MonkeyPatch.context() as patched:
        patched.setenv(KERNELS_VARIABLE, "numpy")
        numpy_target = np.ones(region.shape, bool)
        numpy_path = lit_medians(pixels, region, shadow, numpy_target)
    np.testing.assert_array_equal(numpy_target, target)
    assert (numpy_path is None) == (got is None)
    if got is not None:
        np.testing.assert_array_equal(numpy_path, got)


def test_strided_views_are_read_as_they_are() -> None:
    rng = np.random.default_rng(2)
    image = rng.integers(0, 256, (30, 50, 3), dtype=np.uint8)
    shadow = rng.random((30, 50)) < 0.4
    region = np.zeros((30, 50), bool)
    region[8:, 5:45] = True
    flipped = image[:, ::-1]  # a view with negative strides
    lit = region & ~shadow
    got = lit_medians(flipped, region, shadow, np.empty((30, 50), bool))
    np.testing.assert_array_equal(got, channel_medians(flipped[lit]))
    assert remove_shadows(flipped, shadow, region).shape == flipped.shape


@settings(max_examples=100, deadline=None)
@given(case=_regions())
def test_lit_levels_counts_each_channel_of_the_lit_pixels(
    case: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    """The counts (kept in four histograms by column, then summed) are each channel's
    histogram of the lit pixels, and the shadow pixels of the region are marked."""
    pixels, region, shadow = case
    kernels = compiled("removal_kernels")
    target = np.zeros(region.shape, bool)
    counts, shaded = kernels.lit_levels(pixels, region, shadow, target)
    lit = pixels[region & ~shadow]
    expected = [np.bincount(lit[:, k], minlength=256) for k in range(pixels.shape[2])]
    np.testing.assert_array_equal(counts, np.array(expected).reshape(counts.shape))
    np.testing.assert_array_equal(target, region & shadow)
    assert shaded == int((region & shadow).sum())


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), strided=st.booleans())
def test_fill_where_sets_the_marked_pixels_and_only_them(seed: int, strided: bool) -> None:
    rng = np.random.default_rng(seed)
    values = rng.integers(0, 256, (23, 41), dtype=np.uint8)
    where = rng.random((23, 82 if strided else 41)) < 0.3
    marks = where[:, ::2] if strided else where
    expected = values.copy()
    expected[marks] = 201
    fill_where(values, marks, np.uint8(201))
    np.testing.assert_array_equal(values, expected)


def test_fill_where_refuses_a_mask_of_another_shape_and_a_level_out_of_range() -> None:
    """The kernel reads its mask unchecked, so the wrapper checks it first."""
    values = np.zeros((3, 5), np.uint8)
    with pytest.raises(InputError, match=r"where: expected bool \(3, 5\), got bool \(1, 5\)"):
        fill_where(values, np.ones((1, 5), bool), np.uint8(9))
    with pytest.raises(InputError, match=r"where: expected bool \(3, 5\), got int64 \(3, 5\)"):
        fill_where(values, np.ones((3, 5), np.int64), np.uint8(9))  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="value"):
        fill_where(values, np.ones((3, 5), bool), 300)  # type: ignore[arg-type]
    assert not values.any()
