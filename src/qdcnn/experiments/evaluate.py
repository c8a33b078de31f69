"""``qdcnn evaluate``: direction scores with intervals, the paper's accuracy table.

Every method of the registry (:mod:`qdcnn.direction.methods`) is evaluated by the one
protocol of :mod:`qdcnn.direction.protocol`: contiguous folds with a gap, the method's
hyperparameters chosen by an inner contiguous CV (with the gap) on the training folds
only, scores pooled over all test frames in frame order: balanced accuracy (the main
figure), accuracy, macro-F1, per-class recall, confusion, with 95 % block-bootstrap
intervals and the training-majority baseline. Lane methods read the cached lane features
of the readable frames; frame methods (CNNs) read the frames themselves. ``--seeds K``
retrains every model K times (figures are means over the seeds), ``--paired`` compares
methods on the same frames, and each finished fold is kept in the cache
(:mod:`qdcnn.experiments.result_cache`) so a stopped run resumes. Training on some
recordings and testing on others: :mod:`qdcnn.experiments.evaluate_cross`.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._optional import has_gpu, has_torch
from qdcnn._validation import check_int
from qdcnn.batch import Failure
from qdcnn.config import PipelineConfig
from qdcnn.data.frames import FrameSet, load_frameset
from qdcnn.data.labels import Quantile, check_labels_usable
from qdcnn.direction.frame_cache import method_inputs
from qdcnn.direction.lane_data import LaneData, load_lane_data
from qdcnn.direction.methods import (
    FRAME_FRONTS,
    HYBRID_KINDS,
    DirectionMethod,
    TrainingOptions,
    balanced_applies,
    check_fit_settings,
    check_inner_search,
    classical_recipe,
    cnn_params,
    get_method,
    option_notes,
    select_methods,
    standardise_applies,
)
from qdcnn.direction.protocol import (
    RESAMPLES,
    ContiguousKFold,
    CrossValidation,
    MethodResult,
    cross_validate,
    summarise,
)
from qdcnn.errors import InputError, ParameterError
from qdcnn.experiments.result_cache import UnitStore, unit_key
from qdcnn.outputs import file_identity
from qdcnn.runtime.reporting import Reporter

__all__ = [
    "EvaluationResult",
    "EvaluationSpec",
    "add_failures",
    "array_digest",
    "evaluate_features",
    "evaluate_frames",
    "fold_store",
    "label_summary",
    "method_seeds",
    "options_key",
    "paired_comparisons",
    "run_evaluation",
    "seed_matters",
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
    seeds: int = 1,
    use_cache: bool = False,
) -> MethodResult:
    """Cross-validate one lane method on precomputed lane features ``X`` with labels ``y``.

    ``executor`` (:class:`~qdcnn.runtime.scheduler.Executor`) runs the folds on a
    Dask cluster; the result is the same as in this process. ``seeds`` runs every fold
    with the config's seed and the ``seeds - 1`` after it (one run for a method without
    randomness); ``use_cache`` keeps each finished fold in the cache, so a stopped run
    resumes (:mod:`qdcnn.experiments.result_cache`).
    """
    m = get_method(method) if isinstance(method, str) else method
    cfg = config or PipelineConfig()
    check_labels_usable(y, source=dataset)
    run_seeds, notes = method_seeds(m, cfg, None, seeds)
    protocol = {"folds": folds, "gap": gap, "inner_folds": inner_folds}
    cvs = _seeded_runs(m, cfg, None, X, y, protocol, run_seeds, executor, use_cache)
    result = summarise(
        m.name,
        dataset,
        np.asarray(y, dtype=np.int64),
        cvs,
        frames_without_lines=frames_without_lines,
        extra={"chosen_hyperparameters": cvs[0].chosen, "folds": folds, "gap": gap},
        seeds=run_seeds,
    )
    result.notes[:0] = notes
    return result


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
    seeds: int = 1,
    use_cache: bool = False,
) -> tuple[MethodResult, list[Failure]]:
    """Cross-validate one frame method (a CNN) on the readable frames of ``frames``.

    Each fold trains a fresh estimator on the training frames (its early stopping
    validates on frames of those, never on the test block) and predicts the test block;
    a method with a grid (``hog-logreg``; the CNNs have none) chooses from it by the
    inner contiguous CV of ``inner_folds`` on the training frames. ``seeds`` and
    ``use_cache`` as in :func:`evaluate_features`; with ``use_cache`` a CNN's frames are
    decoded and resized once per recording and input size
    (:func:`qdcnn.direction.frame_cache.network_frames`) and read back by later methods
    and runs.

    Returns
    -------
    result : MethodResult
    failures : list of Failure
        Unreadable frames (left out) and frames of another size than the first.
    """
    m = get_method(method) if isinstance(method, str) else method
    cfg = config or PipelineConfig()
    opts = options or TrainingOptions()
    notes: list[str] = []
    images, readable, failures = method_inputs(
        m, cfg, opts, frames, use_cache=use_cache, on_note=notes.append
    )
    keep = np.flatnonzero(readable)
    y = np.asarray(labels, dtype=np.int64)[keep]
    check_labels_usable(y, source=frames.spec)
    run_seeds, seed_notes = method_seeds(m, cfg, opts, seeds)
    notes += seed_notes
    protocol = {"folds": folds, "gap": gap, "inner_folds": inner_folds}
    x = images if len(keep) == len(images) else images[keep]
    cvs = _seeded_runs(m, cfg, opts, x, y, protocol, run_seeds, executor, use_cache)
    extra: dict[str, Any] = {
        "chosen_hyperparameters": cvs[0].chosen,
        "folds": folds,
        "gap": gap,
        "epochs": opts.epochs,
        "weights": None if opts.weights is None else str(opts.weights),
        "epochs_run": cvs[0].epochs_run,
        "settings": _settings(m.estimator(cfg, opts)[0]),
    }
    result = summarise(m.name, frames.name, y, cvs, extra=extra, seeds=run_seeds)
    result.notes[:0] = notes
    return result, failures


def _seeded_runs(
    m: DirectionMethod,
    cfg: PipelineConfig,
    opts: TrainingOptions | None,
    X: NDArray[Any],
    y: NDArray[np.int64],
    protocol: dict[str, int],
    seeds: list[int],
    executor: Any,
    use_cache: bool,
) -> list[CrossValidation]:
    """One cross-validation of ``m`` per seed (the config's seed replaced), folds kept."""
    runs = []
    data = array_digest(X, y)  # hashing frames is costly: once, not per seed
    for seed in seeds:
        seeded = replace(cfg, seed=seed)
        store = fold_store(m, seeded, opts, protocol, data, use_cache)
        build = _Build(m, seeded, opts)
        folds, gap, inner = protocol["folds"], protocol["gap"], protocol["inner_folds"]
        runs.append(
            cross_validate(
                build, X, y, folds=folds, gap=gap, inner_folds=inner, executor=executor, store=store
            )
        )
    return runs


def method_seeds(
    m: DirectionMethod, config: PipelineConfig, options: TrainingOptions | None, seeds: int
) -> tuple[list[int], list[str]]:
    """The seeds ``m`` runs with (``config.seed`` and the ``seeds - 1`` after it), and a note
    when the method has no randomness (then one run: more seeds would repeat it)."""
    check_int("seeds", seeds, 1, 1000)
    if seeds == 1:
        return [config.seed], []
    if not seed_matters(m, config, options):
        return [config.seed], [f"{m.name} has no randomness: seeds do not apply (one run)"]
    return [config.seed + k for k in range(seeds)], []


def seed_matters(
    m: DirectionMethod, config: PipelineConfig, options: TrainingOptions | None
) -> bool:
    """Whether ``m``'s estimator changes with the seed.

    Its parameters are compared under two seeds; the UU-dagger rule uses its seed only
    for shot sampling, so with exact probabilities (``shots=None``) it is deterministic.
    """
    a = m.estimator(config, options)[0].get_params()
    b = m.estimator(replace(config, seed=config.seed + 1), options)[0].get_params()
    differ = {k for k in a if repr(a[k]) != repr(b.get(k))}
    if differ == {"seed"} and m.kind == "uu" and a.get("shots") is None:
        return False
    return bool(differ)


def fold_store(
    m: DirectionMethod,
    config: PipelineConfig,
    options: TrainingOptions | None,
    protocol: dict[str, Any],
    data: str,
    use_cache: bool,
) -> UnitStore:
    """Where the folds of ``m`` on the data of digest ``data`` (:func:`array_digest` of
    ``X, y``) with ``config`` (and its seed) are kept."""
    key = unit_key(
        kind="k-fold",
        method=m.name,
        config=config.to_dict(),
        options=None if options is None else options_key(options, m),
        protocol=protocol,
        data=data,
    )
    return UnitStore(key, use_cache)


def options_key(options: TrainingOptions, m: DirectionMethod) -> dict[str, Any]:
    """The training options that change ``m``'s result (not threads or progress), as
    resolved: ``--balanced`` and the same ``params`` give one key; ``--transfer`` and
    ``--from`` change only a hybrid's, and so does ``--balanced`` through its stage 1."""
    params = cnn_params(options) if m.kind == "cnn" else options.params
    key: dict[str, Any] = {
        "epochs": options.epochs,
        "weights": None if options.weights is None else str(options.weights),
        "context": options.context,
        "params": {k: repr(v) for k, v in params.items()},
    }
    for front in FRAME_FRONTS:  # absent when off: old keys hold
        if getattr(options, front) and standardise_applies(m):
            key[front] = True
    if m.kind in HYBRID_KINDS:
        key["transfer"] = options.transfer
        if balanced_applies(m, options):  # under --transfer, PilotNet is its stage 1
            key["stage_1"] = {k: repr(v) for k, v in classical_recipe(options).items()}
        trunk = options.from_model
        key["from"] = None if trunk is None else file_identity(trunk, content_hash=True)["sha256"]
    return key


def array_digest(*arrays: NDArray[Any]) -> str:
    """A hash of arrays' shapes, types and bytes (the data part of a unit's key)."""
    h = hashlib.sha256()
    for a in arrays:
        c = np.ascontiguousarray(a)
        h.update(f"{c.shape}{c.dtype}".encode())
        h.update(c.tobytes())
    return h.hexdigest()[:32]


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
        if k not in ("progress", "checkpoint_dir", "trunk_cache")
    }


