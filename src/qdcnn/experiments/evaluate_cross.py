"""``qdcnn evaluate --train ... --test ...``: train on some recordings, score others.

Each method is trained once per seed on all training recordings together: lane methods
on the cached lane features of every training recording, concatenated in the order
given, their hyperparameters chosen by the inner contiguous search (with the gap) on
those frames; frame methods (CNNs, hybrids) on the stacked frames, validating on
training frames only. Every test recording is then scored on its own, with the
metrics and block-bootstrap intervals of :func:`qdcnn.direction.protocol.score_runs`.
Each recording is labelled with its own steering unit and threshold
(``FrameSet.label_info``); a percentile threshold (``@threshold=pNN`` or
``LabelConfig.threshold_quantile``) is taken from the split's TRAINING recordings only and
applied to its test recordings. ``leave_one_out`` makes each recording the test set in
turn.

A test recording that shares frames with the training set is refused before anything
trains; one whose labels are all one class is scored with balanced accuracy undefined
(a note) and the others are kept.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn.batch import Failure
from qdcnn.data.frames import FrameSet, load_frameset, stack_images
from qdcnn.data.labels import check_labels_usable
from qdcnn.direction.features import FeatureTable, compute_features
from qdcnn.direction.methods import DirectionMethod, TrainingOptions
from qdcnn.direction.protocol import (
    MethodResult,
    collapse_notes,
    fit_with_search,
    score_runs,
)
from qdcnn.errors import InputError
from qdcnn.experiments.evaluate import (
    EvaluationResult,
    EvaluationSpec,
    add_failures,
    array_digest,
    check_inner_searches,
    label_summary,
    method_seeds,
    options_key,
)
from qdcnn.experiments.result_cache import UnitStore, unit_key
from qdcnn.runtime.reporting import Reporter

__all__ = ["Recording", "check_no_overlap", "cross_evaluate", "run_cross_evaluation"]


@dataclass(frozen=True)
class Recording:
    """One recording's inputs for one method: readable rows only.

    ``x`` is lane features ``(n, F)`` or frames ``(n, H, W, 3)``; ``y`` their labels.
    """

    name: str
    x: NDArray[Any]
    y: NDArray[np.int64]
    frames_without_lines: int = 0


def check_no_overlap(frames: dict[str, FrameSet], train: tuple[str, ...], test: str) -> None:
    """Refuse a test recording that shares frames (resolved sources) with the training set."""
    seen = {_resolved(s) for spec in train for s in frames[spec].sources}
    shared = sum(_resolved(s) in seen for s in frames[test].sources)
    if shared:
        raise InputError(
            test,
            f"shares {shared} of its {len(frames[test])} frames with the training set: "
            "a test recording must be one the model never saw",
        )


def _resolved(source: str) -> str:
    """A frame source as a resolved path (synthetic ids as they are)."""
    from pathlib import Path

    return source if source.startswith("synthetic:") else str(Path(source).resolve())


def run_cross_evaluation(
    spec: EvaluationSpec, methods: list[DirectionMethod], report: Reporter
) -> EvaluationResult:
    """Every method trained on each split's training recordings, scored on its tests."""
    splits = spec.recording_splits()
    cfg = spec.config
    specs = list(dict.fromkeys(s for train, test in splits for s in (*train, *test)))
    frames = {
        s: load_frameset(s, seed=cfg.seed, steering_unit=cfg.labels.steering_unit) for s in specs
    }
    for train, test in splits:
        for t in test:
            check_no_overlap(frames, train, t)
    tests = list(dict.fromkeys(t for _, test in splits for t in test))
    result = EvaluationResult(
        " | ".join(frames[t].name for t in tests),
        sum(len(frames[t]) for t in tests),
        {
            "protocol": "leave-one-out" if spec.leave_one_out else "cross-recording",
            "gap": spec.gap,
            "inner_folds": spec.inner_folds,
            "seeds": spec.seeds,
        },
        trained_on=[[frames[s].name for s in train] for train, _ in splits],
        tested_on=[frames[t].name for t in tests],
    )
    for s in specs:
        add_failures(result, [Failure(p.source, str(p)) for p in frames[s].problems], report)
    for train, test in splits:
        train_sets = [frames[s] for s in train]
        for s in (*train, *test):
            if frames[s].name not in result.labels:
                summary = label_summary(frames[s], cfg, report, train=train_sets)
                result.labels[frames[s].name] = summary
    _check_before_training(spec, methods, [[frames[s] for s in train] for train, _ in splits])
    inputs = _Inputs(spec, frames, methods, result, report)
    for m in methods:
        for train, test in splits:
            for res in cross_evaluate(
                m,
                [inputs.recording(m, s, train) for s in train],
                [inputs.recording(m, t, train) for t in test],
                spec,
            ):
                names = [*res.extra["trained_on"], res.dataset]
                res.extra["labels"] = {n: result.labels[n] for n in names}
                result.results.append(res)
                report.result(res.to_dict())
                result.notes.extend(f"{res.method} on {res.dataset}: {n}" for n in res.notes)
    return result


