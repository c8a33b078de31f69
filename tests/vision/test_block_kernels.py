"""The compiled kernels of the UU-dagger detector, step by step, against the NumPy code they
replace: NumPy's pairwise sum, Otsu's threshold, the expanded and median-filtered block mask,
and the calibration (to 1e-12: its Newton steps use another tangent and summation order)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from qdcnn.config import ShadowConfig
from qdcnn.vision.otsu import otsu_threshold
from qdcnn.vision.shadows import (
    BlockGrid,
    _block_sums,
    _calibration_settings,
    _half_angle_tangents,
    _pixel_edges,
    binary_median,
    block_grid,
    calibrate_centroid,
    expand_blocks,
)

kernels = pytest.importorskip("qdcnn.vision.block_kernels", reason="numba is not installed")


@pytest.mark.parametrize("n", [1, 7, 8, 9, 127, 128, 129, 255, 256, 1000, 3160, 4099, 20_000])
def test_pairwise_sum_is_numpys_sum(n: int, rng: np.random.Generator) -> None:
    for _ in range(5):
        values = rng.standard_normal(n) * rng.uniform(1, 1e6)
        assert kernels._pairwise_sum(values, 0, n) == values.sum()


@settings(max_examples=200, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(2, 4000),
    area=st.sampled_from([1, 2, 12, 16, 32]),
)
def test_otsu_threshold_is_the_numpy_threshold(seed: int, n: int, area: int) -> None:
    rng = np.random.default_rng(seed)
    values = np.rint(rng.uniform(0, 255, n) * area) / area  # block means of ``area`` pixels
    if rng.random() < 0.5:
        values[: n // 3] = np.rint(rng.normal(40, 8, n // 3).clip(0, 255) * area) / area
    first, last = values.min(), values.max()
    if first == last:
        return
    assert kernels.otsu_threshold(values, 256, first, last) == otsu_threshold(values, 256)


@settings(max_examples=150, deadline=None)
@given(
    h=st.integers(8, 200),
    w=st.integers(8, 360),
    downsample=st.sampled_from([1, 2, 4]),
    grid=st.sampled_from([79, 23, 5]),
    ksize=st.sampled_from([1, 3, 5, 7, 9, 15]),
    seed=st.integers(0, 2**32 - 1),
)
def test_expand_median_is_the_numpy_mask(
    h: int, w: int, downsample: int, grid: int, ksize: int, seed: int
) -> None:
    if min(h, w) < downsample:
        return
    _assert_expand_median_is_the_numpy_mask(block_grid((h, w), downsample, grid), ksize, seed)


def _assert_expand_median_is_the_numpy_mask(geometry: BlockGrid, ksize: int, seed: int) -> None:
    blocks = np.random.default_rng(seed).random(geometry.grid_shape) < 0.5
    expected = expand_blocks(blocks, geometry).view(np.uint8)
    if ksize > 1:
        expected = binary_median(expected, ksize)
    ours = kernels.expand_median(blocks.view(np.uint8), geometry.row_of, geometry.col_of, ksize)
    np.testing.assert_array_equal(ours, expected.astype(bool))


@pytest.mark.parametrize(
    ("size", "downsample", "by_four"),
    [((320, 160), 4, True), ((640, 480), 4, True), ((321, 160), 4, False), ((320, 160), 1, False)],
)
@pytest.mark.parametrize("ksize", [1, 5, 15])
def test_both_row_expansions_give_the_numpy_mask(
    size: tuple[int, int], downsample: int, by_four: bool, ksize: int
) -> None:
    """The mask's rows are expanded four pixels at a time where the geometry allows it
    (the default downsampling on a width it divides) and pixel by pixel elsewhere: both
    give the NumPy mask."""
    geometry = block_grid(size[::-1], downsample, 79)
    assert kernels._in_groups_of_four(geometry.col_of) is by_four
    _assert_expand_median_is_the_numpy_mask(geometry, ksize, seed=ksize)


def _assert_block_sums_are_the_numpy_sums(grey: np.ndarray, downsample: int, grid: int) -> None:
    geometry = block_grid(grey.shape, downsample, grid)
    rows, cols, area = _pixel_edges(geometry, downsample)
    sums, means = kernels.block_sums(grey, rows, cols, area)
    expected, expected_area = _block_sums(np.ascontiguousarray(grey), geometry, downsample)
    np.testing.assert_array_equal(sums.ravel(), expected)
    np.testing.assert_array_equal(means.ravel(), expected / expected_area)


@pytest.mark.parametrize(
    ("size", "downsample", "grid", "layout", "by_word"),
    [
        ((160, 320), 4, 79, "contiguous", True),  # one block two words wide
        ((720, 1280), 4, 79, "contiguous", True),
        ((160, 321), 4, 79, "contiguous", False),  # rows not whole words
        ((160, 320), 2, 79, "contiguous", False),  # edges between words
        ((600, 320), 4, 2, "contiguous", False),  # blocks 300 rows tall: 16-bit lanes overflow
        ((160, 320), 4, 79, "strided rows", True),  # a crop of a wider frame
        ((160, 320), 4, 79, "unaligned", False),
        ((160, 320), 4, 79, "strided columns", False),
    ],
)
def test_both_block_sums_give_the_numpy_sums(
    size: tuple[int, int], downsample: int, grid: int, layout: str, by_word: bool
) -> None:
    """The blocks are summed from 32-bit words where the rows and column edges allow it,
    and pixel by pixel elsewhere: both give the summed-area table's sums."""
    h, w = size
    frame = np.random.default_rng(h + w).integers(0, 256, (h, 2 * w + 4), dtype=np.uint8)
    grey = {
        "contiguous": np.ascontiguousarray(frame[:, :w]),
        "strided rows": frame[:, 4 : w + 4],
        "unaligned": frame[:, 1 : w + 1],
        "strided columns": frame[:, : 2 * w : 2],
    }[layout]
    geometry = block_grid(grey.shape, downsample, grid)
    rows, cols, _ = _pixel_edges(geometry, downsample)
    assert kernels._in_words(grey, rows, cols) is by_word
    _assert_block_sums_are_the_numpy_sums(grey, downsample, grid)