@dataclass(frozen=True)
class EvaluationSpec:
    """What ``qdcnn evaluate`` runs.

    Attributes
    ----------
    data : str
        Dataset spec (``udacity:PATH``, ``carla:PATH``, ``synthetic:PRESET[:N]``) of the
        k-fold protocol (``""`` with ``train``/``test`` or ``leave_one_out``).
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
    train, test : tuple of str
        Cross-recording protocol: train on all ``train`` recordings together, score every
        ``test`` recording (:mod:`qdcnn.experiments.evaluate_cross`).
    leave_one_out : tuple of str
        Each recording the test set in turn, trained on the others.
    seeds : int
        Runs per model: the config's seed and the ``seeds - 1`` after it.
    paired : bool
        Compare each method after the first with the first on the same test frames.
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
    train: tuple[str, ...] = ()
    test: tuple[str, ...] = ()
    leave_one_out: tuple[str, ...] = ()
    seeds: int = 1
    paired: bool = False

    def __post_init__(self) -> None:
        check_int("folds", self.folds, 2, 10_000)
        check_fit_settings(self.gap, self.inner_folds, self.training)
        check_int("seeds", self.seeds, 1, 1000)
        if bool(self.train) != bool(self.test):
            raise ParameterError(
                "test" if self.train else "train", "none", "given with --train/--test"
            )
        if self.leave_one_out and len(set(self.leave_one_out)) < 2:
            raise ParameterError(
                "data", ",".join(self.leave_one_out), "two recordings or more for leave-one-out"
            )
        if sum(map(bool, (self.data, self.train, self.leave_one_out))) != 1:
            raise ParameterError(
                "data", self.data or "none", "one of --data, --train/--test or leave-one-out"
            )

    def recording_splits(self) -> list[tuple[tuple[str, ...], tuple[str, ...]]]:
        """``(training specs, test specs)`` of the cross-recording protocols (empty: k-fold)."""
        if self.train:
            return [(self.train, self.test)]
        recs = self.leave_one_out
        return [(tuple(r for r in recs if r != t), (t,)) for t in recs]


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
    comparisons: list[dict[str, Any]] = field(default_factory=list)
    trained_on: list[list[str]] = field(default_factory=list)
    tested_on: list[str] = field(default_factory=list)

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
            "comparisons": self.comparisons,
            "trained_on": self.trained_on,
            "tested_on": self.tested_on,
        }


def run_evaluation(spec: EvaluationSpec, reporter: Reporter | None = None) -> EvaluationResult:
    """Evaluate the methods of ``spec`` on its dataset; each result is reported as it finishes."""
    report = reporter or Reporter()
    methods, notes = select_methods(
        spec.methods,
        has_torch=has_torch() if spec.has_torch is None else spec.has_torch,
        has_gpu=has_gpu() if spec.has_gpu is None else spec.has_gpu,
    )
    notes += option_notes(methods, spec.training)
    for note in notes:
        report.note(note)
    spec = with_trunk_cache(spec)
    if spec.recording_splits():
        from qdcnn.experiments.evaluate_cross import run_cross_evaluation

        result = run_cross_evaluation(spec, methods, report)
    else:
        result = _run_k_fold(spec, methods, report)
    result.notes[:0] = notes
    result.comparisons = paired_comparisons(result.results, spec.paired, spec.config.seed)
    for c in result.comparisons:
        report.note(f"{c['a']} - {c['b']} on {c['dataset']}: {c['text']}")
    return result


def with_trunk_cache(spec: EvaluationSpec) -> EvaluationSpec:
    """``spec`` with transfer's stage-1 trunks kept in the cache too (when the cache is on
    and hybrids train with ``--transfer``), so a resumed run does not train them again.
    The folder is per code version, like every cached result."""
    from qdcnn.direction.features import cache_dir, code_fingerprint

    training = spec.training
    if not (spec.use_cache and training.transfer) or training.trunk_cache is not None:
        return spec
    folder = cache_dir() / "trunks" / code_fingerprint()
    return replace(spec, training=replace(training, trunk_cache=folder))


def _run_k_fold(
    spec: EvaluationSpec, methods: list[DirectionMethod], report: Reporter
) -> EvaluationResult:
    """Contiguous folds inside the one recording ``spec.data``."""
    frames = load_frameset(
        spec.data, seed=spec.config.seed, steering_unit=spec.config.labels.steering_unit
    )
    if isinstance(frames.threshold_request(spec.config.labels), Quantile):
        raise ParameterError(
            "data",
            spec.data,
            "a fixed label threshold within one recording: a percentile (pNN) is taken from "
            "training recordings (--train/--test or --protocol leave-one-out)",
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
            "seeds": spec.seeds,
        },
    )
    add_failures(result, [Failure(p.source, str(p)) for p in frames.problems], report)
    result.labels = label_summary(frames, spec.config, report)
    # before any work: one class left (always fatal later), then an inner search that cannot run
    check_labels_usable(frames.labels(spec.config.labels), source=frames.spec)
    splits = ContiguousKFold(spec.folds, spec.gap).split(np.zeros(len(frames)))
    shortest = min(len(train) for train, _ in splits)
    where = f"the shortest training set of --folds {spec.folds}"
    check_inner_searches(spec, methods, shortest, where)
    with executor_for(spec.scheduler) as executor:
        _evaluate_all(spec, frames, methods, result, report, executor)
    return result


def check_inner_searches(
    spec: EvaluationSpec, methods: Sequence[DirectionMethod], n_train: int, frames_from: str
) -> None:
    """Refuse ``--inner-folds``/``--gap`` that leave no inner search on ``n_train`` training
    frames (:func:`~qdcnn.direction.methods.check_inner_search`), before any work; methods
    without a grid to search are not concerned."""
    if any(m.estimator(spec.config, spec.training)[1] for m in methods):
        check_inner_search(n_train, spec.inner_folds, spec.gap, frames_from=frames_from)


def paired_comparisons(
    results: list[MethodResult], paired: bool, seed: int
) -> list[dict[str, Any]]:
    """Balanced-accuracy differences on the same test frames, with paired intervals.

    With ``paired``, each method after the first against the first; always each hybrid
    against its classical twin and against each of its head ablations evaluated with it.
    One group per test set.
    """
    from qdcnn.models.specs import hybrid_of

    out: list[dict[str, Any]] = []
    groups: dict[tuple[str, str], list[MethodResult]] = {}
    for r in results:
        groups.setdefault((r.dataset, repr(r.extra.get("trained_on"))), []).append(r)
    for group in groups.values():
        by_name = {r.method: r for r in group}
        pairs = [(r, group[0]) for r in group[1:]] if paired else []
        for r in group:
            h = hybrid_of(r.method)
            if h is None or h.name != r.method:
                continue
            for other in (h.twin, *(name for name, _ in h.ablations)):
                if other in by_name:
                    pairs.append((r, by_name[other]))
        seen: set[tuple[str, str]] = set()
        for a, b in pairs:
            if (a.method, b.method) not in seen:
                seen.add((a.method, b.method))
                out.append(_difference(a, b, seed))
    return out


def _difference(a: MethodResult, b: MethodResult, seed: int) -> dict[str, Any]:
    """``a``'s balanced accuracy minus ``b``'s on their common test frames (or why not)."""
    from qdcnn.direction.scores import format_with_interval, paired_difference

    row: dict[str, Any] = {"a": a.method, "b": b.method, "dataset": a.dataset}
    if a.test_labels != b.test_labels:
        return {**row, "value": None, "interval": None, "text": "not the same test frames"}
    try:
        d = paired_difference(
            a.test_labels, a.predictions, b.predictions, resamples=RESAMPLES, seed=seed
        )
    except InputError as err:
        return {**row, "value": None, "interval": None, "text": f"no comparison: {err}"}
    text = format_with_interval(d.value, d.interval)
    return {**row, **d.to_dict(), "text": text if d.value < 0 else "+" + text}


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
            add_failures(result, lanes.table.failures, report)
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
                seeds=spec.seeds,
                use_cache=spec.use_cache,
            )
            add_failures(result, failures, report)
            res.extra["labels"] = result.labels
            result.results.append(res)
            report.result(res.to_dict())
            method_done()


def label_summary(
    frames: FrameSet,
    config: PipelineConfig,
    report: Reporter,
    train: Sequence[FrameSet] | None = None,
) -> dict[str, Any]:
    """How the labels were made (unit, threshold, classes); a note when the unit is guessed.

    ``train``: the training recordings a percentile threshold (``@threshold=pNN``) is
    taken from."""
    info = frames.label_info(config.labels, train=train)
    if info.unit.assumed:
        report.note(f"{frames.name}: steering unit {info.unit.describe()}")
    return {**info.to_dict(), "class_balance": info.counts(), "description": info.describe()}


def add_failures(result: EvaluationResult, failures: list[Failure], report: Reporter) -> None:
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
        seeds=spec.seeds,
        use_cache=spec.use_cache,
    )
    res.extra["pipeline_ms_per_frame"] = 1e3 * lanes.table.seconds_per_frame
    return res