def _check_before_training(
    spec: EvaluationSpec, methods: list[DirectionMethod], splits: list[list[FrameSet]]
) -> None:
    """Refuse, before any work, training sets of one class (always fatal later) and an
    inner search that cannot run on the smallest training set."""
    for train in splits:
        y = np.concatenate([f.labels(spec.config.labels, train=train) for f in train])
        check_labels_usable(y, source=" + ".join(f.name for f in train))
    shortest = min(sum(len(f) for f in train) for train in splits)
    loo = "the smallest training set of --protocol leave-one-out"
    check_inner_searches(spec, methods, shortest, loo if spec.leave_one_out else "--train")


class _Inputs:
    """Lane features and stacked frames of each recording, computed once and reused."""

    def __init__(
        self,
        spec: EvaluationSpec,
        frames: dict[str, FrameSet],
        methods: list[DirectionMethod],
        result: EvaluationResult,
        report: Reporter,
    ) -> None:
        self.spec, self.frames, self.result, self.report = spec, frames, result, report
        self.groupings = sorted({m.grouping for m in methods if m.grouping is not None})
        self._lanes: dict[str, FeatureTable] = {}
        self._images: dict[str, tuple[NDArray[np.uint8], NDArray[np.bool_]]] = {}

    def recording(self, m: DirectionMethod, spec: str, train: tuple[str, ...]) -> Recording:
        """``spec``'s inputs for ``m``, labelled as the split trained on ``train`` says."""
        fs = self.frames[spec]
        labels = fs.labels(self.spec.config.labels, train=[self.frames[s] for s in train])
        if m.inputs == "lanes":
            assert m.grouping is not None
            table = self._lane_features(spec)
            keep = table.readable
            return Recording(
                fs.name,
                table.features[m.grouping][keep],
                labels[keep],
                table.frames_without_lines(m.grouping),
            )
        images, readable = self._stacked(spec)
        return Recording(fs.name, images[readable], labels[readable])

    def _lane_features(self, spec: str) -> FeatureTable:
        if spec not in self._lanes:
            fs = self.frames[spec]
            with self.report.progress(len(fs), f"lane features ({fs.name})") as advance:
                table = compute_features(
                    fs,
                    self.spec.config,
                    self.groupings,
                    use_cache=self.spec.use_cache,
                    on_frame=advance,
                )
            add_failures(self.result, table.failures, self.report)
            self._lanes[spec] = table
        return self._lanes[spec]

    def _stacked(self, spec: str) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
        if spec not in self._images:
            images, readable, failures = stack_images(self.frames[spec])
            add_failures(self.result, failures, self.report)
            self._images[spec] = (images, readable)
        return self._images[spec]


