"""Temporal tracking of the two fitted lines: smoothing, carrying lost lines, outliers."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from qdcnn.config import GroupingConfig
from qdcnn.errors import ParameterError
from qdcnn.vision.grouping import feature_names, feature_values, group_segments
from qdcnn.vision.tracking import GATE, LaneTracker

H, W = 160, 320
LEFT = (-0.9, 150.0)  # x = a * y + b
RIGHT = (0.9, 170.0)


def segments(left: tuple[float, float] | None, right: tuple[float, float] | None) -> np.ndarray:
    rows = []
    for line in (left, right):
        if line is not None:
            a, b = line
            rows.append([a * 70 + b, 70, a * 155 + b, 155])
    return np.array(rows, dtype=np.float64).reshape(-1, 4)


def frame(left, right, extras=("far-offsets",)):
    return group_segments(segments(left, right), (H, W), extra_features=extras)


@pytest.mark.parametrize("kind", ["ema", "kalman"])
def test_tracking_reduces_frame_to_frame_jitter(kind: str) -> None:
    rng = np.random.default_rng(0)
    tracker = LaneTracker(GroupingConfig(track=kind, track_alpha=0.3))
    raw, tracked = [], []
    for _ in range(200):
        jitter = rng.normal(0, 3.0, 2)
        lanes = frame((LEFT[0], LEFT[1] + jitter[0]), (RIGHT[0], RIGHT[1] + jitter[1]))
        raw.append(lanes.features[0:2].copy())
        out = tracker.update(lanes)
        assert out.status == "ok"
        tracked.append(out.lines[0][1] + out.lines[0][0] * 100)
    true_x = LEFT[1] + LEFT[0] * 100  # the line's x at row 100
    slopes = np.array(raw)[:, 0]  # the jitter moves the lines sideways, not their slopes
    assert np.allclose(slopes, LEFT[0], atol=1e-9)
    err = np.array(tracked[20:]) - true_x
    assert err.std() < 0.7 * 3.0  # smoother than one frame's jitter
    assert abs(err.mean()) < 1.0  # and not biased


@pytest.mark.parametrize("kind", ["ema", "kalman"])
def test_a_lost_line_is_carried_for_hold_frames_then_dropped(kind: str) -> None:
    tracker = LaneTracker(GroupingConfig(track=kind, track_hold=3))
    for _ in range(5):
        tracker.update(frame(LEFT, RIGHT))
    statuses = []
    for _ in range(5):
        out = tracker.update(frame(LEFT, None))
        statuses.append(out.status)
        if out.status == "ok":
            assert out.lines[1] is not None
            np.testing.assert_allclose(out.lines[1], RIGHT, atol=0.05 if kind == "ema" else 5)
    assert statuses == ["ok"] * 3 + ["one-line"] * 2


def test_a_jump_is_rejected_until_it_persists() -> None:
    tracker = LaneTracker(GroupingConfig(track="ema", track_alpha=0.5, track_hold=2))
    for _ in range(5):
        tracker.update(frame(LEFT, RIGHT))
    far = (RIGHT[0], RIGHT[1] + GATE * W * 2)  # clutter fitted as the right line
    kept = tracker.update(frame(LEFT, far))
    np.testing.assert_allclose(kept.lines[1], RIGHT, atol=1e-9)
    tracker.update(frame(LEFT, far))
    moved = tracker.update(frame(LEFT, far))  # the third time in a row: a real change
    np.testing.assert_allclose(moved.lines[1], far, atol=1e-9)


def test_tracked_features_are_those_of_the_tracked_lines() -> None:
    cfg = GroupingConfig.for_features("far-offsets", track="ema")
    tracker = LaneTracker(cfg)
    tracker.update(frame(LEFT, RIGHT, cfg.extra_features))
    out = tracker.update(frame((-0.8, 150.0), RIGHT, cfg.extra_features))
    expected = feature_values(out.lines, cfg.extra_features, H, W)
    np.testing.assert_allclose(out.features, expected)
    assert out.feature_names == feature_names(cfg.extra_features)
    assert out.middle_line is not None


def test_no_tracking_passes_frames_through_and_a_new_size_restarts() -> None:
    lanes = frame(LEFT, RIGHT)
    assert LaneTracker(GroupingConfig()).update(lanes) is lanes
    tracker = LaneTracker(GroupingConfig(track="ema", track_hold=5))
    tracker.update(lanes)
    other = group_segments(segments(LEFT, None), (2 * H, 2 * W))
    assert tracker.update(other).status == "one-line"  # nothing carried across sizes


def test_bad_tracking_settings_raise_parameter_error() -> None:
    with pytest.raises(ParameterError, match=r"^grouping.track='kf'"):
        GroupingConfig(track="kf")  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match=r"^grouping.track_alpha=0"):
        GroupingConfig(track_alpha=0)
    with pytest.raises(ParameterError, match=r"^grouping.track_hold=-1"):
        replace(GroupingConfig(), track_hold=-1)
