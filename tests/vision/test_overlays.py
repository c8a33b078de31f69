"""Overlays: lane segments, fitted lines and caption; shadow tint."""

from __future__ import annotations

import numpy as np
import pytest

from qdcnn.config import LaneConfig
from qdcnn.errors import InputError, ParameterError
from qdcnn.vision.grouping import group_segments
from qdcnn.vision.overlays import (
    GROUP_COLOURS,
    LINE_COLOURS,
    MIDDLE_COLOUR,
    draw_lane_overlay,
    draw_shadow_overlay,
)

H, W = 160, 320
SEGMENTS = np.array([[100.0, 70, 40, 150], [220, 70, 280, 150]])


def frame() -> np.ndarray:
    return np.full((H, W, 3), 60, np.uint8)


def test_lane_overlay_colours_segments_by_group_and_keeps_the_input() -> None:
    img = frame()
    features = group_segments(SEGMENTS, (H, W))
    out = draw_lane_overlay(img, SEGMENTS, features, "straight", roi=None)
    assert out.shape == img.shape and out.dtype == np.uint8
    assert (img == 60).all()
    # a point on each segment, away from the fitted lines' thin strokes' anti-aliasing
    for (x1, y1, x2, y2), group in zip(SEGMENTS, features.labels, strict=True):
        x, y = round(0.75 * x1 + 0.25 * x2), round(0.75 * y1 + 0.25 * y2)
        patch = out[y - 1 : y + 2, x - 1 : x + 2].reshape(-1, 3).astype(int)
        wanted = np.array([GROUP_COLOURS[group], LINE_COLOURS[group]])
        best = np.abs(patch[:, None, :] - wanted[None]).sum(-1).min()
        assert best <= 30


def test_image_split_overlay_draws_the_middle_line() -> None:
    features = group_segments(SEGMENTS, (H, W), "image-split")
    assert features.middle_line == pytest.approx((0.0, 160.0))
    out = draw_lane_overlay(frame(), SEGMENTS, features, roi=None)
    band = out[40:150, 158:162].astype(int)
    nearest = np.abs(band - MIDDLE_COLOUR).sum(-1).min(axis=1)  # best pixel of each row
    assert (nearest < 60).all()


def test_overlay_of_a_frame_without_lines_draws_only_roi_and_caption() -> None:
    features = group_segments(np.empty((0, 4)), (H, W), "kmeans")
    out = draw_lane_overlay(frame(), np.empty((0, 4)), features, None)
    changed = (out != 60).any(-1)
    assert changed.any()
    assert not changed[80:120, 100:220].any()  # inside the ROI, away from its outline


def test_overlay_scale_and_grey_input() -> None:
    features = group_segments(SEGMENTS, (H, W))
    out = draw_lane_overlay(frame()[:, :, 0], SEGMENTS, features, "left", scale=3)
    assert out.shape == (3 * H, 3 * W, 3)
    with pytest.raises(ParameterError, match=r"^scale=0 is invalid"):
        draw_lane_overlay(frame(), SEGMENTS, features, scale=0)


def test_overlay_rejects_segments_that_do_not_match_the_features() -> None:
    features = group_segments(SEGMENTS, (H, W))
    with pytest.raises(InputError, match=r"^segments: 1 segments but 2 labels in features$"):
        draw_lane_overlay(frame(), SEGMENTS[:1], features, roi=LaneConfig().roi)


def test_shadow_overlay_blends_only_inside_the_mask() -> None:
    img = np.random.default_rng(1).integers(0, 256, (H, W, 3), dtype=np.uint8)
    mask = np.zeros((H, W), bool)
    mask[10:50, 20:90] = True
    out = draw_shadow_overlay(img, mask)
    np.testing.assert_array_equal(out[~mask], img[~mask])
    expected = np.round(0.55 * img[mask] + 0.45 * np.array([255, 0, 255]))
    np.testing.assert_allclose(out[mask], expected, atol=0.5)
    np.testing.assert_array_equal(draw_shadow_overlay(img, mask, alpha=0.0), img)
    full = draw_shadow_overlay(img, mask, color=(0, 255, 0), alpha=1.0)
    assert (full[mask] == [0, 255, 0]).all()


def test_shadow_overlay_errors() -> None:
    img = frame()
    with pytest.raises(InputError, match=r"^mask: expected a bool array of shape \(160, 320\)"):
        draw_shadow_overlay(img, np.zeros((H, W), np.uint8))
    with pytest.raises(InputError, match=r"^mask: expected a bool array"):
        draw_shadow_overlay(img, np.zeros((H, W + 1), bool))
    with pytest.raises(ParameterError, match=r"^alpha=1.5 is invalid"):
        draw_shadow_overlay(img, np.zeros((H, W), bool), alpha=1.5)
    with pytest.raises(ParameterError, match=r"^color=\(0, 300, 0\) is invalid"):
        draw_shadow_overlay(img, np.zeros((H, W), bool), color=(0, 300, 0))
    with pytest.raises(InputError, match=r"^image: expected a uint8 array, got float64$"):
        draw_shadow_overlay(img.astype(float), np.zeros((H, W), bool))


def test_caption_shows_the_chosen_inputs_and_fits_the_frame() -> None:
    extras = ("vanishing-point-offset", "near-vanishing-point-offset")
    features = group_segments(SEGMENTS, (H, W), extra_features=extras)
    names = features.feature_names
    columns = (names.index("vanishing_point_offset"), names.index("near_vanishing_point_offset"))
    slopes = draw_lane_overlay(frame(), SEGMENTS, features, roi=None)
    vps = draw_lane_overlay(frame(), SEGMENTS, features, roi=None, columns=columns)
    first, second = slice(0, 12), slice(13, 23)  # caption rows: method/status, then inputs
    np.testing.assert_array_equal(slopes[first], vps[first])
    assert (slopes[second] != vps[second]).any()
    # the long names are shrunk to the width instead of running off the frame's edge
    drawn = np.flatnonzero((vps[second] != 60).any(axis=(0, 2)))
    assert drawn.size and drawn.max() < W - 2
    with pytest.raises(ParameterError, match=r"^columns=\(0, 9\) is invalid"):
        draw_lane_overlay(frame(), SEGMENTS, features, columns=(0, 9))


def test_lane_overlay_draws_what_auto_chose() -> None:
    from qdcnn.vision.camera import CameraGeometry, camera_roi
    from qdcnn.vision.overlays import CAMERA_COLOUR

    hood = tuple([1.0] * 6 + [0.9] * 5 + [1.0] * 6)
    camera = CameraGeometry(
        (H, W), 0.4, (0.5, 0.4), hood, camera_roi((H, W), 0.4, 0.5, hood), "estimated", 9, 10
    )
    features = group_segments(SEGMENTS, (H, W))
    out = draw_lane_overlay(frame(), SEGMENTS, features, roi=camera.roi, camera=camera)
    xv, yv = round(0.5 * (W - 1)), round(0.4 * (H - 1))
    assert (np.abs(out[yv, xv - 3 : xv + 4].astype(int) - CAMERA_COLOUR).sum(-1) < 60).any()
    hood_row = round(0.9 * (H - 1))
    assert (np.abs(out[hood_row, 150:170].astype(int) - CAMERA_COLOUR).sum(-1) < 90).any()
    plain = draw_lane_overlay(frame(), SEGMENTS, features, roi=camera.roi)
    assert not (np.abs(plain[yv, xv - 3 : xv + 4].astype(int) - CAMERA_COLOUR).sum(-1) < 60).any()
