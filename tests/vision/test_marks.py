"""Lane-mark evidence: white and yellow stripes selected by colour, relative to the road."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from qdcnn.config import LaneConfig
from qdcnn.data.synthetic import generate_scene
from qdcnn.errors import InputError, ParameterError
from qdcnn.vision.lanes import detect_segments
from qdcnn.vision.marks import marking_mask

H, W = 120, 160
ASPHALT = (90, 90, 92)


def stripe(colour: tuple[int, int, int], width: int = 3, road=ASPHALT) -> np.ndarray:
    img = np.full((H, W, 3), road, np.uint8)
    img[:, 80 : 80 + width] = colour
    return img


@pytest.mark.parametrize("space", ["lab", "hls"])
@pytest.mark.parametrize(
    ("colour", "is_mark"),
    [
        ((230, 230, 225), True),  # white paint
        ((215, 175, 40), True),  # yellow paint
        ((200, 60, 40), False),  # a red fence or a brake light
        ((210, 120, 30), False),  # orange
        ((70, 150, 60), False),  # sunlit leaves
    ],
)
def test_white_and_yellow_stripes_only(space: str, colour: tuple, is_mark: bool) -> None:
    mask = marking_mask(stripe(colour), LaneConfig(marks=space))
    assert mask[:, 80:83].all() == is_mark
    assert not mask[:, :78].any() and not mask[:, 85:].any()


@pytest.mark.parametrize("space", ["lab", "hls"])
def test_a_marking_at_dusk_passes_as_in_daylight(space: str) -> None:
    # the same scene at a quarter of the light: contrast is a ratio, not grey levels
    day = stripe((230, 230, 225))
    dusk = (day.astype(np.float64) * 0.25).round().astype(np.uint8)
    cfg = LaneConfig(marks=space)
    np.testing.assert_array_equal(marking_mask(dusk, cfg), marking_mask(day, cfg))
    assert marking_mask(dusk, cfg)[:, 80:83].all()


def test_wide_bright_areas_are_not_markings() -> None:
    img = np.full((H, W, 3), ASPHALT, np.uint8)
    img[:, 60:120] = 235  # a wall, the sky or a bright patch 60 px wide
    cfg = LaneConfig(marks="lab")  # window 5 % of 160 px: 9 px
    assert not marking_mask(img, cfg).any()
    assert marking_mask(img, replace(cfg, marks_width=0.5))[:, 60:120].all()


def test_grey_frames_get_the_brightness_test_only_and_bad_input_is_refused() -> None:
    grey = stripe((230, 230, 230))[:, :, 0]
    assert marking_mask(grey, LaneConfig(marks="hls"))[:, 80:83].all()
    with pytest.raises(ParameterError, match=r"^lanes.marks='none'"):
        marking_mask(grey, LaneConfig())
    with pytest.raises(InputError, match=r"^image: expected a uint8 array"):
        marking_mask(grey.astype(float), LaneConfig(marks="lab"))
    with pytest.raises(ParameterError, match=r"^lanes.marks="):
        LaneConfig(marks="hsv")  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match=r"^lanes.marks_contrast="):
        LaneConfig(marks_contrast=-1.0)


def test_marks_find_the_dashcam_markings_and_little_else() -> None:
    scene = generate_scene("dashcam", seed=4, width=640, height=480, direction=1)
    mask = marking_mask(scene.image, LaneConfig(marks="lab"))
    h = scene.image.shape[0]
    # every true marking point low in the frame has a marking pixel within 3 px
    near = cv2.dilate(mask.astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
    for line in scene.lane_lines:
        low = line[line[:, 1] > 0.6 * h]
        assert len(low) > 10
        xy = np.round(low).astype(int)
        hit = near[xy[:, 1], xy[:, 0]]
        assert hit.mean() > 0.9
    # on the road below the horizon the marks cover little more than the markings
    road = scene.road_mask
    assert mask[road].mean() < 0.12


def test_marks_make_a_yellow_line_on_equal_grey_give_segments() -> None:
    # a yellow of the road's own grey level vanishes in grey Canny; the Lab marks see it
    img = np.full((160, 320, 3), (118, 118, 118), np.uint8)
    cv2.line(img, (60, 159), (140, 72), (190, 150, 20), 3)
    udacity = LaneConfig.udacity()
    assert len(detect_segments(img, udacity)) <= len(
        detect_segments(img, replace(udacity, marks="lab"))
    )
    seg = detect_segments(img, replace(udacity, marks="lab"))
    assert len(seg) >= 1
    d = np.array([140 - 60, 72 - 159], float)
    n = np.array([-d[1], d[0]]) / np.hypot(*d)
    for px, py in np.vstack([seg[:, :2], seg[:, 2:]]):
        assert abs((px - 60) * n[0] + (py - 159) * n[1]) < 4.0
