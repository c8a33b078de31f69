"""The fast intensity path of the UU-dagger detector (issue 22), NumPy and compiled, against
a straightforward implementation of the detector as it was before: same centroid, scores
and masks, bit for bit (the compiled calibration's centroid to 1e-12, its Newton steps
using another tangent and summation order); and its shot sampling against the binomial
distribution, numpy's and Aer's counts."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from qdcnn.config import ShadowConfig
from qdcnn.quantum.centroid import propagate_centroid, propagation_fixed_point
from qdcnn.quantum.uu_dagger import (
    angle_to_value,
    overlap_fidelity,
    ry_state_table,
    value_to_angle,
)
from qdcnn.vision.compiled import KERNELS_VARIABLE
from qdcnn.vision.shadows import (
    block_grid,
    compiled_kernels,
    detect_shadows_uu,
    expand_blocks,
    sampled_decisions,
)

#: significance level of each (deterministic, seeded) chi-square test
ALPHA = 1e-4


def _reference_centroid(values: np.ndarray, cfg: ShadowConfig) -> float:
    """Two-means (scikit-image Otsu) start and the propagation fixed point, step by step."""
    from skimage.filters import threshold_otsu

    v = values.ravel()
    cluster = v if v.min() == v.max() else v[v <= float(threshold_otsu(v, nbins=256))]
    counts = np.bincount(np.round(cluster / 0.25).astype(np.intp))
    levels = np.flatnonzero(counts)
    angles = value_to_angle(levels * 0.25)
    weights = counts[levels].astype(np.float64)
    theta0 = float(value_to_angle(float(cluster.mean())))
    its, tol = cfg.propagation_iterations, cfg.propagation_tol
    theta = propagation_fixed_point(angles, weights, theta0, iterations=its, tol=tol)
    if theta is None:
        theta = propagate_centroid(angles, theta0, iterations=its, tol=tol, weights=weights).theta
    return float(np.clip(angle_to_value(theta), 0.0, 255.0))


def _reference(image: np.ndarray, cfg: ShadowConfig) -> tuple[float, np.ndarray, np.ndarray]:
    """Block sums from the corners of an integral image, one score per block from the RY
    state table of its size, scores thresholded, blocks expanded, OpenCV's median."""
    grey = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    geometry = block_grid(grey.shape, cfg.downsample, cfg.grid)
    r, c = geometry.row_edges * cfg.downsample, geometry.col_edges * cfg.downsample
    table = cv2.integral(grey).astype(np.int64)
    sums = table[r[1:, None], c[None, 1:]] - table[r[:-1, None], c[None, 1:]]
    sums = sums - table[r[1:, None], c[None, :-1]] + table[r[:-1, None], c[None, :-1]]
    area = np.outer(np.diff(r), np.diff(c))
    values = sums / area.astype(np.float64)
    centroid = float(cfg.centroid) if cfg.centroid is not None else _reference_centroid(values, cfg)
    theta_c = float(value_to_angle(centroid))
    scores = np.empty(values.shape)
    for n in np.unique(area):
        cos_half, sin_half = ry_state_table(int(n))
        at = area == n
        scores[at] = overlap_fidelity(theta_c, cos_half[sums[at]], sin_half[sums[at]])
    full = expand_blocks(scores >= cfg.threshold, geometry).astype(np.uint8)
    if cfg.median_ksize > 1:
        full = cv2.medianBlur(full, cfg.median_ksize)
    return centroid, scores, full.astype(bool)


@st.composite
def _scenes(draw: st.DrawFn) -> tuple[np.ndarray, ShadowConfig]:
    h, w = draw(st.integers(16, 200)), draw(st.integers(16, 360))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    lit, dark, noise = rng.uniform(60, 250), rng.uniform(0, 160), rng.uniform(0, 40)
    img = lit + noise * rng.standard_normal((h, w, 3))
    for _ in range(draw(st.integers(0, 4))):  # dark rectangles: shadows
        y, x = rng.integers(0, h), rng.integers(0, w)
        img[y : y + rng.integers(1, h), x : x + rng.integers(1, w)] -= lit - dark
    image = np.clip(img, 0, 255).astype(np.uint8)
    cfg = ShadowConfig(
        shots=None,
        downsample=draw(st.sampled_from([1, 2, 4])),
        grid=draw(st.sampled_from([79, 23])),
        threshold=draw(st.sampled_from([0.5, 0.75, 0.9, 0.97, 0.995])),
        median_ksize=draw(st.sampled_from([1, 3, 5, 7])),
        centroid=draw(st.one_of(st.none(), st.floats(0.0, 255.0))),
    )
    return image, cfg


KERNELS = ["numpy", "numba"]


