"""process_frame: the fast lane stage's segments and the lazily built corrected frame."""

from __future__ import annotations

import numpy as np

from qdcnn.config import LaneConfig, PipelineConfig
from qdcnn.data.synthetic import generate_drive
from qdcnn.pipeline import process_frame, road_region
from qdcnn.vision.lanes import detect_segments
from qdcnn.vision.removal import remove_shadows
from qdcnn.vision.shadows import detect_shadows_uu


def test_a_frame_gets_the_segments_of_its_corrected_frame() -> None:
    config = PipelineConfig()
    for i, scene in enumerate(generate_drive("track2", 6, seed=8)):
        image = scene.image
        frame = process_frame(image, config, rng=i)
        mask = detect_shadows_uu(image, config.shadow, rng=i).mask
        np.testing.assert_array_equal(frame.shadow_mask, mask)
        corrected = remove_shadows(image, mask, road_region(image.shape, config.lanes.roi))
        np.testing.assert_array_equal(frame.corrected, corrected)
        assert frame.corrected is frame.corrected  # built once
        np.testing.assert_array_equal(frame.segments, detect_segments(corrected, config.lanes))


def test_without_shadow_removal_the_corrected_frame_is_the_input() -> None:
    config = PipelineConfig(lanes=LaneConfig.udacity(remove_shadows=False))
    image = generate_drive("track1", 1, seed=2)[0].image
    frame = process_frame(image, config)
    assert frame.shadow_mask is None and frame.corrected is image
    np.testing.assert_array_equal(frame.segments, detect_segments(image, config.lanes))
