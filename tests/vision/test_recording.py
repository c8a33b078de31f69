"""Recording-level lane stage: auto ROI into the settings, frames in order, tracking, odd sizes."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from qdcnn.config import GroupingConfig, LaneConfig, PipelineConfig
from qdcnn.data.synthetic import generate_drive
from qdcnn.pipeline import auto_lanes, process_frame, process_recording, recording_sample


@pytest.fixture(scope="module")
def drive() -> list[np.ndarray]:
    return [s.image for s in generate_drive("dashcam", 16, seed=11, width=320, height=240)]


def lanes_only(**changes) -> PipelineConfig:
    return PipelineConfig(lanes=LaneConfig.dashcam(remove_shadows=False, **changes))


def test_auto_lanes_sets_the_estimated_roi_and_keeps_the_other_settings(drive) -> None:
    cfg, camera = auto_lanes(
        [drive[i] for i in recording_sample(len(drive))], lanes_only(marks="lab")
    )
    assert camera.source == "estimated"
    assert cfg.lanes.roi == camera.roi and cfg.lanes.vanishing_point == camera.vanishing_point
    assert cfg.lanes.marks == "lab" and cfg.lanes.remove_shadows is False
    assert cfg.lanes.roi != LaneConfig.dashcam().roi


def test_without_tracking_a_recording_is_its_frames_one_by_one(drive) -> None:
    cfg = lanes_only()
    results = list(process_recording(drive[:4], cfg, ("image-split", "kmeans")))
    for image, result in zip(drive[:4], results, strict=True):
        alone = process_frame(image, cfg, ("image-split", "kmeans"))
        np.testing.assert_array_equal(result.segments, alone.segments)
        for g in ("image-split", "kmeans"):
            np.testing.assert_array_equal(result.lanes[g].features, alone.lanes[g].features)
        assert result.notes == []


def test_tracking_carries_a_line_hidden_in_one_frame(drive) -> None:
    frames = [f.copy() for f in drive[:8]]
    frames[5][:, 160:] = cv2.GaussianBlur(frames[5][:, 160:], (0, 0), 8)  # right line gone
    plain = list(process_recording(frames, lanes_only(), ("image-split",)))
    assert plain[5].lanes["image-split"].status != "ok"
    cfg = replace(lanes_only(), grouping=GroupingConfig(track="ema", track_hold=3))
    tracked = list(process_recording(frames, cfg, ("image-split",)))
    assert tracked[5].lanes["image-split"].status == "ok"
    before, during = tracked[4].lanes["image-split"], tracked[5].lanes["image-split"]
    np.testing.assert_allclose(during.lines[1], before.lines[1], rtol=0.2, atol=5)


def test_frames_of_another_size_use_the_preset_with_one_note(drive) -> None:
    cfg, camera = auto_lanes(drive, lanes_only())
    frames = [drive[0], cv2.resize(drive[1], (640, 360)), cv2.resize(drive[2], (640, 360))]
    told: list[str] = []
    results = list(process_recording(frames, cfg, camera=camera, on_note=told.append))
    assert results[0].notes == []
    assert results[1].notes and "640x360" in results[1].notes[0] and "preset" in told[0]
    assert len(told) == 1 and "\n" not in told[0]
    alone = process_frame(
        frames[1],
        replace(
            cfg, lanes=replace(cfg.lanes, roi=LaneConfig.dashcam().roi, vanishing_point=(0.5, 0.40))
        ),
    )
    np.testing.assert_array_equal(results[1].segments, alone.segments)


def test_lane_stage_bench_row_is_a_labelled_measurement() -> None:
    from qdcnn.experiments.pipeline_bench import bench_lane_stage

    row = bench_lane_stage(frames=6, size=(320, 240), passes=1)
    assert row["size"] == [320, 240] and "320x240" in row["method"]
    assert row["frames_per_second"] == pytest.approx(1e3 / row["ms_per_frame"])
    assert 0 < row["cpu_ms_per_frame"] and 0 < row["camera_estimate_s"]
    assert row["camera"].startswith("camera 320x240")
