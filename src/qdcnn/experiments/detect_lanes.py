"""``qdcnn detect-lanes``: lane overlays and a left / straight / right decision per image.

Each image goes through the pipeline of the model's config (shadow removal, lanes,
grouping), the model decides, and an overlay ``<stem>_lanes.png`` is written at once.
``predictions.csv`` is written row by row with the csv module (so any file name is
quoted properly and a crash keeps every finished row).
"""

from __future__ import annotations

import csv
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._fileio import AtomicTextFile, unique_stems
from qdcnn._validation import check_bool, check_float, check_seed
from qdcnn.batch import Failure, run_batch
from qdcnn.config import PipelineConfig
from qdcnn.data.images import encode_image, list_named_images, read_image
from qdcnn.data.labels import DIRECTIONS
from qdcnn.direction.builtin import (
    DEFAULT_METHOD,
    DEFAULT_TRAINING_DATA,
    QDCNN_SHA256,
    direction_model,
    uses_builtin_qdcnn,
)
from qdcnn.direction.methods import get_method
from qdcnn.direction.model import DirectionModel
from qdcnn.errors import InputError, ParameterError
from qdcnn.experiments.shadow_batch import note_shared_stems
from qdcnn.outputs import refuse_output_in_inputs
from qdcnn.runtime.manifest import ResumableBatch
from qdcnn.runtime.reporting import Reporter

__all__ = [
    "DetectLanesResult",
    "DetectLanesSpec",
    "LaneRecord",
    "detect_lanes",
]

CSV_COLUMNS = ("file", "direction", "status", "p_left", "p_straight", "p_right")


@dataclass(frozen=True)
class DetectLanesSpec:
    """What ``qdcnn detect-lanes`` runs: images, output folder, and a model or a method.

    ``config`` is the pipeline the built-in model of ``method`` is trained with when no
    ``model`` is given (``None``: ``PipelineConfig(seed=seed)``); a model file carries its own.
    """

    paths: tuple[Path, ...]
    out: Path
    model: Path | None = None
    method: str | None = None
    seed: int = 0
    force: bool = False
    wait: float = 0.0
    config: PipelineConfig | None = None

    def __post_init__(self) -> None:
        if self.method is not None:
            get_method(self.method)
        check_seed("seed", self.seed)
        check_bool("force", self.force)
        check_float("wait", self.wait, 0.0, 86_400.0)
        if self.config is not None and not isinstance(self.config, PipelineConfig):
            raise ParameterError("config", type(self.config).__name__, "a PipelineConfig")

    @property
    def pipeline(self) -> PipelineConfig:
        """The config of the built-in model (``config``, or the default one)."""
        return self.config or PipelineConfig(seed=self.seed)

    def settings(self) -> dict[str, Any]:
        """Everything that changes the outputs (hashed into the manifest's records)."""
        from qdcnn.outputs import file_identity

        model = None if self.model is None else file_identity(self.model, content_hash=True)
        default: list[Any] | None = None
        if self.model is None:
            if uses_builtin_qdcnn(self.method, self.seed, self.config):
                default = ["builtin-qdcnn", QDCNN_SHA256]
            else:
                method = self.method or DEFAULT_METHOD
                default = [method, *DEFAULT_TRAINING_DATA, self.pipeline.to_dict()]
        return {"model": model, "default_model": default, "seed": self.seed}


@dataclass(frozen=True)
class LaneRecord:
    """One image's decision and where its overlay went."""

    file: str
    direction: str
    status: str
    features: list[float | None]
    probabilities: list[float] | None
    seconds: float
    overlay: str
    resumed: bool = False

    def to_dict(self) -> dict[str, Any]:
        return {
            "file": self.file,
            "direction": self.direction,
            "status": self.status,
            "features": self.features,
            "probabilities": self.probabilities,
            "seconds": self.seconds,
            "overlay": self.overlay,
            "resumed": self.resumed,
        }


@dataclass
class DetectLanesResult:
    """Every image's record, the failures and the model that decided."""

    model: DirectionModel
    out: Path
    records: list[LaneRecord] = field(default_factory=list)
    failures: list[Failure] = field(default_factory=list)
    skipped: list[Path] = field(default_factory=list)
    #: One line naming the model that decided (the built-in one described, or the file).
    model_name: str = ""

    @property
    def exit_code(self) -> int:
        return 1 if self.failures or not self.records else 0

    def to_dict(self) -> dict[str, Any]:
        return {
            "summary": True,
            "model": self.model_name,
            "method": self.model.method,
            "trained_on": self.model.trained_on,
            "model_summary": self.model.summary,
            "n_images": len(self.records),
            "n_failed": len(self.failures),
            "failures": [f.to_dict() for f in self.failures],
            "skipped": [str(p) for p in self.skipped],
            "out": str(self.out),
        }


