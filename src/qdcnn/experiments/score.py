"""``qdcnn score``: a saved direction model (or the built-in one) scored on labelled data.

Each dataset is labelled from its steering (the model's label settings unless others are
given), turned into what the model reads (lane features made with the model's own
pipeline settings, through the feature cache, or the frames for a CNN model), predicted
in one call (as ``qdcnn evaluate`` does; ``qdcnn run`` decides frame by frame, which a
classifier with shots may answer slightly differently) and scored with
:func:`qdcnn.direction.scores.score`. Each score gets a 95 % circular block-bootstrap
interval (:func:`~qdcnn.direction.scores.block_bootstrap`); one block length per dataset,
chosen for balanced accuracy (for accuracy where that is undefined), serves all three.

A dataset whose labels are all one class gets ``balanced_accuracy: None`` and the reason;
a dataset that cannot be loaded (or has no readable frame) is a failure and the others
are still scored. A missing dataset path, a bad spec or an unusable model file stops
the run before anything is scored.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._validation import check_int, check_seed
from qdcnn.batch import Failure
from qdcnn.config import LabelConfig
from qdcnn.data.frames import FrameSet, load_frameset, parse_data_spec, stack_images
from qdcnn.data.labels import DirectionLabels
from qdcnn.direction.builtin import builtin_model
from qdcnn.direction.model import DirectionModel
from qdcnn.direction.scores import (
    DEFAULT_MIN_BLOCK,
    METRICS,
    Interval,
    Scores,
    block_bootstrap,
    block_length,
    score,
)
from qdcnn.errors import InputError, ParameterError, QdcnnError
from qdcnn.runtime.reporting import Reporter

__all__ = ["DatasetScore", "ScoreResult", "ScoreSpec", "run_score"]


@dataclass(frozen=True)
class ScoreSpec:
    """What ``qdcnn score`` runs.

    Attributes
    ----------
    data : tuple of str
        Dataset specs (``udacity:PATH``, ``carla:PATH``, ``synthetic:PRESET[:N]``).
    model : path or None
        A model file from ``train-direction``; ``None``: the built-in model (the QDCNN
        model with torch, the lane model without: :func:`~qdcnn.direction.builtin.builtin_model`).
    seed : int
        Seed of the synthetic drives, of the built-in model and of the bootstrap.
    resamples : int
        Bootstrap resamples per interval.
    block : int or None
        Frames per bootstrap block; ``None`` chooses it per dataset.
    steering_unit, label_threshold : str or None, float or None
        Label settings that replace the model's own (``None``: the model's).
    use_cache : bool
        Read and write cached lane features.
    """

    data: tuple[str, ...]
    model: Path | None = None
    seed: int = 0
    resamples: int = 1000
    block: int | None = None
    steering_unit: str | None = None
    label_threshold: float | None = None
    use_cache: bool = True

    def __post_init__(self) -> None:
        if not self.data:
            raise ParameterError("data", "", "at least one dataset spec")
        for spec in self.data:
            parse_data_spec(spec)
        check_seed("seed", self.seed)
        check_int("resamples", self.resamples, 10, 10**6)
        if self.block is not None:
            check_int("block", self.block, DEFAULT_MIN_BLOCK)
        self.label_config(LabelConfig())  # checks the unit and the threshold

    def label_config(self, model_labels: LabelConfig) -> LabelConfig:
        """The model's label settings with those this spec gives in their place."""
        unit = model_labels.steering_unit if self.steering_unit is None else self.steering_unit
        threshold = model_labels.threshold if self.label_threshold is None else self.label_threshold
        return replace(model_labels, steering_unit=unit, threshold=threshold)


