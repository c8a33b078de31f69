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
    *balanced accuracy* (the main figure), macro-F1, per-class recall and the confusion
    come from :func:`qdcnn.direction.scores.score` on the pooled test predictions in frame
    order, with 95 % circular block-bootstrap intervals (:func:`score_runs`); with ``K``
    seeds each figure is the mean over the seeds' runs on the same frames.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from sklearn.base import BaseEstimator, clone
from sklearn.metrics import precision_recall_fscore_support
from sklearn.model_selection import GridSearchCV

from qdcnn.data.labels import DIRECTIONS
from qdcnn.data.splits import ContiguousKFold, Split
from qdcnn.errors import ParameterError

__all__ = [
    "RESAMPLES",
    "ContiguousKFold",
    "CrossValidation",
    "MethodResult",
    "cross_validate",
    "fit_with_search",
    "majority_baseline",
    "pooled_accuracy",
    "score_runs",
    "summarise",
]

_N_CLASSES = len(DIRECTIONS)
#: Bootstrap resamples of every interval.
RESAMPLES = 1000


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
    epochs_run: list[int] = field(default_factory=list)


class FoldStore:
    """Where finished folds are kept so an interrupted run resumes (no-op here).

    :meth:`get` gives a fold's ``(predictions, chosen, epochs_run)`` or ``None``;
    :meth:`put` keeps one. ``qdcnn.experiments.evaluate`` keeps them in the cache.
    """

    def get(self, fold: int | str) -> tuple[NDArray[np.int64], dict[str, Any], int] | None:
        return None

    def put(
        self, fold: int | str, predictions: NDArray[np.int64], chosen: dict[str, Any], epochs: int
    ) -> None:
        return None


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
    store: FoldStore | None = None,
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
    store : FoldStore, optional
        Folds already done are read from it and each new one is put in it as it ends;
        their estimators are ``None``.
    """
    y = np.asarray(y, dtype=np.int64)
    splits = list(ContiguousKFold(folds, gap).split(y))
    x = np.asarray(X) if not isinstance(X, np.ndarray) else X
    t0 = time.perf_counter()
    keep = store or FoldStore()
    done: dict[int, tuple[NDArray[np.int64], dict[str, Any], Any]] = {}
    epochs: dict[int, int] = {}
    for i in range(len(splits)):
        hit = keep.get(i)
        if hit is not None:
            done[i], epochs[i] = (hit[0], hit[1], None), hit[2]
    tasks = [(i, train, test) for i, (train, test) in enumerate(splits) if i not in done]

    def finish(i: int, outcome: tuple[NDArray[np.int64], dict[str, Any], Any]) -> None:
        done[i], epochs[i] = outcome, len(getattr(outcome[2], "history_", []))
        keep.put(i, outcome[0], outcome[1], epochs[i])
        if on_fold:
            on_fold(i)

    if executor is None:
        for task in tasks:
            finish(task[0], _fit_fold(task, build, x, y, inner_folds, gap))
    else:
        for task, outcome in executor.map_unordered(
            _fit_fold, tasks, build, x, y, inner_folds, gap
        ):
            if hasattr(outcome, "error") and hasattr(outcome, "kind"):  # a TaskFailure
                raise ParameterError("fold", task[0] + 1, f"a fold that trains ({outcome.error})")
            finish(task[0], outcome)
    out = CrossValidation(splits, [], [])
    for i in range(len(splits)):
        predictions, chosen, fitted = done[i]
        out.predictions.append(np.asarray(predictions, dtype=np.int64))
        out.chosen.append(chosen)
        out.epochs_run.append(epochs[i])
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
    """Scores of one method on one set of test frames (the ``--json`` object).

    ``accuracy``, ``balanced_accuracy`` (the main figure), ``macro_f1``, ``per_class``
    and ``confusion`` are pooled over the test frames (summed over seeds for the
    confusion, averaged over seeds for the rest); ``*_ci`` are their 95 % block-bootstrap
    intervals; ``predictions`` holds, per seed, the prediction of every test frame in
    frame order and ``test_labels`` their labels (for paired comparisons).
    """

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
    balanced_accuracy: float | None = None
    macro_f1: float = 0.0
    accuracy_ci: dict[str, Any] | None = None
    balanced_accuracy_ci: dict[str, Any] | None = None
    majority: dict[str, Any] = field(default_factory=dict)
    seeds: list[int] = field(default_factory=lambda: [0])
    notes: list[str] = field(default_factory=list)
    predictions: list[list[int]] = field(default_factory=list)
    test_labels: list[int] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {
            "method": self.method,
            "dataset": self.dataset,
            "n": self.n,
            "accuracy": self.accuracy,
            "accuracy_std": self.accuracy_std,
            "accuracy_ci": self.accuracy_ci,
            "balanced_accuracy": self.balanced_accuracy,
            "balanced_accuracy_ci": self.balanced_accuracy_ci,
            "macro_f1": self.macro_f1,
            "per_class": self.per_class,
            "confusion": self.confusion,
            "majority_baseline": self.majority_baseline,
            "majority": self.majority,
            "chance_balanced_accuracy": 1 / _N_CLASSES,
            "frames_without_lines": self.frames_without_lines,
            "seconds": self.seconds,
            "fold_accuracies": self.fold_accuracies,
            "seeds": self.seeds,
            "notes": self.notes,
            **self.extra,
            "test_labels": self.test_labels,
            "predictions": self.predictions,
        }


def score_runs(
    truth: NDArray[np.int64],
    runs: NDArray[np.int64],
    majority: NDArray[np.int64],
    *,
    seed: int = 0,
    resamples: int = RESAMPLES,
) -> dict[str, Any]:
    """Scores of ``runs`` ``(K, N)`` (seeds) on labels ``truth`` ``(N,)`` in frame order.

    Returns the :class:`MethodResult` fields ``accuracy``, ``balanced_accuracy``,
    ``macro_f1``, ``per_class``, ``confusion``, ``accuracy_ci``,
    ``balanced_accuracy_ci``, ``majority`` (the same scores of the constant ``majority``
    predictions) and ``notes`` (why a figure or interval is missing).
    """
    from qdcnn.direction.scores import score

    runs = np.atleast_2d(np.asarray(runs, dtype=np.int64))
    k = runs.shape[0]
    each = [score(truth, run) for run in runs]
    pooled = score(np.tile(truth, k), runs.ravel())
    notes = [f"balanced accuracy is undefined: {pooled.undefined}"] if pooled.undefined else []
    intervals, why = _intervals(truth, runs, seed, resamples, pooled.undefined is None)
    notes += why
    majority_scores = score(truth, majority)
    return {
        "accuracy": pooled.accuracy,
        "balanced_accuracy": pooled.balanced_accuracy,
        "macro_f1": float(np.mean([s.macro_f1 for s in each])),
        "per_class": _per_class(np.tile(truth, k), runs.ravel()),
        "confusion": [list(row) for row in pooled.confusion],
        **intervals,
        "majority": {
            "what": "the training frames' most frequent class, predicted for every test frame",
            "accuracy": majority_scores.accuracy,
            "balanced_accuracy": majority_scores.balanced_accuracy,
            "macro_f1": majority_scores.macro_f1,
        },
        "notes": notes,
    }


def _intervals(
    truth: NDArray[np.int64], runs: NDArray[np.int64], seed: int, resamples: int, defined: bool
) -> tuple[dict[str, Any], list[str]]:
    """95 % block-bootstrap intervals of accuracy and balanced accuracy (``None`` if not)."""
    from qdcnn.direction.scores import block_bootstrap
    from qdcnn.errors import InputError

    out: dict[str, Any] = {"accuracy_ci": None, "balanced_accuracy_ci": None}
    metrics = ("accuracy", "balanced_accuracy") if defined else ("accuracy",)
    try:
        for metric in metrics:
            iv = block_bootstrap(truth, runs, metric, resamples=resamples, seed=seed)
            out[f"{metric}_ci"] = iv.to_dict()
    except InputError as err:
        return out, [f"no interval: {err}"]
    return out, []


def _per_class(truth: NDArray[np.int64], pred: NDArray[np.int64]) -> dict[str, dict[str, float]]:
    p, r, f, s = precision_recall_fscore_support(truth, pred, labels=[0, 1, 2], zero_division=0)
    return {
        name: {
            "precision": float(p[i]),
            "recall": float(r[i]),
            "f1": float(f[i]),
            "support": int(s[i]),
        }
        for i, name in enumerate(DIRECTIONS)
    }


def summarise(
    method: str,
    dataset: str,
    y: NDArray[np.int64],
    cv: CrossValidation | Sequence[CrossValidation],
    *,
    frames_without_lines: int = 0,
    extra: Mapping[str, Any] | None = None,
    seeds: Sequence[int] = (0,),
) -> MethodResult:
    """Fold predictions -> pooled scores with intervals, fold spread, pooled confusion.

    ``cv`` is one cross-validation, or one per seed of ``seeds`` (same splits, as many as
    seeds); the first seed also seeds the bootstrap.
    """
    runs = [cv] if isinstance(cv, CrossValidation) else list(cv)
    splits = runs[0].splits
    accs = np.mean(
        [
            [
                float(np.mean(p == y[test]))
                for (_, test), p in zip(splits, r.predictions, strict=True)
            ]
            for r in runs
        ],
        axis=0,
    ).tolist()
    truth = np.concatenate([y[test] for _, test in splits])
    order = np.argsort(np.concatenate([test for _, test in splits]), kind="stable")
    preds = np.stack([np.concatenate(r.predictions)[order] for r in runs])
    majority = np.concatenate(
        [
            np.full(len(test), np.bincount(y[train], minlength=_N_CLASSES).argmax())
            for train, test in splits
        ]
    )[order]
    scored = score_runs(truth[order], preds, majority, seed=seeds[0])
    tests = [test for _, test in splits]
    scored["notes"] += collapse_notes(y, tests, [r.predictions for r in runs], seeds)
    return MethodResult(
        method,
        dataset,
        int(truth.size),
        float(np.mean([pooled_accuracy(y, splits, r.predictions) for r in runs])),
        float(np.std(accs)),
        scored.pop("per_class"),
        scored.pop("confusion"),
        majority_baseline(y, splits),
        frames_without_lines,
        sum(r.seconds for r in runs),
        accs,
        dict(extra or {}),
        seeds=list(seeds),
        predictions=preds.tolist(),
        test_labels=truth[order].tolist(),
        **{k: v for k, v in scored.items() if k != "accuracy"},
    )


def collapse_notes(
    y: NDArray[np.int64],
    blocks: Sequence[NDArray[np.intp]],
    runs: Sequence[Sequence[NDArray[np.int64]]],
    seeds: Sequence[int],
    names: Sequence[str] | None = None,
) -> list[str]:
    """A note for each seed and test block where one answer covers nearly all frames of a
    block that holds several classes (:func:`~qdcnn.direction.scores.collapsed`).

    ``blocks`` are the test frames' indices into ``y``; ``runs`` hold, per seed of
    ``seeds`` (one run each), the predictions of every block; ``names`` say what each
    block is (default: ``fold 1's test frames`` ...).
    """
    from qdcnn.direction.scores import COLLAPSE_SHARE, PRESENT_SHARE, collapsed, one_answer_share

    names = names or [f"fold {i + 1}'s test frames" for i in range(len(blocks))]
    notes = []
    for seed, predictions in zip(seeds, runs, strict=True):
        for name, test, p in zip(names, blocks, predictions, strict=True):
            if collapsed(y[test], p):
                share = one_answer_share(y[test], p)[0]
                answer = DIRECTIONS[int(np.bincount(p, minlength=_N_CLASSES).argmax())]
                notes.append(
                    f"collapsed: '{answer}' for {share:.1%} of {name} (seed "
                    f"{seed}; over {COLLAPSE_SHARE:.0%} of frames holding two classes with "
                    f"{PRESENT_SHARE:.0%} each or more)"
                )
    return notes
