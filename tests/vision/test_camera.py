"""Camera-aware ROI: horizon, vanishing point and hood against the synthetic dashcam's truth."""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
import pytest

from conftest import shared_recording
from qdcnn.config import LaneConfig
from qdcnn.data.frames import load_frameset
from qdcnn.data.synthetic import generate_drive
from qdcnn.data.synthetic_render import hood_coverage
from qdcnn.errors import InputError, ParameterError
from qdcnn.vision.camera import (
    CameraGeometry,
    apply_camera,
    border_segments,
    camera_roi,
    estimate_camera,
    sample_indices,
    vanishing_point,
)
from qdcnn.vision.lanes import roi_mask
from qdcnn.vision.roi import polygon_mask


def drive(seed: int, n: int = 24, size: tuple[int, int] = (320, 240), hood: bool = False):
    w, h = size
    return generate_drive("dashcam", n, seed=seed, width=w, height=h, hood=hood)


def true_horizon(scenes) -> float:
    h = scenes[0].image.shape[0]
    return float(np.median([s.horizon for s in scenes])) / (h - 1)


def test_dashcam_preset_roi_is_the_camera_roi_of_its_own_geometry() -> None:
    built = camera_roi((480, 640), 0.40, 0.5)
    np.testing.assert_allclose(built, LaneConfig.ROI_PRESETS["dashcam"], atol=1e-6)
    assert LaneConfig.dashcam().vanishing_point == (0.5, 0.40)


def test_camera_roi_covers_the_road_below_the_horizon_and_not_the_sky() -> None:
    h, w = 480, 640
    mask = polygon_mask((h, w), camera_roi((h, w), 0.45, 0.55))
    assert not mask[: int(0.45 * h)].any()  # nothing at or above the horizon
    assert mask[int(0.6 * h), int(0.55 * w)]  # the road ahead
    assert mask[h - 1, 5] and mask[h - 1, w - 5]  # the near road at both corners
    assert not mask[int(0.5 * h), 5]  # roadside beside the far road
    # its sides go through points curve_margin either side of the vanishing point
    narrow = polygon_mask((h, w), camera_roi((h, w), 0.45, 0.55, curve_margin=0.05))
    assert narrow.sum() < mask.sum()


def test_camera_roi_leaves_out_the_hood_with_a_notch() -> None:
    h, w = 160, 320
    cov = hood_coverage(w, h)
    top = np.where((cov >= 0.5).any(axis=0), np.argmax(cov >= 0.5, axis=0), h) / (h - 1)
    rows = tuple(np.interp(np.linspace(0, w - 1, 17), np.arange(w), np.minimum(top, 1.0)))
    mask = polygon_mask((h, w), camera_roi((h, w), 0.40, 0.5, rows))
    assert not (mask & (cov >= 0.5)).any()
    assert mask[int(0.8 * h), w // 2]  # the road just above the hood stays


def test_camera_roi_rejects_an_impossible_horizon() -> None:
    with pytest.raises(ParameterError, match=r"^horizon, vp_x="):
        camera_roi((160, 320), 0.99)
    with pytest.raises(ParameterError, match=r"^side_slope="):
        camera_roi((160, 320), 0.4, side_slope=0.0)


def test_vanishing_point_of_two_drawn_borders() -> None:
    # two lines meeting at (150, 50) in a 320x240 frame, top end first
    seg = np.array([[114.0, 80, 30, 150], [174.0, 80, 230, 150]])
    found = vanishing_point(seg, (240, 320))
    assert found is not None
    assert found.x == pytest.approx(150, abs=0.5) and found.y == pytest.approx(50, abs=0.5)
    assert found.left_slope == pytest.approx(1.2) and found.right_slope == pytest.approx(0.8)
    assert vanishing_point(seg[:1], (240, 320)) is None  # one side only


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_horizon_found_within_two_percent_on_synthetic_drives(seed: int) -> None:
    scenes = drive(seed)
    geometry = estimate_camera([s.image for s in scenes])
    assert geometry.source == "estimated" and geometry.notes == ()
    assert abs(geometry.horizon - true_horizon(scenes)) < 0.02
    assert geometry.hood_rows is None
    w = scenes[0].image.shape[1]
    true_x = np.median([s.vanishing_point[0] for s in scenes]) / (w - 1)
    assert abs(geometry.vanishing_point[0] - true_x) < 0.1  # bends move it; the horizon less
    assert geometry.shape == (240, 320)


@pytest.mark.slow
def test_horizon_within_five_percent_on_ninety_five_percent_of_drives() -> None:
    # the target, on 20 drives with their own camera horizon (36-50 %) and yaw
    errors = []
    for seed in range(100, 120):
        scenes = drive(seed, n=16)
        errors.append(
            abs(estimate_camera([s.image for s in scenes]).horizon - true_horizon(scenes))
        )
    assert np.mean(np.array(errors) <= 0.05) >= 0.95


def test_hood_found_where_the_synthetic_hood_is() -> None:
    scenes = drive(5, hood=True)
    h, w = scenes[0].image.shape[:2]
    geometry = estimate_camera([s.image for s in scenes])
    assert geometry.hood_rows is not None and geometry.source == "estimated"
    cov = hood_coverage(w, h) >= 0.5
    true_top = np.argmax(cov, axis=0)[w // 2] / (h - 1)
    assert geometry.hood_top == pytest.approx(true_top, abs=0.03)
    mask = roi_mask((h, w), geometry.roi) > 0
    assert (mask & cov).sum() <= 0.01 * cov.sum()  # the ROI leaves the hood out
    assert abs(geometry.horizon - true_horizon(scenes)) < 0.02  # the hood does not fool it


def test_apply_camera_puts_roi_and_vanishing_point_into_the_lane_settings() -> None:
    geometry = estimate_camera([s.image for s in drive(3)])
    lanes = apply_camera(LaneConfig.dashcam(marks="lab"), geometry)
    assert lanes.roi == geometry.roi and lanes.vanishing_point == geometry.vanishing_point
    assert lanes.marks == "lab" and lanes.work_width == 320
    assert "horizon at" in geometry.describe() and "estimated from" in geometry.describe()
    assert geometry.to_dict()["source"] == "estimated"


def _check_fallback(geometry: CameraGeometry, words: str) -> None:
    assert geometry.source == "preset"
    assert any(words in note for note in geometry.notes), geometry.notes
    assert all("\n" not in note for note in geometry.notes)
    assert roi_mask(geometry.shape, geometry.roi).any()  # never an empty ROI


def test_night_frames_fall_back_to_the_preset_with_a_note() -> None:
    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 6, (240, 320, 3), dtype=np.uint8) for _ in range(10)]
    geometry = estimate_camera(frames)
    _check_fallback(geometry, "no horizon found")
    assert geometry.roi == LaneConfig.ROI_PRESETS["dashcam"]


