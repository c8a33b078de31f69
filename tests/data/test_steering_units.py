"""Steering units: the auto rule on synthetic values, per-unit thresholds, labels that say how."""

from __future__ import annotations

import math

import numpy as np
import pytest

from qdcnn.data.labels import (
    AUTO_RAD_MAX,
    DEFAULT_THRESHOLDS,
    SteeringUnit,
    class_balance,
    direction_labels,
    infer_steering_unit,
    label_directions,
    resolve_steering_unit,
)
from qdcnn.errors import ParameterError


def wheel_angles(n: int, rng: np.random.Generator, scale: float = 0.2) -> np.ndarray:
    """Steering-wheel angles in radians as a CAN sensor gives them: multiples of 0.1 degree."""
    tenths = np.round(rng.normal(0.0, math.degrees(scale) * 10, n))
    return np.radians(tenths / 10)


def keyboard_steering(n: int, rng: np.random.Generator) -> np.ndarray:
    """Simulator-like normalised steering: mostly zero, smooth ramps, never saturating."""
    x = np.zeros(n)
    x[n // 4 : n // 2] = rng.uniform(-0.6, 0.6, n // 2 - n // 4)
    return x


def test_default_thresholds_are_one_road_wheel_angle() -> None:
    assert DEFAULT_THRESHOLDS["norm"] == 0.05
    # 0.05 x 25 degrees at the road wheels x a 15:1 steering ratio
    assert DEFAULT_THRESHOLDS["deg"] == pytest.approx(18.75)
    assert DEFAULT_THRESHOLDS["rad"] == pytest.approx(math.radians(18.75))


def test_simulator_names_mean_norm_whatever_the_values(rng: np.random.Generator) -> None:
    decided = infer_steering_unit(wheel_angles(200, rng), simulator_names=True)
    assert decided == SteeringUnit(
        "norm", "auto", "Udacity simulator image names (center_YYYY_...)"
    )


def test_values_beyond_one_are_radians_then_degrees(rng: np.random.Generator) -> None:
    rad = infer_steering_unit([0.5, -2.0, 4.0, 3.0, 0.0])
    assert rad == SteeringUnit("rad", "auto", "3 values beyond +-1, up to 4")
    deg = infer_steering_unit(rng.uniform(-90.0, 90.0, 300))
    assert deg.unit == "deg"
    assert "beyond +-9.42 (1.5 wheel turns)" in deg.reason
    # a full-lock angle in radians stays radians: 3 pi is the boundary
    assert infer_steering_unit([AUTO_RAD_MAX] * 5 + [0.1] * 5).unit == "rad"


def test_a_few_outliers_do_not_change_the_unit(rng: np.random.Generator) -> None:
    x = keyboard_steering(400, rng)
    x[[10, 20]] = [5.0, -7.0]  # two corrupt rows, under max(3, 1 %) = 4
    assert infer_steering_unit(x).unit == "norm"
    x[[30, 40]] = [2.0, 3.0]  # four: now evidence of an angle
    assert infer_steering_unit(x).unit == "rad"


def test_sensor_quantised_radians_are_recognised_below_one(rng: np.random.Generator) -> None:
    x = wheel_angles(500, rng)
    assert np.abs(x).max() < 1
    decided = infer_steering_unit(x)
    assert decided.unit == "rad" and not decided.assumed
    assert "whole multiples of 0.1 degree in radians" in decided.reason
    # the same magnitudes without the quantisation carry no such evidence
    jitter = x + rng.uniform(1e-5, 2e-5, x.size)
    assert infer_steering_unit(jitter).assumed


def test_norm_evidence_and_the_honest_fallback(rng: np.random.Generator) -> None:
    saturating = keyboard_steering(300, rng)
    saturating[5] = -1.0
    decided = infer_steering_unit(saturating)
    assert decided.unit == "norm" and not decided.assumed
    fallback = infer_steering_unit(keyboard_steering(300, rng))
    assert fallback.unit == "norm" and fallback.assumed
    assert "pass steering unit rad or deg" in fallback.reason
    # too few non-zero values to judge quantisation
    assert infer_steering_unit(np.radians([0.1, 0.2, 0.0, 0.0])).assumed


def test_resolve_given_units_and_bad_names() -> None:
    assert resolve_steering_unit("deg", [0.1]) == SteeringUnit("deg", "deg", "given", False)
    with pytest.raises(ParameterError) as info:
        resolve_steering_unit("degrees", [0.1])
    assert str(info.value) == ("steering_unit='degrees' is invalid: one of auto, norm, rad, deg")


def test_label_directions_reports_unit_and_threshold() -> None:
    steer = np.radians([-30.0, -10.0, 0.0, 10.0, 30.0])  # steering-wheel angles
    out = label_directions(steer, unit="rad", window=0)
    assert out.labels.tolist() == [0, 1, 1, 1, 2]  # 18.75 degrees is the default threshold
    assert out.threshold == pytest.approx(math.radians(18.75))
    assert out.threshold_source == "default" and out.unit.unit == "rad"
    assert out.describe() == (
        "labels: steering in rad (given), threshold 0.3272 rad (default), smoothed over +-0 frames"
    )
    given = label_directions(steer, unit="rad", threshold=0.1, window=0)
    assert given.labels.tolist() == [0, 0, 1, 2, 2]
    assert given.to_dict()["label_threshold"] == 0.1
    assert given.to_dict()["label_threshold_source"] == "given"
    # read as norm (the old behaviour) the same values give other labels
    assert direction_labels(steer, window=0).tolist() == [0, 0, 1, 2, 2]


def test_label_directions_accepts_a_decided_unit() -> None:
    decided = SteeringUnit("deg", "auto", "12 values beyond +-9.42 (1.5 wheel turns)")
    out = label_directions([-40.0, 5.0, 40.0], unit=decided, window=0)
    assert out.labels.tolist() == [0, 1, 2] and out.unit is decided
    assert out.to_dict()["steering_unit_reason"] == decided.reason


@pytest.mark.parametrize(
    ("unit", "threshold", "message"),
    [
        ("norm", 1.0, "threshold=1.0 is invalid: a number in [0, 1)"),
        ("rad", 16.0, "threshold=16.0 is invalid: a number in [0, 15.708) rad"),
        ("deg", -1.0, "threshold=-1.0 is invalid: a number in [0, 900) deg"),
        ("deg", True, "threshold=True is invalid: a number in [0, 900) deg"),
        ("grad", 0.1, "unit='grad' is invalid: one of 'norm', 'rad', 'deg'"),
    ],
)
def test_threshold_range_is_per_unit(unit: str, threshold: float, message: str) -> None:
    with pytest.raises(ParameterError) as info:
        direction_labels([0.0, 0.1], unit=unit, threshold=threshold)
    assert str(info.value) == message


def test_thresholds_beyond_one_work_for_angles() -> None:
    labels = direction_labels([-40.0, 0.0, 25.0], unit="deg", threshold=30.0, window=0)
    assert class_balance(labels) == {"left": 1, "straight": 2, "right": 0}
