"""The fast lane stage gives exactly the reference segments: shadow removal then detect_segments."""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
import pytest

from qdcnn.config import LaneConfig, ShadowConfig
from qdcnn.data.synthetic import generate_drive
from qdcnn.errors import InputError
from qdcnn.vision.lane_stage import fast_path_applies, lane_segments
from qdcnn.vision.lanes import detect_segments
from qdcnn.vision.removal import remove_shadows
from qdcnn.vision.roi import polygon_mask
from qdcnn.vision.shadows import detect_shadows_uu


def _reference(image: np.ndarray, config: LaneConfig, mask: np.ndarray | None) -> np.ndarray:
    corrected = image
    if mask is not None:
        corrected = remove_shadows(image, mask, polygon_mask(image.shape, config.roi))
    return detect_segments(corrected, config)


def _frames(preset: str, n: int, width: int, height: int, seed: int) -> list[np.ndarray]:
    return [s.image for s in generate_drive(preset, n, seed=seed, width=width, height=height)]


CONFIGS = {
    "udacity": LaneConfig.udacity(),
    "paper": LaneConfig.paper(),  # 30 smoothing passes
    "whole-frame": LaneConfig.udacity(smoothing_margin=None),
    "dashcam": LaneConfig.dashcam(),
    "no-median": LaneConfig.udacity(median_ksize=1, smoothing_iterations=2),
}


@pytest.mark.parametrize("name", sorted(CONFIGS))
@pytest.mark.parametrize(
    ("preset", "width", "height"),
    [("track1", 320, 160), ("track2", 640, 480), ("dashcam", 333, 171)],
)
def test_the_segments_equal_the_reference_with_the_detected_shadows(
    name: str, preset: str, width: int, height: int
) -> None:
    config = CONFIGS[name]
    assert fast_path_applies(config)
    frames = _frames(preset, 6, width, height, seed=len(name))
    filled = 0
    for i, image in enumerate(frames):
        mask = detect_shadows_uu(image, ShadowConfig(), rng=i).mask
        filled += int(mask.any())
        np.testing.assert_array_equal(
            lane_segments(image, config, mask), _reference(image, config, mask)
        )
        np.testing.assert_array_equal(
            lane_segments(image, config, None), _reference(image, config, None)
        )
    assert filled  # the shadow fill was exercised
    # and segments were found (the paper's 30 smoothing passes leave no edge; Canny ran)
    assert name == "paper" or any(len(lane_segments(f, config)) for f in frames)


def test_random_masks_grey_frames_and_empty_regions_give_the_reference() -> None:
    rng = np.random.default_rng(5)
    config = LaneConfig.udacity()
    for image in _frames("track2", 4, 320, 160, seed=2):
        for mask in (
            rng.random(image.shape[:2]) < 0.3,  # scattered shadow
            np.ones(image.shape[:2], bool),  # no lit pixel: nothing changes
            np.zeros(image.shape[:2], bool),
            (rng.random(image.shape[:2]) < 0.5).astype(np.uint8) * 200,  # a uint8 mask
        ):
            for frame in (image, image[..., 1].copy()):  # colour and grey
                np.testing.assert_array_equal(
                    lane_segments(frame, config, mask), _reference(frame, config, mask)
                )
    tiny = LaneConfig.udacity(roi=((0.0, 0.0), (0.001, 0.0), (0.0, 0.001)))  # next to no ROI
    image = _frames("track1", 1, 320, 160, seed=0)[0]
    mask = np.ones(image.shape[:2], bool)
    np.testing.assert_array_equal(lane_segments(image, tiny, mask), _reference(image, tiny, mask))


def test_other_edge_settings_take_the_reference_path() -> None:
    image = _frames("dashcam", 1, 640, 480, seed=1)[0]
    mask = detect_shadows_uu(image, ShadowConfig(), rng=0).mask
    for config in (
        LaneConfig.dashcam(marks="lab"),
        LaneConfig.udacity(edge_channels="rgb"),
        LaneConfig.udacity(work_width=320),
    ):
        np.testing.assert_array_equal(
            lane_segments(image, config, mask), _reference(image, config, mask)
        )
    assert not fast_path_applies(LaneConfig.udacity(edge_channels="rgb"))


def test_threads_do_not_share_buffers() -> None:
    config = LaneConfig.udacity()
    frames = _frames("track1", 8, 320, 160, seed=4)
    expected = [_reference(f, config, None) for f in frames]
    errors: list[int] = []

    def work(k: int) -> None:
        for _ in range(20):
            for i, frame in enumerate(frames):
                if not np.array_equal(lane_segments(frame, config), expected[i]):
                    errors.append(k)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors


def test_bad_inputs_are_named() -> None:
    config = LaneConfig.udacity()
    image = np.zeros((160, 320, 3), np.uint8)
    with pytest.raises(InputError, match="shadow_mask"):
        lane_segments(image, config, np.zeros((10, 10), bool))
    with pytest.raises(InputError, match="image"):
        lane_segments(np.zeros((8, 8, 4), np.uint8), config)
    assert replace(config, marks="lab") != config
