"""``qdcnn evaluate``: cross-validated direction accuracy, the paper's accuracy table.

Every method of the registry (:mod:`qdcnn.direction.methods`) is evaluated by the one
protocol of :mod:`qdcnn.direction.protocol`: contiguous folds with a gap, the method's
hyperparameters chosen by an inner contiguous CV (with the gap) on the training folds
only, accuracy pooled over all test frames. Lane methods read the cached lane features of
the readable frames; frame methods (CNNs) read the frames themselves.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._optional import has_gpu, has_torch
from qdcnn._validation import check_int
from qdcnn.batch import Failure
from qdcnn.config import PipelineConfig
from qdcnn.data.frames import FrameSet, load_frameset, stack_images
from qdcnn.data.images import require_file
from qdcnn.data.labels import check_labels_usable
from qdcnn.direction.lane_data import LaneData, load_lane_data
from qdcnn.direction.methods import (
    DirectionMethod,
    TrainingOptions,
    get_method,
    select_methods,
)
from qdcnn.direction.protocol import (
    ContiguousKFold,
    MethodResult,
    cross_validate,
    summarise,
)
from qdcnn.runtime.reporting import Reporter

__all__ = [
    "EvaluationResult",
    "EvaluationSpec",
    "evaluate_features",
    "evaluate_frames",
    "run_evaluation",
]


def evaluate_features(
    method: str | DirectionMethod,
    dataset: str,
    X: NDArray[np.float64],
    y: NDArray[np.int64],
    *,
    config: PipelineConfig | None = None,
    folds: int = 5,
    gap: int = 5,
    inner_folds: int = 3,
    frames_without_lines: int = 0,
    executor: Any = None,
) -> MethodResult:
    """Cross-validate one lane method on precomputed lane features ``X`` with labels ``y``.

    ``executor`` (:class:`~qdcnn.runtime.scheduler.Executor`) runs the folds on a
    Dask cluster; the result is the same as in this process.
    """
    m = get_method(method) if isinstance(method, str) else method
    cfg = config or PipelineConfig()
    check_labels_usable(y, source=dataset)
    cv = cross_validate(
        _Build(m, cfg), X, y, folds=folds, gap=gap, inner_folds=inner_folds, executor=executor
    )
    return summarise(
        m.name,
        dataset,
        np.asarray(y, dtype=np.int64),
        cv,
        frames_without_lines=frames_without_lines,
        extra={"chosen_hyperparameters": cv.chosen, "folds": folds, "gap": gap},
    )


def evaluate_frames(
    method: str | DirectionMethod,
    frames: FrameSet,
    labels: NDArray[np.int64],
    *,
    config: PipelineConfig | None = None,
    options: TrainingOptions | None = None,
    folds: int = 5,
    gap: int = 5,
    inner_folds: int = 3,
    executor: Any = None,
) -> tuple[MethodResult, list[Failure]]:
    """Cross-validate one frame method (a CNN) on the readable frames of ``frames``.

    Each fold trains a fresh estimator on the training frames (its early stopping
    validates on frames of those, never on the test block) and predicts the test block;
    a method with a grid (``hog-logreg``; the CNNs have none) chooses from it by the
    inner contiguous CV of ``inner_folds`` on the training frames.

    Returns
    -------
    result : MethodResult
    failures : list of Failure
        Unreadable frames (left out) and frames of another size than the first.
    """
    m = get_method(method) if isinstance(method, str) else method
    cfg = config or PipelineConfig()
    opts = options or TrainingOptions()
    images, readable, failures = stack_images(frames)
    keep = np.flatnonzero(readable)
    y = np.asarray(labels, dtype=np.int64)[keep]
    check_labels_usable(y, source=frames.spec)
    cv = cross_validate(
        _Build(m, cfg, opts),
        images[keep],
        y,
        folds=folds,
        gap=gap,
        inner_folds=inner_folds,
        keep_estimators=True,
        executor=executor,
    )
    extra: dict[str, Any] = {
        "chosen_hyperparameters": cv.chosen,
        "folds": folds,
        "gap": gap,
        "epochs": opts.epochs,
        "weights": None if opts.weights is None else str(opts.weights),
        "epochs_run": [len(getattr(e, "history_", [])) for e in cv.estimators],
        "settings": _settings(cv.estimators[-1]) if cv.estimators else {},
    }
    return summarise(m.name, frames.name, y, cv, extra=extra), failures


@dataclass(frozen=True)
class _Build:
    """A picklable ``build()``: the method's fresh estimator and grid (folds may run on Dask)."""

    method: DirectionMethod
    config: PipelineConfig
    options: TrainingOptions | None = None

    def __call__(self) -> tuple[Any, Any]:
        return self.method.estimator(self.config, self.options)


