"""Dataset specs with their own label settings: ``KIND:VALUE@unit=...,threshold=...``."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from qdcnn.classes import LEFT, RIGHT, STRAIGHT
from qdcnn.config import LabelConfig, PipelineConfig
from qdcnn.data.frames import (
    DataSpec,
    load_frameset,
    parse_data_spec,
    parse_spec,
    resolve_quantile_threshold,
)
from qdcnn.data.labels import DEFAULT_THRESHOLDS, Quantile
from qdcnn.errors import ParameterError

#: norm -> rad for the same road-wheel angle (the units' default thresholds mean the same).
NORM_TO_RAD = DEFAULT_THRESHOLDS["rad"] / DEFAULT_THRESHOLDS["norm"]


def write_udacity(root: Path, steering: np.ndarray) -> Path:
    """A tiny Udacity folder: one empty image per value, 10 frames a second, no header."""
    (root / "IMG").mkdir(parents=True)
    lines = []
    for i, value in enumerate(steering):
        s, ms = divmod(i * 100, 1000)
        name = f"center_2023_02_17_17_{s // 60:02d}_{s % 60:02d}_{ms:03d}.jpg"
        (root / "IMG" / name).write_bytes(b"")
        lines.append(f"IMG/{name}, , , {float(value)!r}, 0, 0, 1")
    (root / "driving_log.csv").write_text("\n".join(lines) + "\n")
    return root


def drive(n: int, seed: int) -> np.ndarray:
    """Smooth steering in [-0.5, 0.5]: a sum of slow sines, no exact ties."""
    t = np.arange(n) / 10.0
    rng = np.random.default_rng(seed)
    phase = rng.uniform(0, 2 * math.pi, 3)
    x = sum(np.sin(t * f + p) for f, p in zip((0.3, 0.71, 1.3), phase, strict=True))
    return np.round(0.5 * x / 3.0, 6)


# -- parsing -------------------------------------------------------------------------------


def test_plain_specs_parse_as_before() -> None:
    assert parse_data_spec("carla:/a/b") == DataSpec("carla", "/a/b")
    assert parse_spec("carla:/a/b") == ("carla", "/a/b")
    # an @ without key=value after it is part of the path
    assert parse_data_spec("udacity:runs/a@b") == DataSpec("udacity", "runs/a@b")


def test_suffix_parses_unit_and_threshold() -> None:
    spec = parse_data_spec("udacity:../shared/data/real-dashcam-sample@unit=rad,threshold=p33")
    assert spec == DataSpec("udacity", "../shared/data/real-dashcam-sample", "rad", Quantile(33))
    assert parse_data_spec("carla:x@threshold=0.1") == DataSpec("carla", "x", None, 0.1)
    assert parse_data_spec("udacity:x@unit=auto") == DataSpec("udacity", "x", "auto", None)
    assert parse_data_spec("synthetic:track1:40@threshold=p12.5").threshold == Quantile(12.5)


@pytest.mark.parametrize(
    ("spec", "problem"),
    [
        ("udacity:x@colour=red", "unknown key 'colour' (keys: unit, threshold, left)"),
        ("udacity:x@left=right", "left 'right' is not 'negative' or 'positive'"),
        ("udacity:x@left=positive,left=negative", "'left' given twice"),
        ("udacity:x@unit=miles", "unit 'miles' is not one of norm, rad, deg, auto"),
        ("udacity:x@threshold=wide", "threshold 'wide' is not a number >= 0 or pNN (a percentile)"),
        ("udacity:x@threshold=-0.1", "threshold '-0.1' is not a number >= 0 or pNN (a percentile)"),
        ("udacity:x@threshold=p0", "threshold 'p0' is not pNN with a percentile in 1..99"),
        ("udacity:x@threshold=p100", "threshold 'p100' is not pNN with a percentile in 1..99"),
        ("udacity:x@threshold=px", "threshold 'px' is not pNN with a percentile in 1..99"),
        ("udacity:x@unit=rad,unit=deg", "'unit' given twice"),
        ("udacity:x@unit=rad,threshold", "'threshold' in the @ suffix is not key=value"),
        ("udacity:@unit=rad", "udacity:PATH, carla:PATH or synthetic:PRESET[:N]"),
    ],
)
def test_bad_suffixes_name_the_spec_and_the_problem(spec: str, problem: str) -> None:
    with pytest.raises(ParameterError) as caught:
        parse_data_spec(spec)
    assert str(caught.value) == f"data={spec!r} is invalid: {problem}"
    assert "\n" not in str(caught.value)


def test_synthetic_drives_refuse_an_angle_unit() -> None:
    with pytest.raises(ParameterError, match=r"synthetic drive steers in norm"):
        load_frameset("synthetic:track1:20@unit=rad")
    with pytest.raises(ParameterError, match=r"synthetic drive steers left below zero"):
        load_frameset("synthetic:track1:20@left=positive")


def test_a_recording_that_steers_left_above_zero_is_labelled_the_right_way_round(
    tmp_path: Path,
) -> None:
    steering = np.array([0.5] * 10 + [0.0] * 10 + [-0.5] * 10)  # ROS: left, straight, right
    root = write_udacity(tmp_path / "ros", steering)
    assert parse_data_spec(f"udacity:{root}@left=positive").left == "positive"
    ros = load_frameset(f"udacity:{root}@unit=rad,left=positive")
    plain = load_frameset(f"udacity:{root}@unit=rad,left=negative")
    np.testing.assert_array_equal(ros.steering, -steering)
    np.testing.assert_array_equal(plain.steering, steering)
    labels = ros.labels(LabelConfig(window=0))
    assert labels.tolist() == [LEFT] * 10 + [STRAIGHT] * 10 + [RIGHT] * 10
    assert plain.labels(LabelConfig(window=0)).tolist() == labels[::-1].tolist()


def test_global_percentile_option_is_checked() -> None:
    assert LabelConfig(threshold_quantile=33).threshold_quantile == 33
    with pytest.raises(ParameterError, match="labels.threshold_quantile"):
        LabelConfig(threshold_quantile=0.5)
    with pytest.raises(ParameterError, match="not together with labels.threshold"):
        LabelConfig(threshold=0.1, threshold_quantile=33)
    cfg = PipelineConfig().with_labels(threshold_quantile=40)
    assert PipelineConfig.from_dict(cfg.to_dict()) == cfg


# -- units -----------------------------------------------------------------------------------


def test_spec_unit_overrides_the_global_option(tmp_path: Path) -> None:
    steering = np.array([0.1] * 10 + [-0.1] * 10)  # beyond 0.05 (norm), within 0.327 rad
    root = write_udacity(tmp_path / "rec", steering)
    as_norm = load_frameset(f"udacity:{root}", steering_unit="norm")
    as_rad = load_frameset(f"udacity:{root}@unit=rad", steering_unit="norm")
    assert as_norm.unit.unit == "norm" and as_rad.unit.unit == "rad"
    assert as_rad.name == "rec" and as_rad.spec == f"udacity:{root}@unit=rad"
    assert set(as_norm.labels(LabelConfig(window=0)).tolist()) == {0, 2}
    assert set(as_rad.labels(LabelConfig(window=0)).tolist()) == {STRAIGHT}
    assert as_norm.notes == [] and as_rad.notes == []
    assert as_rad.fingerprint() == as_norm.fingerprint()  # same frames: feature caches hit


def test_spec_threshold_overrides_the_config_threshold(tmp_path: Path) -> None:
    root = write_udacity(tmp_path / "rec", np.array([0.1] * 10 + [-0.1] * 10))
    frames = load_frameset(f"udacity:{root}@unit=norm,threshold=0.2")
    info = frames.label_info(LabelConfig(window=0, threshold=0.01))
    assert info.threshold == 0.2 and info.threshold_source == "given"
    assert set(info.labels.tolist()) == {STRAIGHT}


def test_a_given_unit_the_values_exceed_leaves_a_note(tmp_path: Path) -> None:
    steering = np.array([0.5, 2.0, -3.0, 0.2, 1.5] * 4)  # radians, read as norm
    root = write_udacity(tmp_path / "wheel", steering)
    frames = load_frameset(f"udacity:{root}@unit=norm")
    assert frames.notes == [
        "wheel: 12 of 20 rows have |steering| beyond the norm limit 1 and were skipped; "
        "is unit=norm right for this recording?"
    ]
    assert load_frameset(f"udacity:{root}@unit=rad").notes == []
    assert load_frameset(f"udacity:{root}").notes == []  # auto decides rad itself


# -- percentile thresholds -----------------------------------------------------------------------


def test_percentile_resolved_on_training_frames_is_applied_unchanged_to_test(
    tmp_path: Path,
) -> None:
    train = load_frameset(f"udacity:{write_udacity(tmp_path / 'train', drive(600, 1))}")
    test_root = write_udacity(tmp_path / "test", 3 * drive(300, 2))  # wider turns
    test = load_frameset(f"udacity:{test_root}@threshold=p33")
    cfg = LabelConfig(threshold_quantile=33)
    scale = resolve_quantile_threshold([train], 33, cfg)

    on_train = train.label_info(cfg, train=[train])
    assert on_train.threshold == pytest.approx(scale * DEFAULT_THRESHOLDS["norm"])
    assert on_train.threshold_source == "p33 of the training frames"
    assert np.mean(on_train.labels == STRAIGHT) == pytest.approx(0.33, abs=0.01)

    on_test = test.label_info(LabelConfig(), train=[train])
    assert on_test.threshold == on_train.threshold  # not re-estimated on the test frames
    assert np.mean(on_test.labels == STRAIGHT) < 0.2
    with pytest.raises(ParameterError, match="label test with train="):
        test.label_info()


def test_norm_and_radian_recordings_of_one_drive_pool_to_the_same_labels(
    tmp_path: Path,
) -> None:
    norm = drive(400, 3)
    as_norm = load_frameset(f"udacity:{write_udacity(tmp_path / 'sim', norm)}@unit=norm")
    rad_root = write_udacity(tmp_path / "car", np.round(norm * NORM_TO_RAD, 9))
    as_rad = load_frameset(f"udacity:{rad_root}@unit=rad")
    train = [as_norm, as_rad]
    cfg = LabelConfig(threshold_quantile=40)
    alone = resolve_quantile_threshold([as_norm], 40, cfg)
    assert resolve_quantile_threshold(train, 40, cfg) == pytest.approx(alone, rel=1e-6)
    pooled = as_norm.labels(cfg, train=train)
    np.testing.assert_array_equal(pooled, as_rad.labels(cfg, train=train))
    assert np.mean(pooled == STRAIGHT) == pytest.approx(0.40, abs=0.01)
    np.testing.assert_array_equal(as_norm.labels(), as_rad.labels())  # unit defaults


def test_percentile_needs_training_frames() -> None:
    with pytest.raises(ParameterError, match="training frames"):
        resolve_quantile_threshold([], 33)
