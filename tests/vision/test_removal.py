"""Shadow removal: exact replacement values, untouched pixels, relighting recovers the lit road."""

from __future__ import annotations

import numpy as np
import pytest

from qdcnn.errors import InputError, ParameterError
from qdcnn.vision.removal import remove_shadows

H, W = 40, 60


def textured_road(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    road = rng.normal([120, 118, 112], 10, (H, W, 3))
    road[:, 28:31] = [230, 230, 230]  # a lane marking
    return np.clip(np.rint(road), 0, 255).astype(np.uint8)


def masks() -> tuple[np.ndarray, np.ndarray]:
    shadow = np.zeros((H, W), bool)
    shadow[10:30, 15:45] = True
    region = np.zeros((H, W), bool)
    region[5:, 10:50] = True
    return shadow, region


def test_road_fill_uses_median_of_lit_region_pixels() -> None:
    img = textured_road()
    shadow, region = masks()
    out = remove_shadows(img, shadow, region)
    target = shadow & region
    expected = np.rint(np.median(img[region & ~shadow].astype(float), axis=0)).astype(np.uint8)
    assert (out[target] == expected).all()
    np.testing.assert_array_equal(out[~target], img[~target])


def test_only_shadow_pixels_inside_region_change() -> None:
    img = textured_road()
    shadow, region = masks()
    shadow[0:5, 0:10] = True  # shadow outside the region: must stay
    for method in ("road-fill", "relight"):
        out = remove_shadows(img, shadow, region, method=method)
        keep = ~(shadow & region)
        np.testing.assert_array_equal(out[keep], img[keep])
        assert (out[shadow & region] != img[shadow & region]).any()


def test_whole_image_region_by_default() -> None:
    img = textured_road()
    shadow, _ = masks()
    out = remove_shadows(img, shadow)
    expected = np.rint(np.median(img[~shadow].astype(float), axis=0)).astype(np.uint8)
    assert (out[shadow] == expected).all()


def test_relight_recovers_constant_ratio_shadow() -> None:
    lit = textured_road(1)
    shadow, region = masks()
    img = lit.copy()
    attenuation = np.array([0.45, 0.5, 0.6])
    img[shadow] = np.rint(lit[shadow] * attenuation).astype(np.uint8)
    out = remove_shadows(img, shadow, region, method="relight")
    target = shadow & region
    err = np.abs(out[target].astype(int) - lit[target].astype(int))
    assert err.mean() < 2.5  # rounding of the darkened values is amplified by the gain
    assert err.max() <= 6
    # The lane marking under the shadow stays brighter than the road beside it.
    assert out[15, 29].min() > out[15, 20].max() + 60


def test_road_fill_flattens_the_shadow() -> None:
    img = textured_road()
    shadow, region = masks()
    out = remove_shadows(img, shadow, region)
    assert len(np.unique(out[shadow & region], axis=0)) == 1


@pytest.mark.parametrize("method", ["road-fill", "relight"])
def test_no_lit_or_no_shadow_pixels_returns_an_unchanged_copy(method: str) -> None:
    img = textured_road()
    shadow, region = masks()
    for s, r in ((region.copy(), region), (np.zeros_like(shadow), region)):
        out = remove_shadows(img, s, r, method=method)
        np.testing.assert_array_equal(out, img)
        assert not np.shares_memory(out, img)


def test_black_shadow_relight_does_not_divide_by_zero() -> None:
    img = textured_road()
    shadow, region = masks()
    img[shadow] = 0
    out = remove_shadows(img, shadow, region, method="relight")
    assert (out[shadow & region] == 0).all()


def test_uint8_masks_and_greyscale_images() -> None:
    img = textured_road()
    shadow, region = masks()
    expected = remove_shadows(img, shadow, region)
    out = remove_shadows(img, shadow.astype(np.uint8) * 255, region.astype(np.uint8) * 255)
    np.testing.assert_array_equal(out, expected)
    grey = img[:, :, 0]
    out_grey = remove_shadows(grey, shadow, region)
    assert out_grey.shape == grey.shape
    assert (out_grey[shadow & region] == np.rint(np.median(grey[region & ~shadow]))).all()


def test_errors() -> None:
    img = textured_road()
    shadow, _ = masks()
    with pytest.raises(ParameterError, match=r"^method='blur' is invalid: 'road-fill' or 'relight"):
        remove_shadows(img, shadow, method="blur")  # type: ignore[arg-type]
    with pytest.raises(
        InputError, match=r"^region_mask: mask shape \(3, 3\) differs from image shape \(40, 60\)$"
    ):
        remove_shadows(img, shadow, np.ones((3, 3), bool))
    with pytest.raises(InputError, match=r"^image: expected uint8"):
        remove_shadows(img.astype(np.float32), shadow)
    with pytest.raises(InputError, match=r"^shadow_mask: expected a bool or uint8 mask"):
        remove_shadows(img, shadow.astype(np.float32))


def test_channel_medians_equal_numpy_median() -> None:
    from qdcnn.vision.removal import channel_medians

    rng = np.random.default_rng(3)
    for n in (1, 2, 3, 10, 11, 1001):
        values = rng.integers(0, 256, (n, 3)).astype(np.uint8)
        np.testing.assert_allclose(channel_medians(values), np.median(values.astype(float), axis=0))


def test_masked_channel_medians_equal_gathered_medians() -> None:
    from qdcnn.vision.removal import channel_medians, masked_channel_medians

    rng = np.random.default_rng(4)
    pixels = rng.integers(0, 256, (31, 47, 3)).astype(np.uint8)
    for frac in (0.01, 0.3, 0.9):
        mask = rng.random((31, 47)) < frac
        np.testing.assert_array_equal(
            masked_channel_medians(pixels, mask), channel_medians(pixels[mask])
        )


def _reference_removal(
    image: np.ndarray, shadow: np.ndarray, region: np.ndarray, method: str
) -> np.ndarray:
    """The removal written plainly: numpy medians and boolean-index writes on the whole image."""
    out = image.copy()
    target, lit = shadow & region, region & ~shadow
    if not target.any() or not lit.any():
        return out
    pixels = image.reshape(*image.shape[:2], -1)
    view = out.reshape(pixels.shape)
    lit_median = np.median(pixels[lit], axis=0)
    if method == "road-fill":
        view[target] = np.rint(lit_median).astype(np.uint8)
    else:
        gain = lit_median / np.maximum(np.median(pixels[target], axis=0), 1.0)
        view[target] = np.clip(np.rint(pixels[target] * gain), 0, 255).astype(np.uint8)
    return out


@pytest.mark.parametrize("method", ["road-fill", "relight"])
def test_removal_on_the_regions_rows_equals_the_plain_whole_image_removal(method: str) -> None:
    from qdcnn.vision.roi import polygon_mask

    rng = np.random.default_rng(7)
    for trial in range(60):
        h, w = (int(n) for n in rng.integers(2, 50, 2))
        image = rng.integers(0, 256, (h, w, 3) if trial % 3 else (h, w), dtype=np.uint8)
        shadow = rng.random((h, w)) < rng.uniform(0.1, 0.9)
        x0, x1 = sorted(rng.uniform(0, 1, 2))
        y0, y1 = sorted(rng.uniform(0, 1, 2))
        region = (
            polygon_mask((h, w), [(x0, y0), (x1, y0), (x1, y1), (x0, y1)])
            if trial % 2
            else rng.random((h, w)) < 0.5
        )
        got = remove_shadows(image, shadow, region, method=method)  # type: ignore[arg-type]
        np.testing.assert_array_equal(got, _reference_removal(image, shadow, region, method))


def test_an_empty_region_leaves_the_image_as_it_is() -> None:
    image = np.random.default_rng(0).integers(0, 256, (20, 30, 3), dtype=np.uint8)
    shadow = np.ones((20, 30), bool)
    for method in ("road-fill", "relight"):
        out = remove_shadows(image, shadow, np.zeros((20, 30), bool), method=method)
        np.testing.assert_array_equal(out, image)
        assert out is not image