def _settings(estimator: Any) -> dict[str, Any]:
    params = estimator.get_params()
    return {
        k: str(v) if hasattr(v, "__fspath__") else list(v) if isinstance(v, tuple) else v
        for k, v in params.items()
        if k not in ("progress", "checkpoint_dir")
    }


@dataclass(frozen=True)
class EvaluationSpec:
    """What ``qdcnn evaluate`` runs.

    Attributes
    ----------
    data : str
        Dataset spec (``udacity:PATH``, ``carla:PATH``, ``synthetic:PRESET[:N]``).
    methods : str
        A registered method, a comma list, or ``"all"``.
    config : PipelineConfig
        Pipeline and classifier settings (``PipelineConfig.from_options``).
    folds, gap, inner_folds : int
        The protocol of :mod:`qdcnn.direction.protocol`.
    training : TrainingOptions
        Settings of frame methods (epochs, weights, threads).
    use_cache : bool
        Reuse cached lane features.
    has_torch, has_gpu : bool or None
        What ``all`` may include; ``None`` asks the installation.
    scheduler : str or None
        Where the folds run: ``None`` (this process), ``local:N`` or ``tcp://HOST:PORT``
        (:class:`~qdcnn.runtime.scheduler.Executor`, the ``dask`` extra).
    """

    data: str
    methods: str = "all"
    config: PipelineConfig = field(default_factory=PipelineConfig)
    folds: int = 5
    gap: int = 5
    inner_folds: int = 3
    training: TrainingOptions = field(default_factory=TrainingOptions)
    use_cache: bool = True
    has_torch: bool | None = None
    has_gpu: bool | None = None
    scheduler: str | None = None

    def __post_init__(self) -> None:
        check_int("folds", self.folds, 2, 10_000)
        check_int("gap", self.gap, 0, 10_000)
        if self.inner_folds != 0:
            check_int("inner_folds", self.inner_folds, 2, 100)
        if self.training.weights is not None:
            require_file(self.training.weights, "weights file")


@dataclass
class EvaluationResult:
    """Scores of every method on one dataset, and what was skipped."""

    dataset: str
    n_frames: int
    protocol: dict[str, Any]
    results: list[MethodResult] = field(default_factory=list)
    failures: list[Failure] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    labels: dict[str, Any] = field(default_factory=dict)
    camera: dict[str, Any] | None = None

    @property
    def exit_code(self) -> int:
        """0 when every frame and method worked, 1 when some items failed."""
        return 1 if self.failures else 0

    def to_dict(self) -> dict[str, Any]:
        return {
            "dataset": self.dataset,
            "n_frames": self.n_frames,
            "protocol": self.protocol,
            "results": [r.to_dict() for r in self.results],
            "failures": [f.to_dict() for f in self.failures],
            "notes": self.notes,
            "labels": self.labels,
            "camera": self.camera,
        }


