"""Shadow detection and scoring over files and folders (``detect-shadows``, ``score-shadows``)."""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from qdcnn.batch import Failure, run_batch
from qdcnn.config import ShadowConfig
from qdcnn.data.images import list_images, read_image, read_mask, write_mask
from qdcnn.data.shadow_set import index_by_stem
from qdcnn.errors import InputError
from qdcnn.quantum.sampling import as_generator
from qdcnn.vision.detectors import check_method, detect_shadows
from qdcnn.vision.metrics import ConfusionCounts, ShadowScores, confusion_counts, shadow_scores
from qdcnn.vision.shadows import ShadowModel


@dataclass(frozen=True)
class MaskRecord:
    """One image's detection: where the mask went and how long detection took."""

    file: str
    method: str
    seconds: float
    shadow_fraction: float
    mask: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "file": self.file,
            "method": self.method,
            "seconds": self.seconds,
            "shadow_fraction": self.shadow_fraction,
            "mask": self.mask,
        }


@dataclass
class DetectionPlan:
    """Images to process and paths passed over before any work starts."""

    images: list[Path]
    skipped: list[Path] = field(default_factory=list)
    failures: list[Failure] = field(default_factory=list)


def plan_detection(paths: Sequence[str | Path]) -> DetectionPlan:
    """Expand paths; missing paths and non-image files become failures up front."""
    listing = list_images(paths)
    failures = [Failure(e.source, str(e)) for e in listing.missing]
    return DetectionPlan(listing.images, listing.skipped, failures)


def mask_path(out_dir: Path, image: Path) -> Path:
    """``out_dir/<stem>_mask.png``."""
    return out_dir / f"{image.stem}_mask.png"


def detect_files(
    images: Sequence[Path],
    method: str,
    out_dir: Path,
    config: ShadowConfig | None = None,
    *,
    model: ShadowModel | None = None,
    backend: str = "numpy",
    seed: int = 0,
) -> Iterator[MaskRecord | Failure]:
    """Detect shadows in each image and write its mask as it finishes.

    ``seconds`` is the detection time of that image, excluding reading and
    writing files.
    """
    check_method(method)
    out_dir.mkdir(parents=True, exist_ok=True)
    rng = as_generator(seed)

    def work(path: Path) -> MaskRecord:
        image = read_image(path)
        t0 = time.perf_counter()
        mask = detect_shadows(image, method, config, model=model, backend=backend, rng=rng)
        seconds = time.perf_counter() - t0
        target = write_mask(mask_path(out_dir, path), mask)
        return MaskRecord(str(path), method, seconds, float(mask.mean()), str(target))

    for outcome in run_batch(images, work):
        yield outcome.failure if outcome.failure else outcome.result  # type: ignore[misc]


@dataclass
class ScoreReport:
    """Scores of predicted masks against ground truth, with the pairs that failed."""

    scores: ShadowScores | None
    failures: list[Failure]
    matched: int

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = self.scores.to_dict() if self.scores else {"n": 0}
        out["failures"] = [f.to_dict() for f in self.failures]
        return out


def score_folders(pred_dir: Path, gt_dir: Path) -> ScoreReport:
    """Score ``<stem>_mask.png`` predictions against ``<stem>.<ext>`` ground-truth masks.

    BER, shadow and non-shadow errors are computed on counts summed over all
    matched pairs. A prediction without ground truth, an unreadable mask or a
    size mismatch is a failure; the other pairs are still scored.
    """
    for folder, what in ((pred_dir, "prediction"), (gt_dir, "ground-truth")):
        if not folder.is_dir():
            raise InputError(folder, f"{what} folder not found")
    truth = index_by_stem(gt_dir)
    preds = [p for p in index_by_stem(pred_dir).values() if p.stem.endswith("_mask")]
    if not preds:
        raise InputError(pred_dir, "no predicted masks named <stem>_mask.png")

    def work(pred: Path) -> ConfusionCounts:
        stem = pred.stem[: -len("_mask")]
        gt = truth.get(stem)
        if gt is None:
            raise InputError(pred, f"no ground-truth mask {stem}.* in {gt_dir}")
        return confusion_counts(read_mask(pred), read_mask(gt), source=str(pred))

    counts: list[ConfusionCounts] = []
    failures: list[Failure] = []
    for outcome in run_batch(preds, work):
        if outcome.result is not None:
            counts.append(outcome.result)
        elif outcome.failure is not None:
            failures.append(outcome.failure)
    scores = shadow_scores(counts) if counts else None
    return ScoreReport(scores, failures, len(counts))


def median_seconds(records: Sequence[MaskRecord]) -> float | None:
    """Median detection time of the records, or ``None`` when there are none."""
    return float(np.median([r.seconds for r in records])) if records else None
