"""The one evaluation protocol: contiguous folds with a gap, inner model selection, scores.

Frames of a recording are a video: neighbours are near duplicates, and direction
labels come from steering smoothed over neighbouring frames. So every split here is a
:class:`ContiguousKFold`: contiguous test blocks, with ``gap`` frames on each side of a
block left out of training. The same splitter serves the outer folds, the inner
hyperparameter search on the training folds (:func:`fit_with_search`, with the gap
too) and any validation split taken from training frames.

Scores (one definition everywhere)
    *accuracy* is pooled over all test frames: correct test predictions over test
    frames, every frame tested exactly once (:func:`pooled_accuracy`); the spread is the
    standard deviation of the per-fold accuracies. The *majority baseline* predicts, in
    each fold, the most frequent class of that fold's training frames, pooled the same way
    (:func:`majority_baseline`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from sklearn.base import BaseEstimator, clone
from sklearn.metrics import confusion_matrix, precision_recall_fscore_support
from sklearn.model_selection import GridSearchCV

from qdcnn.data.labels import DIRECTIONS
from qdcnn.data.splits import ContiguousKFold, Split
from qdcnn.errors import ParameterError

__all__ = [
    "ContiguousKFold",
    "CrossValidation",
    "MethodResult",
    "cross_validate",
    "fit_with_search",
    "majority_baseline",
    "pooled_accuracy",
    "summarise",
]

_N_CLASSES = len(DIRECTIONS)


def fit_with_search(
    estimator: BaseEstimator,
    grid: Mapping[str, Sequence[Any]],
    X: ArrayLike,
    y: NDArray[np.int64],
    *,
    inner_folds: int = 3,
    gap: int = 0,
) -> tuple[Any, dict[str, Any]]:
    """Fit ``estimator``, first choosing its ``grid`` values by inner contiguous CV.

    The search (``GridSearchCV`` over :class:`ContiguousKFold` ``(inner_folds, gap)`` on
    ``X`` itself, accuracy as the score, refit on all of ``X``) runs when the grid is not
    empty, ``inner_folds >= 2`` and every inner block is longer than the gap; otherwise the
    estimator is fitted with its own parameters.

    Returns
    -------
    fitted : estimator
        The refitted best estimator (or the plainly fitted one).
    chosen : dict
        The chosen grid values (empty without a search).
    """
    n = len(y)
    inner = ContiguousKFold(inner_folds, gap)
    searchable = bool(grid) and inner_folds >= 2 and n // max(inner_folds, 1) > gap
    if not searchable:
        return clone(estimator).fit(X, y), {}
    search = GridSearchCV(clone(estimator), dict(grid), cv=inner, error_score=np.nan)
    try:
        search.fit(X, y)
    except ValueError:  # every candidate failed: raise the estimator's own error if it has one
        clone(estimator).fit(X, y)
        raise
    return search.best_estimator_, dict(search.best_params_)


@dataclass
class CrossValidation:
    """What :func:`cross_validate` produced: per fold the split, predictions and choices."""

    splits: list[Split]
    predictions: list[NDArray[np.int64]]
    chosen: list[dict[str, Any]]
    estimators: list[Any] = field(default_factory=list)
    seconds: float = 0.0


def cross_validate(
    build: Callable[[], tuple[BaseEstimator, Mapping[str, Sequence[Any]]]],
    X: ArrayLike,
    y: NDArray[np.int64],
    *,
    folds: int = 5,
    gap: int = 5,
    inner_folds: int = 3,
    keep_estimators: bool = False,
    on_fold: Callable[[int], None] | None = None,
    executor: Any = None,
) -> CrossValidation:
    """Train and test one method on each contiguous fold.

    Parameters
    ----------
    build : callable
        Returns a fresh ``(estimator, grid)`` (the method registry's
        :meth:`~qdcnn.direction.methods.DirectionMethod.build`).
    X : array_like
        Lane features ``(N, F)`` or frames ``(N, H, W, 3)``; indexed by row.
    y : ndarray of int
        Direction labels.
    folds, gap, inner_folds : int
        The protocol (module docstring); ``inner_folds < 2`` skips the inner search.
    keep_estimators : bool
        Keep each fold's fitted estimator (noise sweeps predict with them again).
    on_fold : callable, optional
        Called with the fold index after each fold.
    executor : Executor, optional
        Where the folds run (:class:`qdcnn.runtime.scheduler.Executor`: this
        process, or workers of a Dask cluster); the results are the same either way.
    """
    y = np.asarray(y, dtype=np.int64)
    splits = list(ContiguousKFold(folds, gap).split(y))
    x = np.asarray(X) if not isinstance(X, np.ndarray) else X
    t0 = time.perf_counter()
    tasks = [(i, train, test) for i, (train, test) in enumerate(splits)]
    done: dict[int, tuple[NDArray[np.int64], dict[str, Any], Any]] = {}
    if executor is None:
        for task in tasks:
            done[task[0]] = _fit_fold(task, build, x, y, inner_folds, gap)
            if on_fold:
                on_fold(task[0])
    else:
        for task, outcome in executor.map_unordered(
            _fit_fold, tasks, build, x, y, inner_folds, gap
        ):
            if hasattr(outcome, "error") and hasattr(outcome, "kind"):  # a TaskFailure
                raise ParameterError("fold", task[0] + 1, f"a fold that trains ({outcome.error})")
            done[task[0]] = outcome
            if on_fold:
                on_fold(task[0])
    out = CrossValidation(splits, [], [])
    for i in range(len(splits)):
        predictions, chosen, fitted = done[i]
        out.predictions.append(predictions)
        out.chosen.append(chosen)
        if keep_estimators:
            out.estimators.append(fitted)
    out.seconds = time.perf_counter() - t0
    return out


def _fit_fold(
    task: tuple[int, NDArray[np.intp], NDArray[np.intp]],
    build: Callable[[], tuple[BaseEstimator, Mapping[str, Sequence[Any]]]],
    x: NDArray[Any],
    y: NDArray[np.int64],
    inner_folds: int,
    gap: int,
) -> tuple[NDArray[np.int64], dict[str, Any], Any]:
    """One fold: choose and fit on the training rows, predict the test rows."""
    _, train, test = task
    estimator, grid = build()
    fitted, chosen = fit_with_search(
        estimator, grid, x[train], y[train], inner_folds=inner_folds, gap=gap
    )
    return np.asarray(fitted.predict(x[test]), dtype=np.int64), chosen, fitted


def pooled_accuracy(
    y: NDArray[np.int64], splits: Sequence[Split], predictions: Sequence[Any]
) -> float:
    """Correct test predictions over all test frames (each frame is tested once)."""
    hits = sum(
        int(np.sum(np.asarray(p) == y[test]))
        for (_, test), p in zip(splits, predictions, strict=True)
    )
    return hits / max(sum(len(test) for _, test in splits), 1)


def majority_baseline(y: NDArray[np.int64], splits: Sequence[Split]) -> float:
    """Pooled accuracy of predicting each fold's training majority class."""
    majority = [
        np.full(len(test), np.bincount(y[train], minlength=_N_CLASSES).argmax())
        for train, test in splits
    ]
    return pooled_accuracy(y, splits, majority)