@contextmanager
def _kernels(name: str) -> Iterator[None]:
    """Run the detector's NumPy path or its compiled kernels (skipped without Numba)."""
    before = os.environ.get(KERNELS_VARIABLE)
    os.environ[KERNELS_VARIABLE] = name
    try:
        if name == "numba" and compiled_kernels() is None:
            pytest.skip("numba is not installed")
        yield
    finally:
        if before is None:
            del os.environ[KERNELS_VARIABLE]
        else:
            os.environ[KERNELS_VARIABLE] = before


def _assert_as_reference(image: np.ndarray, cfg: ShadowConfig, kernels: str) -> None:
    centroid, scores, mask = _reference(image, cfg)
    with _kernels(kernels):
        ours = detect_shadows_uu(image, cfg)
    if kernels == "numba" and cfg.centroid is None:  # calibrated: Newton's last bits differ
        assert ours.centroid == pytest.approx(centroid, rel=1e-12, abs=1e-12)
        np.testing.assert_allclose(ours.block_scores, scores, rtol=1e-12, atol=1e-15)
        np.testing.assert_array_equal(ours.block_mask, ours.block_scores >= cfg.threshold)
    else:
        assert ours.centroid == centroid
        np.testing.assert_array_equal(ours.block_scores, scores)
        np.testing.assert_array_equal(ours.block_mask, scores >= cfg.threshold)
    np.testing.assert_array_equal(ours.mask, mask)


@pytest.mark.parametrize("kernels", KERNELS)
@settings(max_examples=120, deadline=None)
@given(scene=_scenes())
def test_fast_path_is_bit_identical_to_the_reference(
    kernels: str, scene: tuple[np.ndarray, ShadowConfig]
) -> None:
    image, cfg = scene
    if min(image.shape[:2]) < cfg.downsample:
        return
    _assert_as_reference(image, cfg, kernels)


@pytest.mark.parametrize("kernels", KERNELS)
@pytest.mark.parametrize("size", [(320, 160), (1280, 720)])
def test_fast_path_on_the_benchmark_frames(kernels: str, size: tuple[int, int]) -> None:
    from qdcnn.experiments.shadow_bench import bench_frames

    for image in bench_frames(*size, 3, seed=4):
        for cfg in (ShadowConfig(shots=None), ShadowConfig(shots=None, centroid=70.0)):
            _assert_as_reference(image, cfg, kernels)


@pytest.mark.parametrize("centroid", [None, 70.0])
@pytest.mark.parametrize("median_ksize", [1, 5, 15, 17])
def test_compiled_shots_are_the_numpy_paths_shots(
    centroid: float | None, median_ksize: int
) -> None:
    """Same uniforms, same brackets: the compiled kernels' shot decisions, scores and mask
    are the NumPy path's (the calibrated centroid to 1e-12)."""
    from qdcnn.experiments.shadow_bench import bench_frames

    cfg = ShadowConfig(shots=1024, centroid=centroid, median_ksize=median_ksize)
    for image in bench_frames(320, 160, 3, seed=8):
        with _kernels("numpy"):
            theirs = detect_shadows_uu(image, cfg, rng=5)
        with _kernels("numba"):
            ours = detect_shadows_uu(image, cfg, rng=5)
        assert ours.centroid == pytest.approx(theirs.centroid, rel=1e-12)
        np.testing.assert_array_equal(ours.block_mask, theirs.block_mask)
        np.testing.assert_array_equal(ours.block_scores, theirs.block_scores)
        np.testing.assert_array_equal(ours.mask, theirs.mask)


@pytest.mark.parametrize("classes", [3, 4])
@pytest.mark.parametrize("shots", [None, 1024])
@pytest.mark.parametrize("median_ksize", [5, 17])
def test_a_multi_class_calibration_is_the_numpy_paths(
    classes: int, shots: int | None, median_ksize: int
) -> None:
    """The kernels calibrate on Otsu's two classes only: with ``calibration_classes`` 3 or
    4 the compiled detector calibrates the kernel's block means with NumPy, and gives the
    NumPy path's centroid and masks (it used to give the two-class centroid)."""
    cfg = ShadowConfig(shots=shots, calibration_classes=classes, median_ksize=median_ksize)
    image = np.random.default_rng(5).integers(0, 256, (120, 200, 3), dtype=np.uint8)
    with _kernels("numpy"):
        theirs = detect_shadows_uu(image, cfg, rng=5)
        in_two = detect_shadows_uu(image, replace(cfg, calibration_classes=2), rng=5)
    with _kernels("numba"):
        ours = detect_shadows_uu(image, cfg, rng=5)
    assert ours.centroid == theirs.centroid != in_two.centroid
    np.testing.assert_array_equal(ours.block_scores, theirs.block_scores)
    np.testing.assert_array_equal(ours.mask, theirs.mask)


# --- shots -------------------------------------------------------------------------------