@dataclass(frozen=True)
class DatasetScore:
    """One dataset's scores and their intervals.

    Attributes
    ----------
    dataset : str
        The dataset spec.
    scores : Scores
        The metrics of :func:`~qdcnn.direction.scores.score`.
    intervals : dict of str to Interval or None
        95 % interval per metric; ``None`` where it cannot be computed (then
        ``interval_note`` says why).
    labels : DirectionLabels
        How the frames were labelled (unit, threshold, smoothing), all frames.
    skipped : int
        Frames left out (unreadable, or rows skipped while loading).
    """

    dataset: str
    scores: Scores
    intervals: dict[str, Interval | None]
    labels: DirectionLabels
    skipped: int = 0
    interval_note: str | None = None

    @property
    def block(self) -> int | None:
        """Frames per bootstrap block (the same for every metric), if any interval exists."""
        return next((iv.block for iv in self.intervals.values() if iv is not None), None)

    def to_dict(self, model: str) -> dict[str, Any]:
        """Plain values for JSON output; ``model`` names the model that decided."""
        out: dict[str, Any] = {"dataset": self.dataset, "model": model, **self.scores.to_dict()}
        for metric, iv in self.intervals.items():
            out[f"{metric}_ci"] = None if iv is None else [iv.low, iv.high]
        some = next((iv for iv in self.intervals.values() if iv is not None), None)
        out["level"] = None if some is None else some.level
        out["resamples"] = None if some is None else some.resamples
        out["block"] = self.block
        out["interval_method"] = None if some is None else some.method
        if self.interval_note is not None:
            out["interval_note"] = self.interval_note
        out["skipped_frames"] = self.skipped
        out["labels"] = self.labels.to_dict()
        return out


@dataclass
class ScoreResult:
    """The model that decided, each dataset's scores and the datasets that failed."""

    model: DirectionModel
    model_name: str
    rows: list[DatasetScore] = field(default_factory=list)
    failures: list[Failure] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        """1 when a dataset could not be loaded, else 0 (undefined scores are not failures)."""
        return 1 if self.failures else 0

    def summary(self) -> dict[str, Any]:
        """The final JSON line."""
        return {
            "summary": True,
            "model": self.model_name,
            "method": self.model.method,
            "trained_on": self.model.trained_on,
            "n_datasets": len(self.rows),
            "n_failed": len(self.failures),
            "failures": [f.to_dict() for f in self.failures],
        }


def run_score(spec: ScoreSpec, reporter: Reporter | None = None) -> ScoreResult:
    """Score the model of ``spec`` on each of its datasets; each row is reported when done.

    Raises
    ------
    InputError
        A recording path that does not exist, a missing or unusable model file, or a
        model that does not fit the data it is given.
    """
    report = reporter or Reporter()
    _check_paths(spec.data)
    model, name = _load_model(spec, report)
    result = ScoreResult(model, name)
    for dataset in spec.data:
        try:
            data = _load_dataset(dataset, model, spec, report)
        except QdcnnError as exc:  # unloadable, or settings that do not suit its steering
            result.failures.append(_failure(dataset, exc))
            report.failure(result.failures[-1])
            continue
        result.rows.append(_score_dataset(data, model, name, spec))
        report.result(result.rows[-1].to_dict(name))
    return result


def _failure(dataset: str, exc: QdcnnError) -> Failure:
    """The dataset's failure, its one-line reason naming it."""
    text = " ".join(str(exc).split())
    return Failure(dataset, text if dataset in text else f"{dataset}: {text}")


@dataclass(frozen=True)
class _Dataset:
    """One dataset ready to score: its labels, the model's inputs of its readable frames."""

    spec: str
    labels: DirectionLabels
    inputs: NDArray[Any]
    keep: NDArray[np.bool_]
    skipped: int


def _check_paths(specs: tuple[str, ...]) -> None:
    """Every recording named exists (a typo stops the run before anything is scored)."""
    from qdcnn.data.images import require_file_or_folder

    for spec in specs:
        parsed = parse_data_spec(spec)  # a label suffix (@unit=...) is not part of the path
        if parsed.kind != "synthetic":
            require_file_or_folder(parsed.value, "file")


def _load_model(spec: ScoreSpec, report: Reporter) -> tuple[DirectionModel, str]:
    """The model and how results name it: its file, or the built-in model described."""
    if spec.model is not None:
        return DirectionModel.load(spec.model), str(spec.model)
    model, name = builtin_model(None, spec.seed)
    report.note(f"no --model: model: {name}")
    return model, name


