"""Shadow-mask metrics: hand-computed counts and scores, pooling over a set, edge cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from qdcnn.errors import InputError, ParameterError
from qdcnn.vision.metrics import (
    ConfusionCounts,
    ShadowScores,
    confusion_counts,
    score_mask_pairs,
    shadow_scores,
)


def test_confusion_counts_known_answer() -> None:
    pred = np.array([[1, 1, 0, 0], [1, 0, 0, 0]], bool)
    gt = np.array([[1, 0, 1, 0], [1, 1, 1, 0]], bool)
    assert confusion_counts(pred, gt) == ConfusionCounts(tp=2, tn=2, fp=1, fn=3)


def test_uint8_masks_are_binarised_at_128() -> None:
    pred = np.array([[127, 128, 255, 0]], np.uint8)
    gt = np.array([[True, True, False, False]])
    assert confusion_counts(pred, gt) == ConfusionCounts(tp=1, tn=1, fp=1, fn=1)


def test_counts_add_over_a_set() -> None:
    total = ConfusionCounts(1, 2, 3, 4) + ConfusionCounts(10, 20, 30, 40)
    assert total == ConfusionCounts(11, 22, 33, 44)
    assert total.total == 110


def test_scores_hand_computed() -> None:
    s = shadow_scores(ConfusionCounts(tp=8, tn=85, fp=5, fn=2))
    assert s.shadow_error == pytest.approx(20.0)
    assert s.nonshadow_error == pytest.approx(100 * 5 / 90)
    assert s.ber == pytest.approx(100 * (1 - 0.5 * (8 / 10 + 85 / 90)))
    assert s.iou == pytest.approx(100 * 8 / 15)
    assert s.n == 1


def test_counts_are_pooled_not_averaged_per_image() -> None:
    # Image A: perfect (BER 0). Image B: 50 shadow pixels all missed (BER 50).
    # Per-image mean would be 25; pooled: shadow error 50/51, no false positives.
    a = ConfusionCounts(tp=1, tn=99, fp=0, fn=0)
    b = ConfusionCounts(tp=0, tn=50, fp=0, fn=50)
    s = shadow_scores([a, b])
    assert s.ber == pytest.approx(0.5 * 100 * 50 / 51)
    assert s.n == 2
    assert shadow_scores([a, b], n=7).n == 7


def test_trivial_predictions_have_ber_50() -> None:
    gt = np.zeros((10, 10), bool)
    gt[:3] = True
    assert shadow_scores(confusion_counts(np.ones_like(gt), gt)).ber == 50
    assert shadow_scores(confusion_counts(np.zeros_like(gt), gt)).ber == 50


def test_no_shadow_in_ground_truth_uses_the_nonshadow_side() -> None:
    s = shadow_scores(ConfusionCounts(tp=0, tn=90, fp=10, fn=0))
    assert math.isnan(s.shadow_error)
    assert s.nonshadow_error == pytest.approx(10.0)
    assert s.ber == pytest.approx(10.0)
    assert s.iou == 0.0


def test_no_shadow_anywhere_has_zero_ber_and_undefined_iou() -> None:
    s = shadow_scores(ConfusionCounts(tp=0, tn=100, fp=0, fn=0))
    assert s.ber == 0.0
    assert math.isnan(s.iou)
    assert math.isnan(s.shadow_error)


def test_all_shadow_ground_truth_uses_the_shadow_side() -> None:
    s = shadow_scores(ConfusionCounts(tp=75, tn=0, fp=0, fn=25))
    assert math.isnan(s.nonshadow_error)
    assert s.ber == pytest.approx(25.0)
    assert s.iou == pytest.approx(75.0)


def test_to_dict() -> None:
    s = ShadowScores(ber=1.0, shadow_error=2.0, nonshadow_error=0.0, iou=90.0, n=3)
    assert s.to_dict() == {
        "ber": 1.0,
        "shadow_error": 2.0,
        "nonshadow_error": 0.0,
        "iou": 90.0,
        "n": 3,
    }


def test_score_mask_pairs_pools_pairs() -> None:
    rng = np.random.default_rng(1)
    pairs = [(rng.random((6, 9)) < 0.4, rng.random((6, 9)) < 0.3) for _ in range(4)]
    expected = shadow_scores([confusion_counts(p, g) for p, g in pairs])
    assert score_mask_pairs(iter(pairs)) == expected
    assert expected.n == 4


def test_shape_mismatch_names_both_shapes_and_the_source() -> None:
    with pytest.raises(
        InputError,
        match=r"^frame_07\.png: predicted mask shape \(2, 3\) differs from "
        r"ground-truth shape \(3, 2\)$",
    ):
        confusion_counts(np.zeros((2, 3), bool), np.zeros((3, 2), bool), source="frame_07.png")


def test_score_mask_pairs_names_the_bad_pair() -> None:
    good = (np.zeros((2, 2), bool), np.zeros((2, 2), bool))
    bad = (np.zeros((2, 2), bool), np.zeros((2, 3), bool))
    with pytest.raises(InputError, match=r"^pair 1: predicted mask shape"):
        score_mask_pairs([good, bad])


@pytest.mark.parametrize(
    ("mask", "message"),
    [
        (np.zeros((2, 2), np.float64), "mask: expected a bool or uint8 mask, got float64"),
        (
            np.zeros((2, 2, 3), np.uint8),
            r"mask: expected a 2-D mask \(H, W\), got shape \(2, 2, 3\)",
        ),
    ],
)
def test_bad_masks_raise_input_error(mask: np.ndarray, message: str) -> None:
    with pytest.raises(InputError, match=f"^{message}$"):
        confusion_counts(mask, np.zeros((2, 2), bool))


def test_invalid_counts_raise_parameter_error() -> None:
    with pytest.raises(ParameterError, match=r"^counts=\[\] is invalid"):
        shadow_scores([])
    with pytest.raises(ParameterError, match="counts of at least one pixel"):
        shadow_scores(ConfusionCounts(0, 0, 0, 0))
    with pytest.raises(ParameterError, match="^fp=-1 is invalid"):
        ConfusionCounts(1, 1, -1, 1)
    with pytest.raises(ParameterError, match="^n=-2 is invalid"):
        shadow_scores(ConfusionCounts(1, 1, 1, 1), n=-2)