@pytest.mark.parametrize(("height", "by_word"), [(128, True), (129, False)])
def test_saturated_blocks_at_the_lanes_limit(height: int, by_word: bool) -> None:
    """White blocks 128 rows tall fill a word's 16-bit lanes to 65,280 (the word path);
    one row more would overflow them and takes the pixel path."""
    grey = np.full((height, 64), 255, np.uint8)
    rows, cols = np.array([0, height]), np.array([0, 4, 16, 64])
    area = np.outer(np.diff(rows), np.diff(cols)).astype(np.float64)
    assert kernels._in_words(grey, rows, cols) is by_word
    sums, means = kernels.block_sums(grey, rows, cols, area)
    np.testing.assert_array_equal(sums, 255 * area)
    np.testing.assert_array_equal(means, np.full(area.shape, 255.0))


def test_blocks_without_columns_take_the_pixel_path() -> None:
    """Column edges that do not increase (an empty block, which no grid makes) are summed
    pixel by pixel: 0 for the empty block."""
    grey = np.random.default_rng(1).integers(0, 256, (64, 64), dtype=np.uint8)
    rows, cols = np.array([0, 32, 64]), np.array([0, 16, 16, 64])
    area = np.outer(np.diff(rows), np.diff(cols)).astype(np.float64)
    assert not kernels._in_words(grey, rows, cols)
    sums, _ = kernels.block_sums(grey, rows, cols, area)
    expected = [
        [grey[r0:r1, c0:c1].sum(dtype=np.int64) for c0, c1 in ((0, 16), (16, 16), (16, 64))]
        for r0, r1 in ((0, 32), (32, 64))
    ]
    np.testing.assert_array_equal(sums, expected)


