"""The paper's DNN row: CNN baselines under the same contiguous folds as the quantum methods."""

from __future__ import annotations

import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from qdcnn.data.frames import FrameSet, stack_images
from qdcnn.experiments.evaluate import MethodResult, contiguous_folds, majority_accuracy, summarise

ARCH_OF: dict[str, Literal["pilotnet", "resnet50"]] = {
    "dnn-pilotnet": "pilotnet",
    "dnn-resnet50": "resnet50",
}


def evaluate_cnn(
    method: str,
    frames: FrameSet,
    labels: NDArray[np.int64],
    *,
    folds: int = 5,
    gap: int = 5,
    epochs: int = 25,
    weights: Path | None = None,
    seed: int = 0,
    progress: bool = True,
    num_threads: int | None = None,
    params: Mapping[str, Any] | None = None,
) -> MethodResult:
    """Train and test a CNN baseline on each contiguous fold; same folds as the quantum methods.

    Each fold trains a fresh :class:`~qdcnn.models.training.CNNDirectionClassifier` on
    the training frames (early stopping uses the last frames of those, never the
    test block) and predicts the test block.

    Parameters
    ----------
    method : {"dnn-pilotnet", "dnn-resnet50"}
        The network.
    frames : FrameSet
        The recording; unreadable frames are left out and reported in ``extra["failures"]``.
    labels : (N,) int ndarray
        Direction per frame.
    folds, gap : int
        Contiguous folds and the frames left out of training on each side of a test block.
    epochs : int
        Maximum epochs per fold (the paper: 25).
    weights : path or None
        Initial weights (ImageNet ``state_dict`` for ResNet-50).
    seed : int
        Training seed (the same for every fold).
    progress : bool
        Rich progress bar per fold.
    num_threads : int or None
        torch CPU threads (default: the CPUs this process may run on, so
        ``taskset -c 0 qdcnn evaluate ...`` trains on one thread).
    params : mapping or None
        Further classifier settings (``lr``, ``class_weight``, ``tta``, ...) for studies.

    Returns
    -------
    MethodResult
        Accuracy over folds, per-class scores, pooled confusion and majority baseline.
    """
    from qdcnn.models.training import CNNDirectionClassifier

    t0 = time.perf_counter()
    images, readable, failures = stack_images(frames)
    keep = np.flatnonzero(readable)
    x, y = images[keep], labels[keep]
    predictions, majority, histories = [], [], []
    settings: dict[str, Any] = {}
    for train, test in contiguous_folds(len(y), folds, gap):
        model = CNNDirectionClassifier(
            ARCH_OF[method],
            epochs=epochs,
            weights=weights,
            seed=seed,
            progress=progress,
            num_threads=num_threads,
            **dict(params or {}),
        )
        model.fit(x[train], y[train])
        predictions.append((test, np.asarray(model.predict(x[test]), dtype=np.int64)))
        majority.append(majority_accuracy(y[train], y[test]))
        histories.append(getattr(model, "history_", []))
        settings = {
            k: str(v) if isinstance(v, Path) else list(v) if isinstance(v, tuple) else v
            for k, v in model.get_params().items()
            if k not in ("progress", "checkpoint_dir")
        }
    result = summarise(
        method,
        frames.name,
        y,
        predictions,
        majority,
        frames_without_lines=0,
        seconds=time.perf_counter() - t0,
        extra={
            "folds": folds,
            "gap": gap,
            "epochs": epochs,
            "weights": None if weights is None else str(weights),
            "epochs_run": [len(h) for h in histories],
            "settings": settings,
            "failures": failures,
        },
    )
    return result