def test_a_wall_gives_no_horizon() -> None:
    rng = np.random.default_rng(1)
    wall = cv2.resize(rng.integers(60, 200, (24, 32, 3), dtype=np.uint8), (320, 240))
    frames = [np.roll(wall, 3 * i, axis=1) for i in range(10)]
    _check_fallback(estimate_camera(frames), "no horizon found")


def test_a_static_region_over_half_the_frame_is_not_taken_for_a_hood() -> None:
    scenes = drive(4, n=12)
    frames = []
    for s in scenes:
        img = s.image.copy()
        img[90:] = 120  # a covered lower 60 %: never changes
        frames.append(img)
    geometry = estimate_camera(frames)
    _check_fallback(geometry, "over half")
    assert geometry.hood_rows is None


def test_frames_of_another_size_are_left_out_with_a_note() -> None:
    scenes = drive(6, n=12)
    frames = [s.image for s in scenes]
    frames[3] = cv2.resize(frames[3], (160, 120))
    geometry = estimate_camera(frames)
    assert any("differ in size" in note for note in geometry.notes)
    assert geometry.source == "estimated" and geometry.shape == (240, 320)
    with pytest.raises(InputError, match=r"^frames: no frames"):
        estimate_camera([])


def test_sample_indices_spread_over_the_first_frames() -> None:
    idx = sample_indices(10_000)
    assert idx[0] == 0 and idx[-1] == 599 and len(idx) == 40
    assert (np.diff(idx) > 0).all()
    assert sample_indices(0).size == 0
    with pytest.raises(ParameterError, match=r"^count="):
        sample_indices(10, count=0)


def test_border_segments_keep_slanted_lines_only() -> None:
    img = np.full((240, 320), 80, np.uint8)
    cv2.line(img, (40, 230), (150, 110), 230, 3)  # a lane border, about 47 degrees
    cv2.line(img, (20, 200), (300, 195), 230, 3)  # nearly flat
    cv2.line(img, (280, 230), (282, 100), 230, 3)  # nearly vertical
    seg = border_segments(img)
    angle = np.degrees(np.arctan2(seg[:, 3] - seg[:, 1], np.abs(seg[:, 2] - seg[:, 0])))
    assert len(seg) >= 1 and ((angle > 40) & (angle < 55)).all()


@pytest.mark.realdata
def test_real_recordings_give_a_plausible_camera(
    record_property: Callable[[str, object], None],
) -> None:
    real = load_frameset(f"udacity:{shared_recording('real-dashcam-sample')}")
    geometry = estimate_camera([real.image(int(i)) for i in sample_indices(len(real))])
    record_property("real-dashcam-sample", geometry.describe())
    assert geometry.source == "estimated" and geometry.hood_rows is None
    assert 0.3 < geometry.horizon < 0.55  # SOURCE.md: the horizon sits near 40 %
    lake = load_frameset(f"udacity:{shared_recording('udacity-lake-track')}")
    geometry = estimate_camera([lake.image(int(i)) for i in sample_indices(len(lake))])
    record_property("udacity-lake-track", geometry.describe())
    assert geometry.hood_top is not None and 0.8 < geometry.hood_top < 0.9  # the bonnet
    assert 0.3 < geometry.horizon < 0.45
