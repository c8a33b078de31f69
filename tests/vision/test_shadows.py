"""Block-wise UU-dagger shadow detection."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from qdcnn.config import ShadowConfig
from qdcnn.errors import InputError, ParameterError
from qdcnn.quantum.uu_dagger import angle_to_value, band_halfwidth
from qdcnn.vision import shadows
from qdcnn.vision.shadow_training import (
    MULTI_THRESHOLD_GRID,
    halfwidth_threshold,
    train_from_crop,
    train_multi_shadow_model,
    train_shadow_model,
)
from qdcnn.vision.shadows import (
    ShadowModel,
    binary_median,
    block_grid,
    block_means,
    calibrate_centroid,
    detect_shadows_uu,
    expand_blocks,
    extreme_cluster,
    feature_map,
    multi_centroid_test,
    state_lookup,
)

EXACT = ShadowConfig(shots=None)


def road_with_shadow(rng: np.random.Generator, shape=(160, 320), lit=150.0, dark=60.0):
    """Noisy grey road with a darker, slightly blue rectangle; returns image and mask."""
    h, w = shape
    img = rng.normal(lit, 6.0, (h, w, 3))
    mask = np.zeros((h, w), bool)
    mask[h // 3 : 2 * h // 3, w // 4 : w // 2] = True
    img[mask] = rng.normal(dark, 6.0, (mask.sum(), 3)) * [0.9, 0.95, 1.1]
    return np.clip(img, 0, 255).astype(np.uint8), mask


def iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum() / max((a | b).sum(), 1))


def test_paper_geometry_1896_square_gives_79_blocks_of_6x6() -> None:
    g = block_grid((1896, 1896), 4, 79)
    assert g.downsampled == (474, 474)
    assert g.grid_shape == (79, 79)
    assert set(np.diff(g.row_edges)) == {6}
    assert g.downsampled[0] * g.downsampled[1] == 224_676


def test_small_frames_get_one_block_per_downsampled_pixel() -> None:
    g = block_grid((160, 320), 4, 79)
    assert g.downsampled == (40, 80)
    assert g.grid_shape == (40, 79)


@pytest.mark.parametrize(("shape", "grid"), [((160, 320), 79), ((203, 317), 13), ((9, 5), 79)])
def test_expand_blocks_repeats_each_block_over_its_pixels(
    shape: tuple[int, int], grid: int, rng: np.random.Generator
) -> None:
    g = block_grid(shape, 4, grid)
    blocks = rng.random(g.grid_shape) < 0.5
    full = expand_blocks(blocks, g)
    assert full.shape == shape and full.dtype == bool
    np.testing.assert_array_equal(full, blocks[g.row_of[:, None], g.col_of[None, :]])


def test_block_means_equal_area_downsampling_then_block_average(rng: np.random.Generator) -> None:
    grey = rng.integers(0, 256, (203, 317)).astype(np.uint8)
    g = block_grid(grey.shape, 4, 13)
    ours = block_means(grey, g, 4)
    hd, wd = g.downsampled  # downsampling by 4 drops the last rows/columns that do not fill a cell
    small = grey[: hd * 4, : wd * 4].astype(np.float64).reshape(hd, 4, wd, 4).mean(axis=(1, 3))
    ref = np.array(
        [
            [
                small[r0:r1, c0:c1].mean()
                for c0, c1 in zip(g.col_edges[:-1], g.col_edges[1:], strict=True)
            ]
            for r0, r1 in zip(g.row_edges[:-1], g.row_edges[1:], strict=True)
        ]
    )
    np.testing.assert_allclose(ours, ref, atol=1e-9)


@pytest.mark.parametrize("ksize", [3, 5, 7, 11])
def test_binary_median_equals_opencv_median(rng: np.random.Generator, ksize: int) -> None:
    mask = (rng.random((97, 131)) > 0.6).astype(np.uint8)
    np.testing.assert_array_equal(binary_median(mask, ksize), cv2.medianBlur(mask, ksize))


def test_detects_a_dark_rectangle_with_calibrated_centroid(rng: np.random.Generator) -> None:
    img, truth = road_with_shadow(rng)
    res = detect_shadows_uu(img, EXACT)
    assert res.centroid_source == "calibrated"
    # mixed blocks on the rectangle's border pull the cluster centre slightly towards lit values
    assert res.centroid == pytest.approx(feature_map(img)[truth].mean(), abs=8)
    assert res.mask.shape == truth.shape
    assert iou(res.mask, truth) > 0.85


def test_shot_sampled_detection_matches_exact_away_from_the_band_edge(
    rng: np.random.Generator,
) -> None:
    img, truth = road_with_shadow(rng)
    exact = detect_shadows_uu(img, EXACT)
    shots = detect_shadows_uu(img, replace(EXACT, shots=1024), rng=1)
    assert iou(shots.mask, exact.mask) > 0.97
    assert iou(shots.mask, truth) > 0.85


def test_given_centroid_is_a_band_threshold_on_block_means(rng: np.random.Generator) -> None:
    img = rng.integers(0, 256, (64, 64, 3)).astype(np.uint8)
    cfg = replace(EXACT, centroid=100.0, threshold=0.9, median_ksize=1)
    res = detect_shadows_uu(img, cfg)
    halfwidth = angle_to_value(band_halfwidth(0.9))
    inside = np.abs(res.block_values - 100.0) <= halfwidth
    away = np.abs(np.abs(res.block_values - 100.0) - halfwidth) > 1e-6
    np.testing.assert_array_equal((res.block_scores >= 0.9)[away], inside[away])
    assert res.centroid_source == "given"


def test_aer_backend_gives_the_same_exact_scores(rng: np.random.Generator) -> None:
    pytest.importorskip("qiskit_aer")
    img, _ = road_with_shadow(rng, shape=(40, 48))
    a = detect_shadows_uu(img, EXACT)
    b = detect_shadows_uu(img, EXACT, backend="aer")
    np.testing.assert_allclose(a.block_scores, b.block_scores, atol=1e-10)


@pytest.mark.parametrize("shots", [None, 1024])
def test_state_table_path_equals_the_cosine_path(
    rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch, shots: int | None
) -> None:
    img, _ = road_with_shadow(rng)
    cfg = replace(EXACT, shots=shots)
    geometry = block_grid(img.shape[:2], cfg.downsample, cfg.grid)
    assert state_lookup(geometry, img.shape[1], cfg.downsample) is not None
    table = detect_shadows_uu(img, cfg, rng=3)
    monkeypatch.setattr(shadows, "MAX_STATE_TABLE", 0)
    geometry.state_cache.clear()
    assert state_lookup(geometry, img.shape[1], cfg.downsample) is None
    cosine = detect_shadows_uu(img, cfg, rng=3)
    geometry.state_cache.clear()
    np.testing.assert_allclose(table.block_scores, cosine.block_scores, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(table.mask, cosine.mask)


def test_the_last_state_lookup_is_reused_until_its_grid_is_rebuilt() -> None:
    """A frame of the last frame's grid gets the same lookup (no new tables or objects);
    another grid gets its own, and a grid whose cache was cleared a new one."""
    geometry = block_grid((160, 320), 4, 79)
    first = state_lookup(geometry, 320, 4)
    assert first is not None and state_lookup(geometry, 320, 4) is first
    other = state_lookup(block_grid((120, 200), 4, 79), 200, 4)
    assert other is not None and other.offsets.size != first.offsets.size
    again = state_lookup(geometry, 320, 4)
    assert again is not None and again is not first  # one lookup kept: the memory stays bounded
    np.testing.assert_array_equal(again.offsets, first.offsets)
    geometry.state_cache.clear()
    rebuilt = state_lookup(geometry, 320, 4)
    assert rebuilt is not None and rebuilt is not again
    np.testing.assert_array_equal(rebuilt.cos_half, first.cos_half)


def test_state_tables_are_skipped_for_very_large_blocks() -> None:
    geometry = block_grid((3000, 4000), 4, 79)  # blocks of about 38 x 50 pixels
    assert state_lookup(geometry, 4000, 4) is None


def test_chromaticity_feature_values() -> None:
    grey = np.full((2, 2, 3), 120, np.uint8)
    assert feature_map(grey, "chromaticity")[0, 0] == pytest.approx(127.5, abs=1e-3)
    blue = np.array([[[60, 70, 110]]], np.uint8)
    assert feature_map(blue, "chromaticity")[0, 0] > 127.5
    with pytest.raises(ParameterError, match="feature='hue'"):
        feature_map(grey, "hue")


def test_chromaticity_detector_finds_bluish_shadow(rng: np.random.Generator) -> None:
    img, truth = road_with_shadow(rng)
    # c3 of this shadow is only ~11 levels above lit grey, so the band must be narrow (+-7 levels)
    res = detect_shadows_uu(img, replace(EXACT, feature="chromaticity", threshold=0.998))
    assert iou(res.mask, truth) > 0.8


def test_calibration_picks_dark_mode(rng: np.random.Generator) -> None:
    values = np.concatenate([rng.normal(55, 4, 500), rng.normal(170, 8, 2000)])
    assert calibrate_centroid(values, "intensity", EXACT) == pytest.approx(55, abs=1.5)


def test_image_smaller_than_one_downsampling_cell() -> None:
    with pytest.raises(ParameterError, match=r"image size='3x2' is invalid: at least 4x4 pixels"):
        detect_shadows_uu(np.zeros((2, 3, 3), np.uint8), EXACT)


def test_uniform_image_does_not_crash() -> None:
    res = detect_shadows_uu(np.full((50, 70, 3), 90, np.uint8), EXACT)
    assert res.mask.shape == (50, 70)


def test_train_from_crop_gives_the_shadow_value(rng: np.random.Generator) -> None:
    img, truth = road_with_shadow(rng)
    model = train_from_crop(img, (100, 70, 150, 100), EXACT)
    assert model.centroid == pytest.approx(feature_map(img)[truth].mean(), abs=2)
    res = detect_shadows_uu(img, EXACT, model=model)
    assert res.centroid_source == "model"
    assert iou(res.mask, truth) > 0.85
    with pytest.raises(ParameterError, match="box"):
        train_from_crop(img, (10, 10, 5, 20))


def test_train_on_images_with_masks_and_pick_threshold(rng: np.random.Generator) -> None:
    pairs = [road_with_shadow(rng, dark=d) for d in (50, 60, 70)]
    model = train_shadow_model(
        [p[0] for p in pairs], [p[1] for p in pairs], EXACT, thresholds=(0.5, 0.75, 0.97)
    )
    assert model.centroid == pytest.approx(60, abs=4)
    assert model.threshold in (0.75, 0.97)
    img, truth = road_with_shadow(rng, dark=65)
    assert iou(detect_shadows_uu(img, EXACT, model=model).mask, truth) > 0.85


def test_model_file_round_trip_and_errors(tmp_path: Path) -> None:
    model = ShadowModel("intensity", 61.5, 0.97, {"trained_on": "test"})
    assert ShadowModel.load(model.save(tmp_path / "m.json")) == model
    with pytest.raises(InputError, match="m2.json: model file not found"):
        ShadowModel.load(tmp_path / "m2.json")
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(InputError, match="bad.json: not a qdcnn shadow model"):
        ShadowModel.load(tmp_path / "bad.json")
    (tmp_path / "other.json").write_text('{"kind": "something"}')
    with pytest.raises(InputError, match="holds a 'something', not a 'qdcnn-shadow-model'"):
        ShadowModel.load(tmp_path / "other.json")
    (tmp_path / "range.json").write_text(
        '{"kind": "qdcnn-shadow-model", "feature": "intensity", "centroid": 900, "threshold": 0.9}'
    )
    with pytest.raises(InputError) as info:
        ShadowModel.load(tmp_path / "range.json")
    assert str(info.value) == (
        f"{tmp_path / 'range.json'}: bad field: centroid=900 is invalid: "
        "a finite number in [0, 255]"
    )


# --- chromaticity look-up, multi-class calibration, multi-centroid models ---


def test_chromaticity_lookup_equals_direct_formula(rng: np.random.Generator) -> None:
    img = rng.integers(0, 256, (37, 53, 3)).astype(np.uint8)
    rgb = img.astype(np.float32)
    direct = np.arctan2(rgb[..., 2], np.maximum(rgb[..., 0], rgb[..., 1]))
    direct = (direct * np.float32(255.0 / (np.pi / 2))).astype(np.float32)
    got = feature_map(img, "chromaticity")
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, direct)


def test_extreme_cluster_separates_three_modes(rng: np.random.Generator) -> None:
    values = np.concatenate(
        [rng.normal(60, 3, 300), rng.normal(150, 5, 1500), rng.normal(225, 4, 700)]
    )
    assert extreme_cluster(values, 3, "lowest").mean() == pytest.approx(60, abs=2)
    assert extreme_cluster(values, 3, "highest").mean() == pytest.approx(225, abs=2)
    with pytest.raises(ParameterError, match="pick"):
        extreme_cluster(values, 3, "middle")


def test_multi_class_calibration_ignores_a_bright_third_mode(rng: np.random.Generator) -> None:
    # shadow, lit road and a large bright sky: two-means puts shadow and road together
    values = np.concatenate(
        [rng.normal(60, 3, 300), rng.normal(140, 5, 900), rng.normal(230, 3, 1800)]
    )
    two = calibrate_centroid(values, "intensity", EXACT)
    three = calibrate_centroid(values, "intensity", replace(EXACT, calibration_classes=3))
    assert abs(two - 60) > 20
    assert three == pytest.approx(60, abs=2)


@pytest.mark.parametrize("classes", [1, 5, 2.0])
def test_calibration_classes_is_checked(classes: object) -> None:
    with pytest.raises(ParameterError, match="shadow.calibration_classes"):
        ShadowConfig(calibration_classes=classes)  # type: ignore[arg-type]


def test_halfwidth_threshold_inverts_band_halfwidth() -> None:
    for h in (2.0, 28.0, 85.0):
        assert angle_to_value(band_halfwidth(halfwidth_threshold(h))) == pytest.approx(h)
    assert halfwidth_threshold(28.0) == pytest.approx(0.97, abs=0.002)
    assert list(MULTI_THRESHOLD_GRID) == sorted(MULTI_THRESHOLD_GRID)


def test_cascade_gives_the_decisions_of_all_circuits(rng: np.random.Generator) -> None:
    values = rng.uniform(0, 255, (2, 500))
    centroids = np.array([[50.0, 140.0], [60.0, 100.0], [120.0, 128.0]])
    thresholds = np.array([[0.95, 0.9], [0.98, 0.97], [0.99, 0.95]])
    accepted, scores = multi_centroid_test(values, centroids, thresholds, shots=None)
    fid = np.cos((centroids[:, :, None] - values[None]) * np.pi / 255 / 2) ** 2  # (k, F, N)
    member = np.all(fid >= thresholds[:, :, None], axis=1)
    np.testing.assert_array_equal(accepted, member.any(axis=0))
    # where a block passed a component's first test, its product fidelity is known
    ran = fid[:, 0] >= thresholds[:, :1]
    best = np.where(ran, fid.prod(axis=1), 0.0).max(axis=0)
    np.testing.assert_allclose(scores, best, atol=1e-12)


def road_with_decoy(rng: np.random.Generator, shift: int = 0):
    """Grey road with a brown verge: a bluish shadow on each, and a neutral dark tar patch
    on the road that is not shadow (as dark as the road shadow)."""
    h, w = 96, 160
    img = np.empty((h, w, 3))
    img[:] = [150.0, 150.0, 150.0]
    img[:, 120:] = [150.0, 120.0, 80.0]  # verge
    mask = np.zeros((h, w), bool)
    mask[16 + shift : 48 + shift, 16:64] = True  # shadow on the road
    mask[56:88, 124 - shift : 156 - shift] = True  # shadow on the verge
    tar = np.zeros((h, w), bool)
    tar[60:88, 70 + shift : 110 + shift] = True
    img[mask] *= [0.40, 0.42, 0.50]  # skylight: blue darkens least
    img[tar] *= [0.45, 0.45, 0.46]
    img += rng.normal(0.0, 3.0, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8), mask, tar


def test_multi_centroid_model_rejects_neutral_tar(rng: np.random.Generator) -> None:
    train = [road_with_decoy(rng, shift) for shift in (0, 4, 8)]
    images, masks = [t[0] for t in train], [t[1] for t in train]
    model = train_multi_shadow_model(images, masks, EXACT, n_centroids=2)
    assert model.is_multi and model.features == ("intensity", "chromaticity")
    # one component per surface: road shadow (~63, bluish c3 ~141), verge shadow (~53, ~96)
    cents = sorted(model.centroids, key=lambda c: c[1])
    assert cents[0] == pytest.approx((52.6, 95.5), abs=3)
    assert cents[1] == pytest.approx((63.1, 140.8), abs=3)
    img, truth, tar = road_with_decoy(rng, 2)
    res = detect_shadows_uu(img, EXACT, model=model)
    assert res.centroid_source == "model" and res.feature == "intensity+chromaticity"
    assert res.feature_values is not None and res.feature_values.shape == (2, 24, 40)
    assert iou(res.mask, truth) > 0.85
    assert res.mask[tar].mean() < 0.05
    # the paper's single intensity centroid cannot tell the tar from the road shadow
    paper = train_shadow_model(images, masks, EXACT)
    assert detect_shadows_uu(img, EXACT, model=paper).mask[tar].mean() > 0.9
    shots = detect_shadows_uu(img, replace(EXACT, shots=1024), model=model, rng=3)
    assert iou(shots.mask, res.mask) > 0.9


def test_multi_centroid_model_file_round_trip_and_checks(tmp_path: Path) -> None:
    model = ShadowModel(
        "intensity",
        50.0,
        0.95,
        {"trained_on": "test"},
        ("intensity", "chromaticity"),
        ((50.0, 140.0), (60.0, 100.0)),
        ((0.95, 0.9), (0.98, 0.97)),
    )
    assert ShadowModel.load(model.save(tmp_path / "multi.json")) == model
    # a paper model keeps the original file layout and reads back as one
    paper = ShadowModel("intensity", 61.5, 0.97)
    paper.save(tmp_path / "paper.json")
    assert "centroids" not in (tmp_path / "paper.json").read_text()
    assert not ShadowModel.load(tmp_path / "paper.json").is_multi
    with pytest.raises(ParameterError, match="thresholds"):
        ShadowModel("intensity", 50.0, 0.95, {}, ("intensity",), ((50.0,),), ((0.9, 0.8),))
    with pytest.raises(ParameterError, match="features"):
        ShadowModel("intensity", 50.0, 0.95, {}, ("hue",), ((50.0,),), ((0.9,),))
    with pytest.raises(ParameterError, match="centroids"):
        ShadowModel("intensity", 50.0, 0.95, {}, ("intensity",), ((300.0,),), ((0.9,),))
    img = np.full((40, 48, 3), 90, np.uint8)
    with pytest.raises(ParameterError, match="shadow.centroid"):
        detect_shadows_uu(img, replace(EXACT, centroid=50.0), model=model)


def test_train_multi_checks_its_arguments(rng: np.random.Generator) -> None:
    img, truth = road_with_shadow(rng, shape=(48, 64))
    with pytest.raises(ParameterError, match="features"):
        train_multi_shadow_model([img], [truth], EXACT, features=("hue",))
    with pytest.raises(ParameterError, match="n_centroids"):
        train_multi_shadow_model([img], [truth], EXACT, n_centroids=0)
    with pytest.raises(ParameterError, match="masks"):
        train_multi_shadow_model([img], [np.zeros_like(truth)], EXACT)
    with pytest.raises(ParameterError, match="images/masks"):
        train_multi_shadow_model([img], [], EXACT)


def _reference_detection(
    image: np.ndarray, cfg: ShadowConfig
) -> tuple[float, np.ndarray, np.ndarray]:
    """The detector as it was before the speed-up (issue 22): block sums from the four
    corners of each block, scikit-image's Otsu split, the propagation iterated to its
    tolerance, one cosine per block; returns centroid, block scores and mask."""
    from skimage.filters import threshold_otsu

    from qdcnn.quantum.centroid import propagate_centroid
    from qdcnn.quantum.uu_dagger import fidelity, value_to_angle

    grey = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    geometry = block_grid(grey.shape, cfg.downsample, cfg.grid)
    r, c = geometry.row_edges * cfg.downsample, geometry.col_edges * cfg.downsample
    table = cv2.integral(grey).astype(np.float64)
    sums = table[r[1:, None], c[None, 1:]] - table[r[:-1, None], c[None, 1:]]
    sums = sums - table[r[1:, None], c[None, :-1]] + table[r[:-1, None], c[None, :-1]]
    values = sums / np.outer(np.diff(r), np.diff(c))
    v = values.ravel()
    cluster = v[v <= float(threshold_otsu(v, nbins=256))]
    counts = np.bincount(np.round(cluster / 0.25).astype(np.intp))
    levels = np.flatnonzero(counts)
    res = propagate_centroid(
        value_to_angle(levels * 0.25),
        float(value_to_angle(cluster.mean())),
        iterations=cfg.propagation_iterations,
        tol=cfg.propagation_tol,
        weights=counts[levels],
    )
    centroid = float(np.clip(angle_to_value(res.theta), 0.0, 255.0))
    scores = fidelity(value_to_angle(centroid), value_to_angle(v), shots=None)
    block_mask = (scores >= cfg.threshold).reshape(values.shape)
    mask = cv2.medianBlur(expand_blocks(block_mask, geometry).astype(np.uint8), cfg.median_ksize)
    return centroid, scores.reshape(values.shape), mask.astype(bool)


@pytest.mark.parametrize("size", [(320, 160), (1280, 720), (333, 187)])
def test_calibrated_detector_equals_the_reference_implementation(size: tuple[int, int]) -> None:
    from qdcnn.data.synthetic import generate_scenes

    for track in ("track1", "track2"):
        for scene in generate_scenes(track, 4, seed=5, width=size[0], height=size[1]):
            centroid, scores, mask = _reference_detection(scene.image, EXACT)
            ours = detect_shadows_uu(scene.image, EXACT)
            assert ours.centroid_source == "calibrated"
            assert ours.centroid == pytest.approx(centroid, abs=1e-6)
            np.testing.assert_allclose(ours.block_scores, scores, rtol=0, atol=1e-9)
            np.testing.assert_array_equal(ours.mask, mask)