def run_evaluation(spec: EvaluationSpec, reporter: Reporter | None = None) -> EvaluationResult:
    """Evaluate the methods of ``spec`` on its dataset; each result is reported as it finishes."""
    report = reporter or Reporter()
    methods, notes = select_methods(
        spec.methods,
        has_torch=has_torch() if spec.has_torch is None else spec.has_torch,
        has_gpu=has_gpu() if spec.has_gpu is None else spec.has_gpu,
    )
    for note in notes:
        report.note(note)
    frames = load_frameset(
        spec.data, seed=spec.config.seed, steering_unit=spec.config.labels.steering_unit
    )
    ContiguousKFold(spec.folds, spec.gap).check(len(frames))
    result = EvaluationResult(
        frames.name,
        len(frames),
        {
            "folds": spec.folds,
            "gap": spec.gap,
            "inner_folds": spec.inner_folds,
            "scheduler": spec.scheduler,
        },
        notes=notes,
    )
    _add_failures(result, [Failure(p.source, str(p)) for p in frames.problems], report)
    result.labels = label_summary(frames, spec.config, report)
    with executor_for(spec.scheduler) as executor:
        _evaluate_all(spec, frames, methods, result, report, executor)
    return result


def executor_for(scheduler: str | None) -> Any:
    """A context giving the :class:`~qdcnn.runtime.scheduler.Executor` of ``scheduler``
    (``None``: no executor, everything in this process)."""
    from contextlib import nullcontext

    if scheduler is None:
        return nullcontext(None)
    from qdcnn.runtime.scheduler import Executor

    return Executor(scheduler)


def _evaluate_all(
    spec: EvaluationSpec,
    frames: FrameSet,
    methods: list[DirectionMethod],
    result: EvaluationResult,
    report: Reporter,
    executor: Any,
) -> None:
    with report.progress(len(methods), f"methods on {frames.name}") as method_done:
        lane_methods = [m for m in methods if m.inputs == "lanes"]
        if lane_methods:
            lanes = _lane_data(spec, frames, lane_methods, report)
            _add_failures(result, lanes.table.failures, report)
            result.camera = lanes.table.camera
            for note in lanes.camera_notes():
                report.note(note)
            for m in lane_methods:
                res = _evaluate_lane_method(spec, m, lanes, executor)
                res.extra["labels"] = result.labels
                result.results.append(res)
                report.result(res.to_dict())
                method_done()
        for m in (m for m in methods if m.inputs == "frames"):
            res, failures = evaluate_frames(
                m,
                frames,
                frames.labels(spec.config.labels),
                config=spec.config,
                options=spec.training,
                folds=spec.folds,
                gap=spec.gap,
                inner_folds=spec.inner_folds,
                executor=executor,
            )
            _add_failures(result, failures, report)
            res.extra["labels"] = result.labels
            result.results.append(res)
            report.result(res.to_dict())
            method_done()


def label_summary(frames: FrameSet, config: PipelineConfig, report: Reporter) -> dict[str, Any]:
    """How the labels were made (unit, threshold, classes); a note when the unit is guessed."""
    info = frames.label_info(config.labels)
    if info.unit.assumed:
        report.note(f"{frames.name}: steering unit {info.unit.describe()}")
    return {**info.to_dict(), "class_balance": info.counts(), "description": info.describe()}


def _add_failures(result: EvaluationResult, failures: list[Failure], report: Reporter) -> None:
    """Record and report the failures of items not failed already (by file)."""
    seen = {f.file for f in result.failures}
    for f in failures:
        if f.file not in seen:
            seen.add(f.file)
            result.failures.append(f)
            report.failure(f)


def _lane_data(
    spec: EvaluationSpec, frames: FrameSet, methods: list[DirectionMethod], report: Reporter
) -> LaneData:
    groupings = sorted({m.grouping for m in methods if m.grouping is not None})
    with report.progress(len(frames), f"lane features ({frames.name})") as advance:
        return load_lane_data(
            frames, spec.config, groupings, use_cache=spec.use_cache, on_frame=advance
        )


def _evaluate_lane_method(
    spec: EvaluationSpec, m: DirectionMethod, lanes: LaneData, executor: Any = None
) -> MethodResult:
    assert m.grouping is not None
    res = evaluate_features(
        m,
        lanes.frames.name,
        lanes.features(m.grouping),
        lanes.y,
        config=spec.config,
        folds=spec.folds,
        gap=spec.gap,
        inner_folds=spec.inner_folds,
        frames_without_lines=lanes.table.frames_without_lines(m.grouping),
        executor=executor,
    )
    res.extra["pipeline_ms_per_frame"] = 1e3 * lanes.table.seconds_per_frame
    return res
