"""The one evaluation protocol: contiguous folds with a gap, inner search, pooled scores."""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import pytest
from sklearn.base import BaseEstimator, ClassifierMixin

from qdcnn.direction.protocol import (
    ContiguousKFold,
    CrossValidation,
    fit_with_search,
    majority_baseline,
    pooled_accuracy,
    summarise,
)
from qdcnn.errors import InputError, ParameterError


@pytest.mark.parametrize(("n", "k", "gap"), [(100, 5, 0), (103, 4, 5), (50, 10, 2)])
def test_folds_are_contiguous_cover_everything_and_respect_the_gap(
    n: int, k: int, gap: int
) -> None:
    folds = list(ContiguousKFold(k, gap).split(np.arange(n)))
    assert len(folds) == k
    tests = np.concatenate([t for _, t in folds])
    np.testing.assert_array_equal(np.sort(tests), np.arange(n))
    for train, test in folds:
        np.testing.assert_array_equal(test, np.arange(test[0], test[-1] + 1))  # one block
        dist = np.min(np.abs(train[:, None] - test[None, :]), axis=1)
        assert dist.min() > gap  # no training frame within `gap` of the test block
        assert len(train) + len(test) + min(gap, test[0]) + min(gap, n - 1 - test[-1]) == n


def test_blocks_are_those_of_kfold() -> None:
    from sklearn.model_selection import KFold

    ours = [t.tolist() for _, t in ContiguousKFold(4).split(np.arange(103))]
    theirs = [t.tolist() for _, t in KFold(4).split(np.arange(103))]
    assert ours == theirs


@pytest.mark.parametrize(
    ("k", "gap", "message"),
    [
        (1, 0, "folds=1 is invalid"),
        (11, 0, "folds=11 is invalid"),
        (2, -1, "gap=-1 is invalid"),
        (5, 2, "gap=2 is invalid: smaller than the shortest test block \\(2 frames"),
    ],
)
def test_bad_protocols_are_refused(k: int, gap: int, message: str) -> None:
    with pytest.raises(ParameterError, match=message):
        list(ContiguousKFold(k, gap).split(np.arange(10)))


def test_majority_baseline_uses_each_folds_training_majority() -> None:
    y = np.array([0, 0, 0, 1, 1, 1, 1, 1, 2])
    splits = list(ContiguousKFold(3).split(y))
    # fold 1 trains on [1 1 1 1 1 2] -> 1, tests [0 0 0]: 0 hits
    # fold 2 trains on [0 0 0 1 1 2] -> 0, tests [1 1 1]: 0 hits
    # fold 3 trains on [0 0 0 1 1 1] -> 0 (tie, lowest), tests [1 1 2]: 0 hits
    assert majority_baseline(y, splits) == 0.0
    assert pooled_accuracy(y, splits, [np.zeros(3), np.ones(3), np.ones(3)]) == pytest.approx(8 / 9)


def test_summarise_pools_over_test_frames() -> None:
    y = np.array([0, 0, 1, 1, 2, 2, 2])
    splits = [
        (np.array([3, 4, 5, 6]), np.array([0, 1, 2])),
        (np.array([0, 1, 2]), np.array([3, 4, 5, 6])),
    ]
    cv = CrossValidation(
        splits, [np.array([0, 1, 1]), np.array([1, 2, 0, 2])], [{}, {}], seconds=0.1
    )
    r = summarise("image-split-uu", "toy", y, cv, frames_without_lines=1)
    assert r.accuracy == pytest.approx(5 / 7)  # pooled, not the mean of 2/3 and 3/4
    assert r.fold_accuracies == pytest.approx([2 / 3, 3 / 4])
    assert r.accuracy_std == pytest.approx(np.std([2 / 3, 3 / 4]))
    assert r.confusion == [[1, 1, 0], [0, 2, 0], [1, 0, 2]]
    assert r.per_class["left"]["recall"] == 0.5


def test_summarise_notes_each_collapsed_fold_and_seed() -> None:
    y = np.repeat([0, 1, 1, 2], 10)  # fold 1 holds left and straight, fold 2 straight and right
    splits = list(ContiguousKFold(2).split(y))
    one_class = CrossValidation(splits, [np.ones(20, int), y[20:]], [{}, {}], seconds=0.1)
    right = CrossValidation(splits, [y[:20], np.full(20, 2)], [{}, {}], seconds=0.1)
    r = summarise("m", "toy", y, [one_class, right], seeds=(3, 4))
    assert [n for n in r.notes if n.startswith("collapsed")] == [
        "collapsed: 'straight' for 100.0% of fold 1's test frames (seed 3; over 95% of frames "
        "holding two classes with 10% each or more)",
        "collapsed: 'right' for 100.0% of fold 2's test frames (seed 4; over 95% of frames "
        "holding two classes with 10% each or more)",
    ]
    honest = CrossValidation(splits, [y[:20], y[20:]], [{}, {}], seconds=0.1)
    assert not [n for n in summarise("m", "toy", y, honest).notes if "collapsed" in n]


class _Recorder(ClassifierMixin, BaseEstimator):
    """Predicts the majority class; records the rows it was trained on (for the gap test)."""

    seen: ClassVar[list[np.ndarray]] = []

    def __init__(self, c: int = 0) -> None:
        self.c = c

    def fit(self, X, y):
        _Recorder.seen.append(np.asarray(X)[:, 0].astype(int))
        self.classes_ = np.arange(3)
        self.label_ = int(np.bincount(y, minlength=3).argmax())
        return self

    def predict(self, X):
        return np.full(len(X), self.label_)


def test_inner_search_keeps_the_gap_around_its_test_blocks() -> None:
    _Recorder.seen.clear()
    X = np.arange(60)[:, None].astype(float)  # the row index as the only feature
    y = np.repeat([0, 1, 2], 20)
    _, chosen = fit_with_search(_Recorder(), {"c": [0, 1]}, X, y, inner_folds=3, gap=4)
    assert chosen == {"c": 0}
    inner_trains = _Recorder.seen[:6]  # 2 grid values x 3 inner folds, then the refit
    for train in inner_trains:
        left_out = np.setdiff1d(np.arange(60), train)
        assert len(left_out) >= 20 + 4  # a 20-frame test block plus at least one 4-frame gap
    assert len(_Recorder.seen[-1]) == 60  # refit on everything


class _Untrainable(_Recorder):
    """Refuses every training set, as a lane method does when no frame has lines."""

    def fit(self, X, y):
        raise InputError("X", "nothing to train on")


def test_a_search_whose_every_candidate_fails_raises_the_estimators_own_error() -> None:
    X = np.arange(60)[:, None].astype(float)
    y = np.repeat([0, 1, 2], 20)
    with pytest.raises(InputError, match="nothing to train on"):
        fit_with_search(_Untrainable(), {"c": [0, 1]}, X, y, inner_folds=3)
