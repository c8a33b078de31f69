"""Contiguous folds, majority baseline and result bookkeeping of the evaluation harness."""

from __future__ import annotations

import numpy as np
import pytest

from qdcnn.errors import InputError, ParameterError
from qdcnn.experiments.evaluate import (
    QUANTUM_METHODS,
    contiguous_folds,
    evaluate_features,
    majority_accuracy,
    summarise,
)


@pytest.mark.parametrize(("n", "k", "gap"), [(100, 5, 0), (103, 4, 5), (50, 10, 2)])
def test_folds_are_contiguous_cover_everything_and_respect_the_gap(
    n: int, k: int, gap: int
) -> None:
    folds = contiguous_folds(n, k, gap)
    assert len(folds) == k
    tests = np.concatenate([t for _, t in folds])
    np.testing.assert_array_equal(np.sort(tests), np.arange(n))
    for train, test in folds:
        np.testing.assert_array_equal(test, np.arange(test[0], test[-1] + 1))  # one block
        dist = np.min(np.abs(train[:, None] - test[None, :]), axis=1)
        assert dist.min() > gap  # no training frame within `gap` of the test block
        assert len(train) + len(test) + min(gap, test[0]) + min(gap, n - 1 - test[-1]) == n


def test_bad_fold_counts() -> None:
    with pytest.raises(ParameterError, match="folds=1 is invalid"):
        contiguous_folds(10, 1)
    with pytest.raises(ParameterError, match="folds=11 is invalid"):
        contiguous_folds(10, 11)


def test_majority_baseline_uses_training_majority() -> None:
    assert majority_accuracy(np.array([0, 0, 1]), np.array([0, 1, 1, 1])) == 0.25


def test_summarise_known_answer() -> None:
    y = np.array([0, 0, 1, 1, 2, 2])
    preds = [(np.array([0, 1, 2]), np.array([0, 1, 1])), (np.array([3, 4, 5]), np.array([1, 2, 0]))]
    r = summarise(
        "image-split-uu", "toy", y, preds, [0.5, 0.0], frames_without_lines=1, seconds=0.1
    )
    assert r.accuracy == pytest.approx((2 / 3 + 2 / 3) / 2)
    assert r.confusion == [[1, 1, 0], [0, 2, 0], [1, 0, 1]]
    assert r.per_class["left"]["recall"] == 0.5
    assert r.majority_baseline == 0.25
    assert set(r.to_dict()) >= {
        "method",
        "dataset",
        "n",
        "accuracy",
        "accuracy_std",
        "per_class",
        "confusion",
        "majority_baseline",
        "frames_without_lines",
        "seconds",
    }


def test_evaluate_learns_separable_features(rng: np.random.Generator) -> None:
    # slopes that follow the road geometry: left bends tilt both lines one way, right the other
    y = np.repeat([0, 1, 2, 1, 0, 2, 1, 2, 0, 1], 30)
    shift = np.array([-0.6, 0.0, 0.6])[y]
    X = np.column_stack([-1.0 + shift, 1.0 + shift]) + rng.normal(0, 0.08, (y.size, 2))
    # the 4-weight VQC cannot fit this as well as the geometric UU rule; both beat chance (1/3)
    for method, floor in (("image-split-uu", 0.9), ("image-split-vqc", 0.6)):
        r = evaluate_features(method, "toy", X, y, folds=5, gap=2)
        assert r.accuracy > floor, method
        assert len(r.extra["chosen_hyperparameters"]) == 5


def test_single_class_labels_are_an_error() -> None:
    with pytest.raises(InputError, match="all 20 labels are 'straight'"):
        evaluate_features("kmeans-vqc", "flat", np.zeros((20, 2)), np.ones(20, np.int64))


def test_paper_has_six_quantum_methods() -> None:
    assert len(QUANTUM_METHODS) == 6
    assert {k for _, k in QUANTUM_METHODS.values()} == {"uu", "vqc"}