@dataclass
class MethodResult:
    """Cross-validated accuracy of one method on one dataset (the ``--json`` object)."""

    method: str
    dataset: str
    n: int
    accuracy: float
    accuracy_std: float
    per_class: dict[str, dict[str, float]]
    confusion: list[list[int]]
    majority_baseline: float
    frames_without_lines: int
    seconds: float
    fold_accuracies: list[float]
    extra: dict[str, Any]

    def to_dict(self) -> dict[str, Any]:
        return {
            "method": self.method,
            "dataset": self.dataset,
            "n": self.n,
            "accuracy": self.accuracy,
            "accuracy_std": self.accuracy_std,
            "per_class": self.per_class,
            "confusion": self.confusion,
            "majority_baseline": self.majority_baseline,
            "frames_without_lines": self.frames_without_lines,
            "seconds": self.seconds,
            "fold_accuracies": self.fold_accuracies,
            **self.extra,
        }


def summarise(
    method: str,
    dataset: str,
    y: NDArray[np.int64],
    cv: CrossValidation,
    *,
    frames_without_lines: int = 0,
    extra: Mapping[str, Any] | None = None,
) -> MethodResult:
    """Fold predictions -> pooled accuracy, fold spread, per-class scores, pooled confusion."""
    accs = [
        float(np.mean(p == y[test])) for (_, test), p in zip(cv.splits, cv.predictions, strict=True)
    ]
    truth = np.concatenate([y[test] for _, test in cv.splits])
    pred = np.concatenate(cv.predictions)
    p, r, f, s = precision_recall_fscore_support(truth, pred, labels=[0, 1, 2], zero_division=0)
    per_class = {
        name: {
            "precision": float(p[i]),
            "recall": float(r[i]),
            "f1": float(f[i]),
            "support": int(s[i]),
        }
        for i, name in enumerate(DIRECTIONS)
    }
    return MethodResult(
        method,
        dataset,
        int(truth.size),
        pooled_accuracy(y, cv.splits, cv.predictions),
        float(np.std(accs)),
        per_class,
        confusion_matrix(truth, pred, labels=[0, 1, 2]).tolist(),
        majority_baseline(y, cv.splits),
        frames_without_lines,
        cv.seconds,
        accs,
        dict(extra or {}),
    )