def cross_evaluate(
    m: DirectionMethod, train: list[Recording], tests: list[Recording], spec: EvaluationSpec
) -> list[MethodResult]:
    """``m`` trained on all ``train`` recordings together (per seed), scored on each test."""
    x_train = _concatenate([r.x for r in train], m)
    y_train = np.concatenate([r.y for r in train])
    names = [r.name for r in train]
    check_labels_usable(y_train, source=" + ".join(names))
    opts = spec.training if m.inputs == "frames" else None
    seeds, notes = method_seeds(m, spec.config, opts, spec.seeds)
    t0 = time.perf_counter()
    runs: dict[str, list[NDArray[np.int64]]] = {t.name: [] for t in tests}
    chosen: list[dict[str, Any]] = []
    # hashing frames is costly: each digest once, not per seed and per lookup
    train_digest = array_digest(x_train, y_train)
    test_digests = {t.name: array_digest(t.x, t.y) for t in tests}
    for seed in seeds:
        cfg = replace(spec.config, seed=seed)
        store = UnitStore(_train_key(m, cfg, opts, spec, train_digest), spec.use_cache)
        done = {t.name: store.get(test_digests[t.name]) for t in tests}
        fitted: Any = None
        picked: dict[str, Any] = {}
        if any(hit is None for hit in done.values()):
            estimator, grid = m.estimator(cfg, opts)
            fitted, picked = fit_with_search(
                estimator, grid, x_train, y_train, inner_folds=spec.inner_folds, gap=spec.gap
            )
        for t in tests:
            hit = done[t.name]
            if hit is None:
                assert fitted is not None
                pred = np.asarray(fitted.predict(t.x), dtype=np.int64)
                epochs = len(getattr(fitted, "history_", []))
                store.put(test_digests[t.name], pred, picked, epochs)
                hit = (pred, picked, epochs)
            runs[t.name].append(hit[0])
            picked = hit[1]
        chosen.append(picked)
    seconds = time.perf_counter() - t0
    majority = int(np.bincount(y_train, minlength=3).argmax())
    return [
        _scored(m, t, np.stack(runs[t.name]), majority, seeds, names, chosen, seconds, notes)
        for t in tests
    ]


def _train_key(
    m: DirectionMethod,
    cfg: Any,
    opts: TrainingOptions | None,
    spec: EvaluationSpec,
    train_digest: str,
) -> str:
    return unit_key(
        kind="cross-recording",
        method=m.name,
        config=cfg.to_dict(),
        options=None if opts is None else options_key(opts, m),
        protocol={"gap": spec.gap, "inner_folds": spec.inner_folds},
        train=train_digest,
    )


def _concatenate(parts: list[NDArray[Any]], m: DirectionMethod) -> NDArray[Any]:
    """The training recordings' inputs in one array; frames prepared for a network input
    (:class:`~qdcnn.models.preprocess.PreparedFrames`, all for the same one) stay marked as
    such: a plain array of them would be cropped and resized again as if raw frames."""
    shapes = {p.shape[1:] for p in parts}
    if len(shapes) > 1:
        raise InputError(
            m.name, f"training recordings have inputs of different sizes {sorted(shapes)}"
        )
    joined = np.concatenate(parts)
    spec = getattr(parts[0], "spec", None)
    if spec is not None and all(getattr(p, "spec", None) == spec for p in parts):
        return type(parts[0])(joined, spec)
    return joined


def _scored(
    m: DirectionMethod,
    test: Recording,
    runs: NDArray[np.int64],
    majority: int,
    seeds: list[int],
    trained_on: list[str],
    chosen: list[dict[str, Any]],
    seconds: float,
    notes: list[str],
) -> MethodResult:
    """The result of ``m``'s ``runs`` (seeds x frames) on one test recording."""
    constant = np.full(test.y.size, majority, dtype=np.int64)
    scored = score_runs(test.y, runs, constant, seed=seeds[0])
    everything = [np.arange(test.y.size)]
    notes = notes + collapse_notes(
        test.y, everything, [[r] for r in runs], seeds, ["the test recording's frames"]
    )
    per_seed = [float(np.mean(run == test.y)) for run in runs]
    return MethodResult(
        m.name,
        test.name,
        int(test.y.size),
        scored.pop("accuracy"),
        float(np.std(per_seed)),
        scored.pop("per_class"),
        scored.pop("confusion"),
        scored["majority"]["accuracy"],
        test.frames_without_lines,
        seconds,
        per_seed,
        {"trained_on": trained_on, "tested_on": test.name, "chosen_hyperparameters": chosen},
        seeds=seeds,
        predictions=runs.tolist(),
        test_labels=test.y.tolist(),
        **{**scored, "notes": notes + scored["notes"]},
    )