def _pooled(observed: np.ndarray, expected: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cells expected at least 5 times; the rest pooled into the largest cell."""
    keep = expected >= 5
    obs, exp = observed[keep].astype(float), expected[keep].astype(float)
    big = int(np.argmax(exp))
    obs[big] += observed[~keep].sum()
    exp[big] += expected[~keep].sum()
    return obs, exp * (obs.sum() / exp.sum())


@pytest.mark.parametrize("fid", [0.999, 0.985, 0.97, 0.95, 0.6, 0.02])
def test_sampled_scores_follow_the_binomial_distribution(fid: float) -> None:
    from scipy.stats import binom, chisquare

    n = 100_000
    passed, scores = sampled_decisions(np.full(n, fid), 1024, 0.97, 17)
    ones = np.rint((1.0 - scores()) * 1024).astype(np.int64)
    expected = binom.pmf(np.arange(1025), 1024, 1.0 - fid) * n
    obs, exp = _pooled(np.bincount(ones, minlength=1025), expected)
    if obs.size > 1:
        assert chisquare(obs, exp).pvalue > ALPHA
    # the decisions are the sampled scores' and pass as often as the binomial CDF says
    np.testing.assert_array_equal(passed, scores() >= 0.97)
    p_pass = binom.cdf(1024 - 994, 1024, 1.0 - fid)  # 994 / 1024 is the first score >= 0.97
    sigma = np.sqrt(p_pass * (1 - p_pass) / n) + 1e-12
    assert abs(passed.mean() - p_pass) < 5 * sigma


def test_sampled_scores_agree_with_numpy_binomial(rng: np.random.Generator) -> None:
    from scipy.stats import chi2_contingency

    fid = rng.uniform(0.9, 1.0, 40)  # the blocks near the band edge, where shots matter
    _, scores = sampled_decisions(np.repeat(fid, 3000), 1024, 0.97, 5)
    ours = np.rint((1.0 - scores()) * 1024).astype(np.int64).reshape(40, 3000)
    theirs = np.random.default_rng(6).binomial(1024, np.repeat(1.0 - fid, 3000)).reshape(40, 3000)
    for a, b in zip(ours, theirs, strict=True):
        edges = np.unique(np.quantile(np.concatenate([a, b]), np.linspace(0, 1, 12)))
        if edges.size < 3:
            edges = np.arange(min(a.min(), b.min()), max(a.max(), b.max()) + 2)
        table = np.stack([np.histogram(a, edges)[0], np.histogram(b, edges)[0]])
        assert chi2_contingency(table[:, table.sum(axis=0) > 0]).pvalue > ALPHA / 40


def test_detector_shot_counts_agree_with_aer_counts() -> None:
    """Aer measures the UU-dagger circuit of one block 1024 x 400 times; the detector's
    sampled scores of 400 blocks with that block's value have the same distribution."""
    aer = pytest.importorskip("qiskit_aer")
    from scipy.stats import chi2_contingency

    from qdcnn.quantum.circuits import uu_dagger_circuit
    from qdcnn.quantum.qiskit_bridge import to_qiskit

    runs, centroid, value = 400, 70.0, 95.0
    image = np.full((4 * 20, 4 * 20, 3), value, dtype=np.uint8)  # 400 blocks of one value
    cfg = ShadowConfig(shots=1024, centroid=centroid, grid=20, median_ksize=1)
    det = detect_shadows_uu(image, cfg, rng=9)
    ours = np.rint((1.0 - det.block_scores.ravel()) * 1024).astype(np.int64)
    qc = to_qiskit(
        uu_dagger_circuit(value_to_angle(centroid), value_to_angle(np.array([value]))), 0
    )
    qc.measure_all()
    job = aer.AerSimulator().run(qc, shots=1024 * runs, memory=True, seed_simulator=4)
    ones = np.array([bit[-1] == "1" for bit in job.result().get_memory()])
    theirs = ones.reshape(runs, 1024).sum(axis=1)
    edges = np.unique(np.quantile(np.concatenate([theirs, ours]), np.linspace(0, 1, 9)))
    table = np.stack([np.histogram(theirs, edges)[0], np.histogram(ours, edges)[0]])
    assert chi2_contingency(table[:, table.sum(axis=0) > 0]).pvalue > ALPHA
    np.testing.assert_array_equal(det.block_mask, det.block_scores >= cfg.threshold)


def test_shot_decisions_are_reproducible_and_match_their_scores() -> None:
    from qdcnn.experiments.shadow_bench import bench_frames

    image = bench_frames(320, 160, 1, seed=2)[0]
    cfg = ShadowConfig(shots=1024)
    a = detect_shadows_uu(image, cfg, rng=3)
    b = detect_shadows_uu(image, cfg, rng=3)
    np.testing.assert_array_equal(a.mask, b.mask)
    np.testing.assert_array_equal(a.block_mask, a.block_scores >= cfg.threshold)
    np.testing.assert_array_equal(a.block_scores, b.block_scores)
    exact = detect_shadows_uu(image, replace(cfg, shots=None))
    assert np.abs(a.block_scores - exact.block_scores).max() < 0.1