@settings(max_examples=100, deadline=None)
@given(
    h=st.integers(4, 300),
    w=st.integers(1, 100).map(lambda k: 4 * k),
    downsample=st.sampled_from([1, 2, 4, 8]),
    grid=st.sampled_from([79, 23, 5, 1]),
    seed=st.integers(0, 2**32 - 1),
)
def test_block_sums_are_the_numpy_sums(
    h: int, w: int, downsample: int, grid: int, seed: int
) -> None:
    if min(h, w) < downsample:
        return
    grey = np.random.default_rng(seed).integers(0, 256, (h, w), dtype=np.uint8)
    _assert_block_sums_are_the_numpy_sums(grey, downsample, grid)


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 7, 8, 3160])
def test_the_value_range_is_numpys(n: int, rng: np.random.Generator) -> None:
    for _ in range(20):
        values = rng.uniform(-1e3, 1e3, n)
        assert kernels._value_range(values) == (values.min(), values.max())


@pytest.mark.parametrize("bin_width", [0.25, 0.5, 2.0, 0.3, 1 / 3])
def test_the_calibration_levels_are_the_rounded_quotients(
    bin_width: float, rng: np.random.Generator
) -> None:
    """Powers of two are multiplied by their inverse, other widths divide: both give
    ``rint(values / width)``, ties and halves included."""
    values = np.concatenate([rng.uniform(0, 255, 3000), np.arange(0, 255, bin_width / 2)])
    np.testing.assert_array_equal(
        kernels._levels(values, bin_width), np.rint(values / bin_width).astype(np.intp)
    )


