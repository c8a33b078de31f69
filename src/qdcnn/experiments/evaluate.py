"""Cross-validated direction accuracy: the paper's table, with honest folds.

Folds are contiguous blocks of frames (scikit-learn ``KFold`` without shuffling);
frames within ``gap`` of a test block are also left out of training, because
labels come from steering smoothed over neighbouring frames. Hyperparameters are
chosen by an inner contiguous cross-validation on the training folds only.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sklearn.base import BaseEstimator, clone
from sklearn.metrics import confusion_matrix, precision_recall_fscore_support
from sklearn.model_selection import GridSearchCV, KFold

from qdcnn.config import PipelineConfig
from qdcnn.data.labels import DIRECTIONS, check_labels_usable
from qdcnn.errors import ParameterError

#: The paper's six quantum methods: grouping + classifier.
QUANTUM_METHODS: dict[str, tuple[str, str]] = {
    "image-split-uu": ("image-split", "uu"),
    "kmeans-uu": ("kmeans", "uu"),
    "spectral-uu": ("spectral", "uu"),
    "image-split-vqc": ("image-split", "vqc"),
    "kmeans-vqc": ("kmeans", "vqc"),
    "spectral-vqc": ("spectral", "vqc"),
}
DNN_METHODS: tuple[str, ...] = ("dnn-pilotnet", "dnn-resnet50")
ALL_METHODS: tuple[str, ...] = (*QUANTUM_METHODS, *DNN_METHODS)


def check_method(method: str) -> str:
    if method not in ALL_METHODS and method != "all":
        raise ParameterError("method", method, "one of " + ", ".join((*ALL_METHODS, "all")))
    return method


def contiguous_folds(
    n: int, k: int, gap: int = 0
) -> list[tuple[NDArray[np.intp], NDArray[np.intp]]]:
    """``k`` contiguous test blocks; training leaves out ``gap`` frames on each side of each."""
    if not 2 <= k <= n:
        raise ParameterError("folds", k, f"an integer in [2, {n}] (the number of frames)")
    folds = []
    for _, test in KFold(n_splits=k, shuffle=False).split(np.arange(n)):
        lo, hi = test[0] - gap, test[-1] + gap
        idx = np.arange(n)
        train = idx[(idx < lo) | (idx > hi)]
        folds.append((train, test))
    return folds


def make_classifier(
    kind: str, config: PipelineConfig, seed: int = 0
) -> tuple[BaseEstimator, dict[str, list[Any]]]:
    """The estimator of a quantum method and its hyperparameter grid for the inner CV.

    The estimator reads the two columns of the feature mode ``config.grouping.features``
    (:func:`qdcnn.vision.grouping.mode_columns`) from a feature table computed with
    ``config.grouping.extra_features``; with the paper's mode ("slopes") and no extras the
    table is exactly the two slopes.

    Grids. The paper's mode keeps the original grid (UU: the angle map; VQC: the interpret
    map). The other (named, not the paper's) modes add to the VQC grid the angle span of
    the feature scaling (1 or 0.5) and the ZZ feature map's repetitions (1 or 2), and train
    the VQC from 3 starting points, keeping the lowest training objective
    (``restarts=3``): on the paper's full span the ZZ map's phase reaches ``2 pi^2``, and
    from one start COBYLA often ends worse than the majority class.
    """
    from qdcnn.vision.grouping import mode_columns

    grouping = config.grouping
    columns: tuple[int, int] | None = None
    if grouping.features != "slopes" or grouping.extra_features:
        columns = mode_columns(grouping.features, grouping.extra_features)
    paper = grouping.features == "slopes"
    if kind == "uu":
        from qdcnn.quantum.direction import UUDirectionClassifier

        uu = UUDirectionClassifier(
            straight_margin=config.direction.straight_margin,
            shots=config.direction.shots,
            seed=seed,
            feature_columns=columns,
        )
        return uu, {"angle_map": ["arctan", "minmax"]}
    from qdcnn.quantum.vqc import VQCClassifier

    vqc = VQCClassifier(
        feature_map_reps=config.vqc.feature_map_reps,
        ansatz_reps=config.vqc.ansatz_reps,
        maxiter=config.vqc.maxiter,
        loss=config.vqc.loss,
        shots=config.vqc.shots,
        seed=seed,
        feature_columns=columns,
    )
    grid: dict[str, list[Any]] = {"interpret": ["min2", "mod3"]}
    if not paper:
        vqc.set_params(restarts=3)
        grid["angle_span"] = [1.0, 0.5]
        grid["feature_map_reps"] = sorted({config.vqc.feature_map_reps, 1})
    return vqc, grid


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
    predictions: list[tuple[NDArray[np.intp], NDArray[np.int64]]],
    majority: list[float],
    *,
    frames_without_lines: int,
    seconds: float,
    extra: dict[str, Any] | None = None,
) -> MethodResult:
    """Fold predictions -> accuracy (mean over folds), per-class scores, pooled confusion."""
    accs = [float(np.mean(pred == y[test])) for test, pred in predictions]
    truth = np.concatenate([y[test] for test, _ in predictions])
    pred = np.concatenate([p for _, p in predictions])
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
        float(np.mean(accs)),
        float(np.std(accs)),
        per_class,
        confusion_matrix(truth, pred, labels=[0, 1, 2]).tolist(),
        float(np.mean(majority)),
        frames_without_lines,
        seconds,
        accs,
        extra or {},
    )


def majority_accuracy(y_train: NDArray[np.int64], y_test: NDArray[np.int64]) -> float:
    """Accuracy of always predicting the training folds' most frequent class."""
    return float(np.mean(y_test == np.bincount(y_train, minlength=3).argmax()))


def evaluate_features(
    method: str,
    dataset: str,
    X: NDArray[np.float64],
    y: NDArray[np.int64],
    *,
    config: PipelineConfig | None = None,
    folds: int = 5,
    gap: int = 5,
    inner_folds: int = 3,
    frames_without_lines: int = 0,
    on_fold: Callable[[int], None] | None = None,
) -> MethodResult:
    """Cross-validate one quantum method on precomputed lane features."""
    cfg = config or PipelineConfig()
    _, kind = QUANTUM_METHODS[method]
    check_labels_usable(y, source=dataset)
    t0 = time.perf_counter()
    predictions, majority, chosen = [], [], []
    for i, (train, test) in enumerate(contiguous_folds(len(y), folds, gap)):
        estimator, grid = make_classifier(kind, cfg, seed=cfg.seed)
        model: Any = estimator
        if inner_folds >= 2 and grid:
            model = GridSearchCV(
                clone(estimator), grid, cv=KFold(inner_folds, shuffle=False), error_score=np.nan
            )
        model.fit(X[train], y[train])
        if isinstance(model, GridSearchCV):
            chosen.append(model.best_params_)
        predictions.append((test, np.asarray(model.predict(X[test]), dtype=np.int64)))
        majority.append(majority_accuracy(y[train], y[test]))
        if on_fold:
            on_fold(i)
    return summarise(
        method,
        dataset,
        y,
        predictions,
        majority,
        frames_without_lines=frames_without_lines,
        seconds=time.perf_counter() - t0,
        extra={"chosen_hyperparameters": chosen, "folds": folds, "gap": gap},
    )