def detect_lanes(spec: DetectLanesSpec, reporter: Reporter | None = None) -> DetectLanesResult:
    """Decide a direction for every image of ``spec``, writing overlays and predictions.csv."""
    report = reporter or Reporter()
    listing = list_named_images(spec.paths)
    refuse_output_in_inputs(spec.out, spec.paths)
    if not listing.images and not listing.missing:
        raise InputError(", ".join(map(str, spec.paths)), "no image files found")
    if spec.out.exists() and not spec.out.is_dir():
        raise InputError(spec.out, "exists and is not a folder (--out names a folder for overlays)")
    model, name = direction_model(
        spec.model, spec.method, spec.seed, spec.pipeline, report.note, reporter=report
    )
    result = DetectLanesResult(model, spec.out, skipped=listing.skipped, model_name=name)
    note_shared_stems(listing.images, report)
    with (
        ResumableBatch(spec.out, spec.settings(), force=spec.force, wait=spec.wait) as batch,
        _PredictionTable(spec.out) as table,
        report.progress(len(listing.images), "detect-lanes") as advance,
    ):
        decide = _Decider(model, batch, spec.seed, listing.images)
        for outcome in run_batch(listing.images, decide):
            if outcome.result is not None:
                result.records.append(outcome.result)
                table.add(outcome.result)
                report.result(outcome.result.to_dict())
            elif outcome.failure is not None:
                result.failures.append(outcome.failure)
                report.failure(outcome.failure)
            advance()
    return result


class _PredictionTable:
    """``predictions.csv`` written row by row into ``predictions.partial.csv`` (flushed
    per row, never through a link), which becomes ``predictions.csv`` when the run ends;
    a run that ends on an error (a full disk) removes it."""

    def __init__(self, out: Path) -> None:
        self.partial = out / "predictions.partial.csv"
        self.final = out / "predictions.csv"

    def __enter__(self) -> _PredictionTable:
        self.file = AtomicTextFile(self.final, partial=self.partial, errors="surrogateescape")
        self.writer = csv.writer(self.file)
        self.writer.writerow(CSV_COLUMNS)
        return self

    def add(self, record: LaneRecord) -> None:
        self.writer.writerow(_csv_row(record))
        self.file.flush()

    def __exit__(self, exc_type: type[BaseException] | None, *_: object) -> None:
        if exc_type is None:
            self.file.commit()
        elif issubclass(exc_type, Exception):
            self.file.abort()  # the run ended on an error: its rows are in the manifest
        else:
            self.file.close()  # interrupted (Ctrl-C): the rows so far stay readable


def _csv_row(record: LaneRecord) -> list[str]:
    probs = [f"{p:.6f}" for p in record.probabilities] if record.probabilities else ["", "", ""]
    return [record.file, record.direction, record.status, *probs]


class _Decider:
    """The per-image work: pipeline, decision, overlay."""

    def __init__(
        self, model: DirectionModel, batch: ResumableBatch, seed: int, images: list[Path]
    ) -> None:
        from qdcnn.vision.grouping import mode_columns

        self.model = model
        self.batch = batch
        self.seed = seed
        self.stems = unique_stems(images)
        self.index = {path: i for i, path in enumerate(images)}
        cfg = model.config.grouping
        self.columns = mode_columns(cfg.features, cfg.extra_features)
        self.grouping = model.grouping or "image-split"

    def __call__(self, path: Path) -> LaneRecord:
        rel = f"{self.stems[path]}_lanes.png"
        done = self.batch.finished(rel, path)
        if done is not None:
            return LaneRecord(**{**done, "resumed": True})
        record, overlay = self.decide(path, rel)
        self.batch.record(rel, path, {rel: encode_image(overlay)}, record.to_dict())
        return record

    def decide(self, path: Path, rel: str) -> tuple[LaneRecord, NDArray[np.uint8]]:
        """Pipeline, decision and overlay of one image (shots seeded by its index)."""
        from qdcnn.pipeline import process_frame
        from qdcnn.vision.overlays import draw_lane_overlay

        image = read_image(path)
        rng = np.random.default_rng([self.seed, self.index[path]])
        t0 = time.perf_counter()
        frame = process_frame(image, self.model.config, (self.grouping,), rng=rng)
        lanes = frame.lanes[self.grouping]
        inputs = lanes.features if self.model.info.inputs == "lanes" else image[None]
        labels, probs = self.model.predict_with_proba(inputs)
        label = int(labels[0])
        seconds = time.perf_counter() - t0
        direction = DIRECTIONS[label]
        overlay = draw_lane_overlay(
            image,
            frame.segments,
            lanes,
            direction,
            roi=self.model.config.lanes.roi,
            columns=self.columns,
        )
        record = LaneRecord(
            str(path),
            direction,
            lanes.status,
            [None if np.isnan(v) else float(v) for v in lanes.features],
            None if probs is None else [float(p) for p in probs[0]],
            seconds,
            str(self.batch.folder.path(rel)),
        )
        return record, overlay
