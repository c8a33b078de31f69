"""Classical shadow detectors: known answers, sensible BER on a clear synthetic road scene,
degenerate inputs and parameter checks."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from conftest import shared_recording
from qdcnn.data.images import read_image
from qdcnn.errors import InputError, ParameterError
from qdcnn.vision.baselines import detect_cbs, detect_ibt, detect_lbp, hsi_hue_intensity, to_grey
from qdcnn.vision.metrics import confusion_counts, shadow_scores

DETECTORS = [detect_ibt, detect_cbs, detect_lbp]


def road_scene(
    seed: int, h: int = 160, w: int = 320
) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
    """Textured grey asphalt, blue sky, two lane markings and a darker, bluish shadow polygon.

    The shadow multiplies R, G, B by 0.42, 0.47, 0.58 (attenuated direct light, bluish
    skylight). Returns the RGB image and the ground-truth shadow mask.
    """
    rng = np.random.default_rng(seed)
    coarse = cv2.GaussianBlur(rng.normal(0, 1, (h, w)).astype(np.float32), (0, 0), 3)
    asphalt = 135 + 12 * coarse / coarse.std() + rng.normal(0, 6, (h, w))
    img = np.repeat(asphalt[:, :, None], 3, axis=2)
    img[:, :, 2] -= 4
    cv2.line(img, (int(0.15 * w), h - 1), (int(0.45 * w), int(0.35 * h)), (235, 235, 235), 3)
    cv2.line(img, (int(0.85 * w), h - 1), (int(0.55 * w), int(0.35 * h)), (230, 200, 60), 3)
    sky = int(0.3 * h)
    img[:sky] = np.array([150, 190, 235]) + rng.normal(0, 3, (sky, w, 1))
    gt = np.zeros((h, w), np.uint8)
    poly = np.array([[0.05, 0.55], [0.6, 0.45], [0.75, 0.8], [0.2, 0.95]]) * [w, h]
    cv2.fillPoly(gt, [poly.astype(np.int32)], 1)
    shadow = gt.astype(bool)
    img[shadow] *= np.array([0.42, 0.47, 0.58])
    return np.clip(np.rint(img), 0, 255).astype(np.uint8), shadow


@pytest.mark.parametrize(
    ("detector", "max_ber"), [(detect_ibt, 5), (detect_cbs, 10), (detect_lbp, 5)]
)
@pytest.mark.parametrize("seed", [0, 1])
def test_detectors_find_a_clear_shadow(detector, max_ber: float, seed: int) -> None:
    img, gt = road_scene(seed)
    mask = detector(img)
    scores = shadow_scores(confusion_counts(mask, gt))
    assert scores.ber < max_ber
    assert scores.iou > 80


@pytest.mark.parametrize("detector", DETECTORS)
@pytest.mark.parametrize("shape", [(1, 1, 3), (2, 3, 3), (5, 7), (37, 61, 3)])
def test_any_size_gives_bool_mask_of_input_size(detector, shape: tuple[int, ...]) -> None:
    img = np.random.default_rng(3).integers(0, 256, shape, dtype=np.uint8)
    mask = detector(img)
    assert mask.dtype == np.bool_
    assert mask.shape == shape[:2]


@pytest.mark.parametrize("detector", DETECTORS)
@pytest.mark.parametrize("value", [0, 97, 255])
def test_constant_image_has_no_shadow(detector, value: int) -> None:
    assert not detector(np.full((20, 30, 3), value, np.uint8)).any()


@pytest.mark.parametrize("detector", DETECTORS)
def test_greyscale_input_equals_replicated_rgb(detector) -> None:
    img, _ = road_scene(5, 40, 80)
    grey = to_grey(img)
    np.testing.assert_array_equal(detector(grey), detector(np.dstack([grey] * 3)))
    np.testing.assert_array_equal(detector(grey), detector(grey[:, :, None]))


def test_ibt_fixed_threshold_is_inclusive() -> None:
    grey = np.array([[10, 100, 101, 200]], np.uint8)
    np.testing.assert_array_equal(detect_ibt(grey, threshold=100), [[True, True, False, False]])
    assert detect_ibt(grey, threshold=255).all()
    assert not detect_ibt(grey, threshold=0).any()


def test_ibt_otsu_splits_two_levels() -> None:
    rng = np.random.default_rng(0)
    grey = np.where(rng.random((30, 30)) < 0.3, 50, 200).astype(np.uint8)
    np.testing.assert_array_equal(detect_ibt(grey), grey == 50)


def test_cbs_ignores_dark_neutral_patches_that_ibt_marks() -> None:
    img, gt = road_scene(2)
    patch = np.zeros(gt.shape, bool)
    patch[60:100, 250:300] = True  # dark, neutral grey (not bluish): a dark object, not a shadow
    img[patch] = 62
    assert detect_ibt(img)[patch].mean() > 0.95
    assert detect_cbs(img)[patch].mean() < 0.05
    assert detect_cbs(img)[gt].mean() > 0.9


def test_cbs_equalize_false_also_finds_the_shadow() -> None:
    img, gt = road_scene(0)
    assert shadow_scores(confusion_counts(detect_cbs(img, equalize=False), gt)).ber < 5


def test_hsi_hue_known_colours() -> None:
    colours = np.array(
        [[[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 0], [0, 255, 255], [90, 90, 90]]],
        np.uint8,
    )
    hue, intensity = hsi_hue_intensity(colours)
    np.testing.assert_allclose(hue[0], [0, 120, 240, 60, 180, 0], atol=1e-9)
    np.testing.assert_allclose(intensity[0], [85, 85, 85, 170, 170, 90])


def test_hsi_hue_matches_arccos_formula() -> None:
    rgb = np.random.default_rng(7).integers(0, 256, (50, 50, 3)).astype(np.float64)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    den = np.sqrt((r - g) ** 2 + (r - b) * (g - b))
    ok = den > 1e-6
    theta = np.degrees(np.arccos(np.clip(0.5 * ((r - g) + (r - b)) / np.where(ok, den, 1), -1, 1)))
    expected = np.where(b <= g, theta, 360 - theta)
    hue, _ = hsi_hue_intensity(rgb.astype(np.uint8))
    diff = np.abs(hue - expected)[ok]
    np.testing.assert_allclose(np.minimum(diff, 360 - diff), 0, atol=1e-6)


def test_lbp_is_reproducible_with_a_seed_and_subsampling() -> None:
    img, gt = road_scene(4)
    a = detect_lbp(img, max_samples=500, seed=3)
    np.testing.assert_array_equal(a, detect_lbp(img, max_samples=500, seed=3))
    assert shadow_scores(confusion_counts(a, gt)).ber < 5


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"threshold": -1}, "threshold=-1 is invalid"),
        ({"threshold": 256}, "threshold=256 is invalid"),
        ({"threshold": 12.5}, "threshold=12.5 is invalid"),
        ({"threshold": True}, "threshold=True is invalid"),
    ],
)
def test_ibt_rejects_bad_thresholds(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ParameterError, match=message):
        detect_ibt(np.zeros((4, 4, 3), np.uint8), **kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "kwargs",
    [
        {"points": 2},
        {"radius": 0},
        {"window": 8},
        {"window": 1},
        {"texture_weight": -0.1},
        {"max_samples": 10},
    ],
)
def test_lbp_rejects_absurd_parameters(kwargs: dict[str, object]) -> None:
    name = next(iter(kwargs))
    with pytest.raises(ParameterError, match=f"^{name}="):
        detect_lbp(np.zeros((8, 8, 3), np.uint8), **kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize("detector", DETECTORS)
@pytest.mark.parametrize(
    ("image", "message"),
    [
        (np.zeros((4, 4, 3), np.float32), "image: expected uint8 pixels, got float32"),
        (
            np.zeros((4, 4, 4), np.uint8),
            r"image: expected shape \(H, W, 3\) or \(H, W\), got shape \(4, 4, 4\)",
        ),
        (np.zeros((0, 4, 3), np.uint8), r"image: image is empty, shape \(0, 4, 3\)"),
    ],
)
def test_bad_images_raise_input_error(detector, image: NDArray[np.generic], message: str) -> None:
    with pytest.raises(InputError, match=f"^{message}$"):
        detector(image)


@pytest.mark.realdata
def test_real_frame_road_shadow() -> None:
    # A Udacity mountain-track frame with a cast shadow across the road (inspected by eye):
    # rows 78-99 x cols 90-199 lie inside the shadow, rows 122-139 are lit road.
    rec = shared_recording("udacity-mountain-track")
    img = read_image(rec / "IMG" / "center_2023_06_22_22_20_22_192.jpg")
    shadow, lit = (slice(78, 100), slice(90, 200)), (slice(122, 140), slice(20, 300))
    for detector in (detect_ibt, detect_lbp):
        mask = detector(img)
        assert mask[shadow].mean() > 0.9
        assert mask[lit].mean() < 0.5
    assert detect_cbs(img)[shadow].mean() > 0.7