@settings(max_examples=150, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), dark=st.floats(0, 200), n=st.integers(20, 4000))
def test_calibration_agrees_with_the_numpy_calibration(seed: int, dark: float, n: int) -> None:
    rng = np.random.default_rng(seed)
    values = np.rint(rng.uniform(dark, 255, n) * 16) / 16
    values[: n // 4] = np.rint(rng.normal(dark, 6, n // 4).clip(0, 255) * 16) / 16
    cfg = ShadowConfig(shots=None)
    theta = kernels.calibrate(values, *_args(cfg))
    expected = calibrate_centroid(values, "intensity", cfg)
    if np.isnan(theta):  # no certified fixed point: the caller runs the NumPy calibration
        return
    ours = min(max(theta * (255.0 / np.pi), 0.0), 255.0)
    assert ours == pytest.approx(expected, rel=1e-12, abs=1e-12)


def test_constant_blocks_calibrate_to_their_value() -> None:
    cfg = ShadowConfig(shots=None)
    theta = kernels.calibrate(np.full(300, 80.0), *_args(cfg))
    assert theta * 255.0 / np.pi == pytest.approx(80.0, abs=1e-9)


def _args(cfg: ShadowConfig) -> tuple[object, ...]:
    bin_width, angle, iterations, tol, spread, _ = _calibration_settings(cfg)
    return bin_width, angle, _half_angle_tangents(), int(iterations), tol, spread


class _KernelInputs(NamedTuple):
    """What the calibrated kernels take for one frame, as the detector builds it."""

    grey: np.ndarray
    edges: tuple[np.ndarray, np.ndarray, np.ndarray]
    calibration: tuple[np.ndarray, np.ndarray]
    amplitudes: tuple[np.ndarray, np.ndarray, np.ndarray]
    image_of: tuple[np.ndarray, np.ndarray, int]


def _kernel_inputs(size: tuple[int, int], cfg: ShadowConfig) -> list[_KernelInputs]:
    """The calibrated kernels' inputs for three benchmark frames of ``size``."""
    from qdcnn.experiments.shadow_bench import bench_frames
    from qdcnn.vision.shadows import _pixel_edges, feature_input, state_lookup

    out = []
    for image in bench_frames(*size, 3, seed=2):
        grey = feature_input(image, "intensity")
        geometry = block_grid(grey.shape[:2], cfg.downsample, cfg.grid)
        lookup = state_lookup(geometry, grey.shape[1], cfg.downsample)
        assert lookup is not None
        out.append(
            _KernelInputs(
                grey,
                _pixel_edges(geometry, cfg.downsample),
                (_half_angle_tangents(), _calibration_settings(cfg)),
                (lookup.offsets, lookup.cos_half, lookup.sin_half),
                (geometry.row_of, geometry.col_of, cfg.median_ksize),
            )
        )
    return out


@pytest.mark.parametrize("size", [(320, 160), (1280, 720)])
def test_the_fused_calibrated_detection_is_the_two_calls(size: tuple[int, int]) -> None:
    """``detect_calibrated`` gives what ``calibrate_blocks`` then ``detect_scores`` give."""
    from qdcnn.vision.shadows import _calibrated_value

    cfg = ShadowConfig(shots=None)
    for grey, edges, calibration, amplitudes, image_of in _kernel_inputs(size, cfg):
        fused = kernels.detect_calibrated(
            grey, edges, *calibration, amplitudes, cfg.threshold, *image_of
        )
        sums, blocks, theta = kernels.calibrate_blocks(grey, *edges, *calibration)
        centroid = _calibrated_value(theta, blocks, cfg)
        half = centroid * (np.pi / 255.0) / 2.0
        scores, decided, mask = kernels.detect_scores(
            sums, amplitudes, np.cos(half), np.sin(half), cfg.threshold, *image_of
        )
        assert fused[2] == centroid
        for ours, theirs in zip(fused[3:], (scores, decided, mask), strict=True):
            np.testing.assert_allclose(ours, theirs, rtol=1e-15, atol=0)
        np.testing.assert_array_equal(fused[0], sums)
        np.testing.assert_array_equal(fused[1], blocks)


@pytest.mark.parametrize("size", [(320, 160), (1280, 720)])
def test_the_fused_calibrated_shots_are_the_two_calls(size: tuple[int, int]) -> None:
    """``detect_calibrated_shots`` gives what ``calibrate_blocks`` then ``detect_shots``
    give, from the same uniforms."""
    from qdcnn.quantum.sampling import CDF_GRID
    from qdcnn.vision.shadows import _shot_tables

    cfg = ShadowConfig(shots=1024)
    tables, _ = _shot_tables(1024, cfg.threshold)
    for seed, inputs in enumerate(_kernel_inputs(size, cfg)):
        grey, edges, calibration, amplitudes, image_of = inputs
        u = np.random.default_rng(seed).random(edges[2].size)
        fused = kernels.detect_calibrated_shots(
            grey, edges, *calibration, amplitudes, u, tables, CDF_GRID, *image_of
        )
        sums, blocks, theta = kernels.calibrate_blocks(grey, *edges, *calibration)
        half = fused[2] * (np.pi / 255.0) / 2.0
        two_calls = kernels.detect_shots(
            sums, amplitudes, np.cos(half), np.sin(half), u, tables, CDF_GRID, *image_of
        )
        assert fused[2] == min(max(theta * (255.0 / np.pi), 0.0), 255.0)
        np.testing.assert_allclose(fused[3], two_calls[0], rtol=1e-15, atol=1e-15)
        for ours, theirs in zip(fused[4:], two_calls[1:], strict=True):
            np.testing.assert_array_equal(ours, theirs)
        np.testing.assert_array_equal(fused[0], sums)
        np.testing.assert_array_equal(fused[1], blocks)


@pytest.mark.parametrize("guess_right", [True, False])
def test_a_block_between_the_brackets_is_settled_and_the_mask_redone_if_it_changed(
    guess_right: bool,
) -> None:
    """The shot kernels put a block whose uniform fell between its CDF brackets in the
    mask with a first guess; settling it with the CDF at its own ``p`` keeps that mask
    when the guess was right and expands the block mask again when it was not."""
    from scipy.special import bdtr

    from qdcnn.vision.shadows import _settled

    geometry = block_grid((160, 320), 4, 79)
    image_of = (geometry.row_of, geometry.col_of, 5)
    decided = np.zeros(geometry.grid_shape, np.uint8)
    decided[10:14, 20:30] = 1
    p = np.full(decided.size, 0.3)
    shots, limit, block = 1024, 40, 12 * decided.shape[1] + 30  # beside the 1s
    p[block] = 0.04
    u = np.full(decided.size, 0.5)
    u[block] = float(bdtr(limit, shots, p[block])) * (1 - 1e-9)  # passes, just
    decided.ravel()[block] = 1 if guess_right else 0
    mask = kernels.expand_median(decided, *image_of)
    scores, settled = _settled(
        kernels, decided, np.array([block]), (p, u, shots, limit), mask, image_of
    )
    assert decided.ravel()[block] == 1
    assert (settled is mask) is guess_right
    assert np.array_equal(settled, mask) is guess_right
    np.testing.assert_array_equal(settled, kernels.expand_median(decided, *image_of))
    assert scores()[block] >= 1 - limit / shots  # its sampled score passes too


@pytest.mark.parametrize("shots", [None, 1024])
def test_a_frame_without_a_certified_fixed_point_is_calibrated_with_numpy(
    monkeypatch: pytest.MonkeyPatch, shots: int | None
) -> None:
    """Where the kernels find no certified fixed point (NaN: rare, so simulated here), the
    detector calibrates with NumPy and gives the NumPy path's result (with shots, from the
    same uniforms)."""
    from types import SimpleNamespace

    from qdcnn.experiments.shadow_bench import bench_frames
    from qdcnn.vision import shadows
    from qdcnn.vision.compiled import KERNELS_VARIABLE

    empty = np.empty((0, 0), np.uint8)

    def no_fixed_point(grey: np.ndarray, *args: object) -> tuple[object, ...]:
        sums, blocks, *_ = kernels.detect_calibrated(grey, *args)
        return sums, blocks, np.nan, np.empty(0), empty, empty.view(np.bool_)

    def no_fixed_point_shots(grey: np.ndarray, *args: object) -> tuple[object, ...]:
        sums, blocks, *_ = kernels.detect_calibrated_shots(grey, *args)
        return sums, blocks, np.nan, np.empty(0), empty, np.empty(0, np.intp), empty.view(bool)

    calls: list[float] = []
    cfg = ShadowConfig(shots=shots)
    image = bench_frames(320, 160, 1, seed=5)[0]
    with monkeypatch.context() as numpy_path:
        numpy_path.setenv(KERNELS_VARIABLE, "numpy")
        reference = shadows.detect_shadows_uu(image, cfg, rng=3)
    stub = SimpleNamespace(**vars(kernels))
    stub.detect_calibrated = no_fixed_point
    stub.detect_calibrated_shots = no_fixed_point_shots
    monkeypatch.setattr(shadows, "compiled_kernels", lambda: stub)
    monkeypatch.setattr(shadows, "_calibrated_value", _counting(shadows, calls))
    ours = shadows.detect_shadows_uu(image, cfg, rng=3)
    assert len(calls) == 1 and ours.centroid == reference.centroid
    np.testing.assert_array_equal(ours.mask, reference.mask)
    np.testing.assert_array_equal(ours.block_scores, reference.block_scores)
    assert ours.centroid_source == "calibrated"


def _counting(shadows: object, calls: list[float]) -> object:
    """``shadows._calibrated_value`` that records the NumPy calibrations it runs."""
    original = shadows._calibrated_value  # type: ignore[attr-defined]
    calibrate = shadows.calibrate_centroid  # type: ignore[attr-defined]

    def wrapped(theta: float, blocks: np.ndarray, cfg: ShadowConfig) -> float:
        if np.isnan(theta):
            calls.append(calibrate(blocks, cfg.feature, cfg))
        return float(original(theta, blocks, cfg))

    return wrapped
