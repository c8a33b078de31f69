"""Direction labels from steering: gap-aware smoothing, thresholds, class balance, usability."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import shared_recording
from qdcnn.config import LabelConfig
from qdcnn.data.labels import (
    DIRECTIONS,
    LEFT,
    RIGHT,
    STRAIGHT,
    check_labels_usable,
    class_balance,
    direction_labels,
    smooth_steering,
)
from qdcnn.data.udacity import load_udacity
from qdcnn.errors import InputError, ParameterError


def reference_smooth(
    x: np.ndarray, t: np.ndarray | None, window: int, max_gap: float
) -> np.ndarray:
    """Per-frame loop: mean over neighbours reachable without crossing a break."""
    out = np.empty_like(x)
    for i in range(len(x)):
        lo = i
        while lo > max(i - window, 0) and (t is None or 0 <= t[lo] - t[lo - 1] <= max_gap):
            lo -= 1
        hi = i
        while hi < min(i + window, len(x) - 1) and (t is None or 0 <= t[hi + 1] - t[hi] <= max_gap):
            hi += 1
        out[i] = x[lo : hi + 1].mean()
    return out


def test_constants_unchanged() -> None:
    assert DIRECTIONS == ("left", "straight", "right")
    assert (LEFT, STRAIGHT, RIGHT) == (0, 1, 2)


def test_smooth_known_answers() -> None:
    np.testing.assert_allclose(
        smooth_steering([0.0, 0.0, 0.9, 0.0, 0.0], window=1), [0.0, 0.3, 0.3, 0.3, 0.0]
    )
    # window 2 on a ramp: edges average the available neighbours only
    np.testing.assert_allclose(smooth_steering([1, 2, 3, 4, 5], window=2), [2, 2.5, 3, 3.5, 4])
    # a window wider than the series is the global mean everywhere
    np.testing.assert_allclose(smooth_steering([1.0, -1.0, 0.5, 0.5], window=10), [0.25] * 4)


def test_window_zero_is_identity() -> None:
    x = np.array([0.05, -0.3, 1.0])
    out = smooth_steering(x, window=0)
    np.testing.assert_array_equal(out, x)
    assert out is not x


def test_gap_splits_segments() -> None:
    steer = [1.0, 1.0, 1.0, -1.0, -1.0, -1.0]
    times = [0.0, 0.1, 0.2, 2.2, 2.3, 2.4]  # 2 s gap between rows 3 and 4
    np.testing.assert_array_equal(smooth_steering(steer, times, window=5), [1, 1, 1, -1, -1, -1])
    # without timestamps (or a gap limit above 2 s) the two halves mix
    np.testing.assert_allclose(smooth_steering(steer, window=5), [0.0] * 6, atol=1e-15)
    np.testing.assert_allclose(smooth_steering(steer, times, window=5, max_gap_s=2.5), [0.0] * 6)


def test_gap_equal_to_limit_and_backwards_time() -> None:
    # a step of exactly max_gap_s stays inside the segment; time going backwards splits
    np.testing.assert_allclose(smooth_steering([1.0, 0.0], [0.0, 1.0], window=1), [0.5, 0.5])
    np.testing.assert_array_equal(smooth_steering([1.0, 0.0], [5.0, 4.9], window=1), [1.0, 0.0])


def test_smooth_matches_loop_reference(rng: np.random.Generator) -> None:
    x = rng.uniform(-1, 1, 400)
    t = np.cumsum(np.where(rng.random(400) < 0.03, 2.0, 0.1))
    for window in (1, 3, 7):
        np.testing.assert_allclose(
            smooth_steering(x, t, window=window), reference_smooth(x, t, window, 1.0), atol=1e-12
        )
    np.testing.assert_allclose(
        smooth_steering(x, window=4), reference_smooth(x, None, 4, 1.0), atol=1e-12
    )


def test_label_thresholds() -> None:
    steer = [-0.06, -0.05, 0.0, 0.05, 0.06]
    np.testing.assert_array_equal(direction_labels(steer, window=0), [0, 1, 1, 1, 2])
    np.testing.assert_array_equal(direction_labels(steer, window=0, threshold=0.0), [0, 0, 1, 2, 2])
    labels = direction_labels(steer, window=0)
    assert labels.dtype == np.int64


def test_labels_use_smoothing() -> None:
    # a keyboard-style bend: one spike of 0.9 among zeros reads "right" across the window
    steer = [0.0, 0.0, 0.0, 0.9, 0.0, 0.0, 0.0]
    np.testing.assert_array_equal(direction_labels(steer, window=0), [1, 1, 1, 2, 1, 1, 1])
    np.testing.assert_array_equal(direction_labels(steer, window=1), [1, 1, 2, 2, 2, 1, 1])


def test_defaults_come_from_label_config() -> None:
    cfg = LabelConfig()
    x = np.zeros(23)
    x[11] = 0.5
    np.testing.assert_array_equal(
        direction_labels(x),
        direction_labels(x, window=cfg.window, max_gap_s=cfg.max_gap_s, threshold=cfg.threshold),
    )
    # window 5 spreads 0.5 / 11 = 0.045 (straight); window 4 gives 0.5 / 9 = 0.056 (right)
    assert class_balance(direction_labels(x)) == {"left": 0, "straight": 23, "right": 0}
    assert class_balance(direction_labels(x, window=4)) == {"left": 0, "straight": 14, "right": 9}


def test_class_balance() -> None:
    assert class_balance([2, 2, 1, 2]) == {"left": 0, "straight": 1, "right": 3}
    assert class_balance(np.array([], dtype=np.int64)) == {"left": 0, "straight": 0, "right": 0}
    with pytest.raises(ParameterError, match="class indices 0, 1 or 2"):
        class_balance([0, 3])


def test_check_labels_usable() -> None:
    check_labels_usable([0, 1, 1], source="rec")  # two classes: fine
    with pytest.raises(InputError) as info:
        check_labels_usable(np.ones(4, dtype=np.int64), source="data/rec")
    assert str(info.value) == (
        "data/rec: all 4 labels are 'straight': accuracy would be meaningless "
        "(a constant guess scores 1.0); use a recording with turns or a smaller threshold"
    )
    with pytest.raises(InputError) as info:
        check_labels_usable([], source="data/rec")
    assert str(info.value) == "data/rec: no labels: there is nothing to evaluate"


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"window": -1}, "window=-1 is invalid: an integer >= 0 (frames on each side)"),
        ({"window": 1.5}, "window=1.5 is invalid: an integer >= 0 (frames on each side)"),
        ({"window": True}, "window=True is invalid: an integer >= 0 (frames on each side)"),
        ({"max_gap_s": 0.0}, "max_gap_s=0.0 is invalid: a number of seconds > 0"),
        ({"max_gap_s": float("nan")}, "max_gap_s=nan is invalid: a number of seconds > 0"),
        ({"threshold": -0.1}, "threshold=-0.1 is invalid: a number in [0, 1)"),
        ({"threshold": 1.0}, "threshold=1.0 is invalid: a number in [0, 1)"),
    ],
)
def test_parameter_errors(kwargs: dict[str, float], message: str) -> None:
    with pytest.raises(ParameterError) as info:
        direction_labels([0.0, 0.1], **kwargs)  # type: ignore[arg-type]
    assert str(info.value) == message


def test_input_shape_errors() -> None:
    with pytest.raises(ParameterError, match="one per steering value"):
        smooth_steering([0.0, 0.1], [0.0])
    with pytest.raises(ParameterError, match="a 1-D array"):
        smooth_steering(np.zeros((2, 2)))
    with pytest.raises(ParameterError, match="finite numbers"):
        smooth_steering([0.0, np.nan])


@pytest.mark.parametrize("name", ["udacity-lake-track", "udacity-mountain-track"])
def test_real_recordings_give_usable_labels(name: str) -> None:
    rec = load_udacity(shared_recording(name))
    labels = direction_labels(rec.steering, rec.timestamps)
    check_labels_usable(labels, source=name)
    counts = class_balance(labels)
    assert all(counts[d] > 0 for d in DIRECTIONS)
    assert sum(counts.values()) == len(rec)