def _load_dataset(
    dataset: str, model: DirectionModel, spec: ScoreSpec, report: Reporter
) -> _Dataset:
    """Frames, labels and the model's inputs of one dataset (an InputError when unusable)."""
    labelling = spec.label_config(model.config.labels)
    frames = load_frameset(dataset, seed=spec.seed, steering_unit=labelling.steering_unit)
    inputs, keep, unreadable = _model_inputs(frames, model, spec, report)
    if not keep.any():
        raise InputError(dataset, f"none of its {len(frames)} frames could be read")
    _note_skipped(
        dataset, [str(p) for p in frames.problems] + [f.error for f in unreadable], report
    )
    skipped = len(frames.problems) + len(unreadable)
    return _Dataset(dataset, frames.label_info(labelling), inputs, keep, skipped)


#: Skipped rows and frames of one dataset told one line each; the rest in one line.
MAX_SKIPPED_LINES = 50


def _note_skipped(dataset: str, reasons: list[str], report: Reporter) -> None:
    """One note per row or frame left out of the score, naming the file or row and why."""
    for reason in reasons[:MAX_SKIPPED_LINES]:
        report.note(f"{dataset}: not scored: {reason}")
    if len(reasons) > MAX_SKIPPED_LINES:
        more = len(reasons) - MAX_SKIPPED_LINES
        report.note(f"{dataset}: {more} more rows or frames not scored")


def _score_dataset(
    data: _Dataset, model: DirectionModel, name: str, spec: ScoreSpec
) -> DatasetScore:
    """The model's predictions on one dataset, their scores and intervals."""
    truth = data.labels.labels[data.keep]
    predictions = _predict(model, name, data.inputs, data.spec)
    intervals, note = _intervals(truth, predictions, spec)
    return DatasetScore(
        data.spec, score(truth, predictions), intervals, data.labels, data.skipped, note
    )


def _model_inputs(
    frames: FrameSet, model: DirectionModel, spec: ScoreSpec, report: Reporter
) -> tuple[NDArray[Any], NDArray[np.bool_], list[Failure]]:
    """What the model reads for each readable frame, which frames those are, and the
    frames that could not be read."""
    if model.grouping is None:
        images, readable, failures = stack_images(frames)
        return images[readable], readable, failures
    from qdcnn.direction.features import compute_features

    with report.progress(len(frames), f"lane features ({frames.name})") as advance:
        table = compute_features(
            frames, model.config, (model.grouping,), use_cache=spec.use_cache, on_frame=advance
        )
    keep = table.readable
    return table.features[model.grouping][keep], keep, list(table.failures)


def _predict(
    model: DirectionModel, name: str, inputs: NDArray[Any], dataset: str
) -> NDArray[np.int64]:
    """The model's directions, checked to be one of classes 0, 1, 2 per frame.

    Raises
    ------
    InputError
        The model cannot read the inputs, or answers with other classes: it does not fit
        the data (bad input for the whole run, not a failed dataset).
    """
    try:
        predictions = model.predict(inputs)
    except (QdcnnError, ValueError) as exc:
        why = " ".join(str(exc).split())
        raise InputError(name, f"cannot read the inputs of {dataset}: {why}") from None
    if predictions.shape != (inputs.shape[0],) or not np.isin(predictions, (0, 1, 2)).all():
        raise InputError(name, "predicts classes other than left, straight, right (0, 1, 2)")
    return predictions


def _intervals(
    truth: NDArray[np.int64], predictions: NDArray[np.int64], spec: ScoreSpec
) -> tuple[dict[str, Interval | None], str | None]:
    """95 % block-bootstrap interval of each metric over one shared block length.

    Balanced accuracy has none when the labels hold one class; no metric has one when
    the frames are too few for two blocks (the note says why).
    """
    defined = np.unique(truth).size > 1
    metric = "balanced_accuracy" if defined else "accuracy"
    intervals: dict[str, Interval | None] = dict.fromkeys(METRICS)
    try:
        block = spec.block or block_length(truth, predictions, metric)
        for m in METRICS if defined else ("accuracy", "macro_f1"):
            intervals[m] = block_bootstrap(
                truth, predictions, m, block=block, resamples=spec.resamples, seed=spec.seed
            )
    except (InputError, ParameterError) as exc:  # too few frames, or a --block too long
        return dict.fromkeys(METRICS), " ".join(str(exc).split())
    return intervals, None
