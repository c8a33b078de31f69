"""Shadow detection, scoring and training over files and folders.

The runners of ``qdcnn detect-shadows`` (:func:`run_shadow_detection`), ``score-shadows``
(:func:`score_folders`) and ``train-shadows`` (:func:`train_shadows`).
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from qdcnn._fileio import unique_stems
from qdcnn._validation import check_bool, check_float, check_int, check_seed
from qdcnn.batch import Failure, run_batch
from qdcnn.config import ShadowConfig
from qdcnn.data.images import (
    encode_mask,
    list_named_images,
    read_image,
    read_mask,
    require_folder,
    write_mask,
)
from qdcnn.data.shadow_set import index_by_stem, load_shadow_set
from qdcnn.errors import InputError, ParameterError
from qdcnn.outputs import refuse_output_in_inputs
from qdcnn.runtime.manifest import ResumableBatch
from qdcnn.runtime.reporting import Reporter
from qdcnn.vision.detectors import QUANTUM_DETECTORS, check_method, detect_shadows
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
    resumed: bool = False

    def to_dict(self) -> dict[str, Any]:
        return {
            "file": self.file,
            "method": self.method,
            "seconds": self.seconds,
            "shadow_fraction": self.shadow_fraction,
            "mask": self.mask,
            "resumed": self.resumed,
        }


#: How each image's shot sampling is seeded (recorded in the settings, so masks that an
#: older qdcnn seeded by list position are detected again, never resumed).
SAMPLING_SEED = "run seed + SHA-256 of the image bytes"


def mask_path(out_dir: Path, image: Path, stem: str | None = None) -> Path:
    """``out_dir/<stem>_mask.png`` (``stem`` defaults to the image's own)."""
    return out_dir / f"{image.stem if stem is None else stem}_mask.png"


def detect_files(
    images: Sequence[Path],
    method: str,
    out_dir: Path,
    config: ShadowConfig | None = None,
    *,
    model: ShadowModel | None = None,
    backend: str = "numpy",
    seed: int = 0,
    batch: ResumableBatch | None = None,
) -> Iterator[MaskRecord | Failure]:
    """Detect shadows in each image and write its mask as it finishes.

    ``seconds`` is the detection time of that image, excluding reading and writing
    files. Shot sampling of an image draws from :func:`image_rng` (the run seed and the
    SHA-256 of the file's bytes), so an image's mask depends neither on its position in
    the list nor on its name: a fresh run, a resumed run after images were added, and a
    run on a renamed copy agree. With a ``batch``, masks
    go through its manifest: images whose record is complete are not detected again
    (their record comes back with ``resumed=True``).
    """
    check_method(method)
    out_dir.mkdir(parents=True, exist_ok=True)
    stems = unique_stems(list(images))

    def work(path: Path) -> MaskRecord:
        rel = mask_path(Path(), path, stems[path]).as_posix()
        done = batch.finished(rel, path) if batch is not None else None
        if done is not None:
            return MaskRecord(**{**done, "resumed": True})
        image = read_image(path)
        rng = image_rng(seed, path)
        t0 = time.perf_counter()
        mask = detect_shadows(image, method, config, model=model, backend=backend, rng=rng)
        seconds = time.perf_counter() - t0
        result = MaskRecord(str(path), method, seconds, float(mask.mean()), str(out_dir / rel))
        if batch is not None:
            batch.record(rel, path, {rel: encode_mask(mask)}, result.to_dict())
        else:
            write_mask(out_dir / rel, mask)
        return result

    for outcome in run_batch(images, work):
        yield outcome.failure if outcome.failure else outcome.result  # type: ignore[misc]


def image_rng(seed: int, path: Path) -> np.random.Generator:
    """The shot-sampling generator of one image: seeded by ``seed`` and the file's content.

    The first 8 bytes of the SHA-256 of the file's bytes join the run seed, so identical
    files get identical masks whatever their name or position in the list.
    """
    from qdcnn.outputs import file_identity

    digest = file_identity(path, content_hash=True)["sha256"]
    return np.random.default_rng([seed, int(digest[:16], 16)])


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
    matched pairs. A prediction without ground truth, a ground-truth mask without a
    prediction, an unreadable mask or a size mismatch is a failure; the other pairs
    are still scored.
    """
    for folder, what in ((pred_dir, "prediction"), (gt_dir, "ground-truth")):
        require_folder(folder, f"{what} folder")
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
    predicted = {p.stem[: -len("_mask")] for p in preds}
    failures = [
        Failure(str(gt), f"{gt}: no prediction {stem}_mask.png in {pred_dir}")
        for stem, gt in truth.items()
        if stem not in predicted
    ]
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


# ---------------------------------------------------------------- runners


@dataclass(frozen=True)
class ShadowDetectionSpec:
    """What ``qdcnn detect-shadows`` runs.

    Attributes
    ----------
    paths : sequence of path
        Image files and/or folders of images.
    out : Path
        Folder for ``<stem>_mask.png`` files.
    method : str
        A shadow detector of :data:`qdcnn.vision.detectors.SHADOW_DETECTORS`.
    config : ShadowConfig
        UU-dagger settings (shots, threshold, centroid, calibration classes).
    model : Path or None
        A model file from ``train-shadows`` (UU-dagger methods).
    backend : {"numpy", "aer"}
    seed : int
        Run seed of shot sampling (each image adds its SHA-256, :func:`image_rng`).
    """

    paths: tuple[Path, ...]
    out: Path
    method: str = "uu"
    config: ShadowConfig = field(default_factory=ShadowConfig)
    model: Path | None = None
    backend: str = "numpy"
    seed: int = 0
    force: bool = False
    wait: float = 0.0

    def __post_init__(self) -> None:
        from qdcnn.quantum.execute import check_backend

        check_method(self.method)
        check_backend(self.backend)
        check_seed("seed", self.seed)
        check_bool("force", self.force)
        check_float("wait", self.wait, 0.0, 86_400.0)

    def settings(self) -> dict[str, Any]:
        """Everything that changes the masks (hashed into the manifest's records)."""
        from dataclasses import asdict

        from qdcnn.outputs import file_identity

        return {
            "method": self.method,
            "config": asdict(self.config),
            "model": None if self.model is None else file_identity(self.model, content_hash=True),
            "backend": self.backend,
            "seed": self.seed,
            "sampling": SAMPLING_SEED,
        }


@dataclass
class ShadowDetectionResult:
    """Masks written, images that failed, and files passed over."""

    method: str
    out: Path
    shots: int | None
    records: list[MaskRecord] = field(default_factory=list)
    failures: list[Failure] = field(default_factory=list)
    skipped: list[Path] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        return 1 if self.failures or not self.records else 0

    def to_dict(self) -> dict[str, Any]:
        return {
            "summary": True,
            "method": self.method,
            "n_images": len(self.records),
            "n_failed": len(self.failures),
            "failures": [f.to_dict() for f in self.failures],
            "skipped": [str(p) for p in self.skipped],
            "median_seconds": median_seconds(self.records),
            "shots": self.shots,
            "out": str(self.out),
        }


def run_shadow_detection(
    spec: ShadowDetectionSpec, reporter: Reporter | None = None
) -> ShadowDetectionResult:
    """Detect shadows in every image of ``spec``; each mask is written and reported as it ends."""
    report = reporter or Reporter()
    model = ShadowModel.load(spec.model) if spec.model else None
    listing = list_named_images(spec.paths)
    refuse_output_in_inputs(spec.out, spec.paths)
    if spec.out.exists() and not spec.out.is_dir():
        raise InputError(spec.out, "exists and is not a folder (--out names a folder for masks)")
    quantum = spec.method in QUANTUM_DETECTORS
    result = ShadowDetectionResult(
        spec.method, spec.out, spec.config.shots if quantum else None, skipped=listing.skipped
    )
    note_shared_stems(listing.images, report)
    with (
        ResumableBatch(spec.out, spec.settings(), force=spec.force, wait=spec.wait) as batch,
        report.progress(len(listing.images), f"detect-shadows {spec.method}") as advance,
    ):
        items = detect_files(
            listing.images,
            spec.method,
            spec.out,
            spec.config,
            model=model,
            backend=spec.backend,
            seed=spec.seed,
            batch=batch,
        )
        for item in items:
            if isinstance(item, MaskRecord):
                result.records.append(item)
                report.result(item.to_dict())
            else:
                result.failures.append(item)
                report.failure(item)
            advance()
    return result


def note_shared_stems(images: Sequence[Path], report: Reporter) -> None:
    stems = unique_stems(list(images))
    shared = sum(1 for p in images if stems[p] != p.stem)
    if shared:
        report.note(
            f"{shared} inputs share a file stem with another input: their outputs are named "
            "<stem>-<8 hex digits of the input path>, listed in each record"
        )


@dataclass(frozen=True)
class ShadowTrainingSpec:
    """What ``qdcnn train-shadows`` runs.

    One feature and one centroid is the paper's model (centroid by the propagation
    algorithm, threshold chosen on the training set from
    :data:`~qdcnn.config.SHADOW_THRESHOLD_GRID`); several features or centroids train the
    multi-centroid model (not the paper's).
    """

    data: Path
    out: Path
    features: tuple[str, ...] = ("intensity",)
    centroids: int = 1
    search_threshold: bool = True
    seed: int = 0

    def __post_init__(self) -> None:
        from qdcnn.vision.shadows import FEATURES

        names = self.features
        if not names or any(f not in FEATURES for f in names) or len(set(names)) != len(names):
            raise ParameterError("features", ",".join(names), "intensity and/or chromaticity")
        check_int("centroids", self.centroids, 1, 8)
        check_seed("seed", self.seed)


@dataclass
class ShadowTrainingResult:
    """The trained shadow model, where it went, and the image/mask pairs left out."""

    model: ShadowModel
    path: Path
    failures: list[Failure]

    @property
    def exit_code(self) -> int:
        return 1 if self.failures else 0

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": str(self.path),
            **self.model.to_dict(),
            "failures": [f.to_dict() for f in self.failures],
        }


def train_shadows(
    spec: ShadowTrainingSpec, reporter: Reporter | None = None
) -> ShadowTrainingResult:
    """Train a UU-dagger shadow model on a shadow set and save it."""
    report = reporter or Reporter()
    images, masks, failures = load_shadow_set(spec.data)
    for f in failures:
        report.failure(f)
    with report.progress(1, f"training a shadow model on {len(images)} images") as trained:
        model = _fit_shadow_model(spec, images, masks)
        trained()
    path = model.save(spec.out)
    return ShadowTrainingResult(model, Path(path), failures)


def _fit_shadow_model(spec: ShadowTrainingSpec, images: Any, masks: Any) -> ShadowModel:
    """The one-feature model (a threshold search if asked) or the multi-feature one."""
    from qdcnn.config import SHADOW_THRESHOLD_GRID
    from qdcnn.vision.shadow_training import train_multi_shadow_model, train_shadow_model

    cfg = ShadowConfig(feature=spec.features[0], shots=None)  # type: ignore[arg-type]
    if len(spec.features) == 1 and spec.centroids == 1:
        grid = SHADOW_THRESHOLD_GRID if spec.search_threshold else None
        return train_shadow_model(images, masks, cfg, thresholds=grid)
    return train_multi_shadow_model(
        images, masks, cfg, features=spec.features, n_centroids=spec.centroids, seed=spec.seed
    )
