"""``detect-shadows``, ``score-shadows`` and ``train-shadows``.

The shadow runners and the config are imported when a command runs, so ``qdcnn --help``
loads none of them.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.table import Table

from qdcnn.cli._common import (
    CliReporter,
    JsonOpt,
    QuietOpt,
    WaitOpt,
    click,
    deprecated_spelling,
    emit,
    fail,
    out,
    report_error,
)
from qdcnn.errors import QdcnnError

if TYPE_CHECKING:
    from qdcnn.experiments.shadow_batch import ShadowDetectionResult

PathsArg = Annotated[list[Path], typer.Argument(help="Image files and/or folders of images.")]
MaskOutOpt = Annotated[Path, typer.Option("--out", help="Folder for <stem>_mask.png files.")]
MethodOpt = Annotated[str, typer.Option(help="uu | uu-chroma | ibt | cbs | lbp")]
ExactOpt = Annotated[bool, typer.Option("--exact", help="Exact probabilities instead of shots.")]
ShotsOpt = Annotated[
    int | None, typer.Option(help="Shots per block circuit (default and paper: 1024).")
]
BackendOpt = Annotated[str, typer.Option(help="numpy | aer")]
ThresholdOpt = Annotated[float | None, typer.Option(help="Fidelity threshold (default 0.97).")]
CentroidOpt = Annotated[float | None, typer.Option(help="Shadow centroid in [0, 255].")]
ModelOpt = Annotated[Path | None, typer.Option(help="Model file from train-shadows.")]
ClassesOpt = Annotated[
    int, typer.Option(help="Clusters of the per-image calibration start (paper: 2).")
]
SeedOpt = Annotated[int, typer.Option(help="Seed of shot sampling.")]


def detect_shadows_cmd(
    paths: PathsArg,
    out_dir: MaskOutOpt,
    method: MethodOpt = "uu",
    exact: ExactOpt = False,
    shots: ShotsOpt = None,
    backend: BackendOpt = "numpy",
    threshold: ThresholdOpt = None,
    centroid: CentroidOpt = None,
    model: ModelOpt = None,
    calibration_classes: ClassesOpt = 2,
    seed: SeedOpt = 0,
    force: Annotated[bool, typer.Option(help="Redo images whose mask is already done.")] = False,
    wait: WaitOpt = 0.0,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Detect shadows; write a 0/255 mask per image at input size.

    Resumable: a re-run with the same settings skips images whose mask is recorded as
    finished in the folder's manifest (--force redoes them).
    """
    from qdcnn.config import ShadowConfig
    from qdcnn.experiments.shadow_batch import ShadowDetectionSpec, run_shadow_detection

    table = Table("file", "shadow %", "ms", title=f"shadow detection: {method}")
    try:
        check_shadow_options(method, exact=exact, shots=shots, centroid=centroid, model=model)
        shots = None if exact else 1024 if shots is None else shots
        cfg = ShadowConfig(shots=shots, calibration_classes=calibration_classes)
        cfg = replace(cfg, threshold=cfg.threshold if threshold is None else threshold)
        cfg = replace(cfg, centroid=centroid)
        spec = ShadowDetectionSpec(
            tuple(paths), out_dir, method, cfg, model, backend, seed, force, wait
        )
        reporter = CliReporter(as_json, lambda r: _mask_row(table, r), quiet=quiet)
        result = run_shadow_detection(spec, reporter)
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json:
        emit(result.to_dict())
    else:
        out.print(table)
        out.print(_detection_line(result))
    raise typer.Exit(result.exit_code)


def check_shadow_options(
    method: str, *, exact: bool, shots: int | None, centroid: float | None, model: Path | None
) -> None:
    """Refuse options that the others would silently override or ignore.

    Raises
    ------
    OptionConflict
        ``--exact`` with ``--shots``, ``--model`` with ``--centroid`` (the given centroid
        would replace the model's), or ``--model`` with a classical ``--method``.
    """
    from qdcnn.errors import OptionConflict
    from qdcnn.vision.detectors import QUANTUM_DETECTORS

    if exact and shots is not None:
        raise OptionConflict("--exact", "--shots", "exact probabilities use no shots")
    if model is not None and centroid is not None:
        raise OptionConflict("--model", "--centroid", "the model file holds the centroid")
    if model is not None and method not in QUANTUM_DETECTORS:
        raise OptionConflict(
            "--model", f"--method {method}", "a shadow model applies to the UU-dagger methods"
        )


def _mask_row(table: Table, record: Any) -> None:
    seconds = 1e3 * record["seconds"]
    table.add_row(
        Path(record["file"]).name, f"{100 * record['shadow_fraction']:.1f}", f"{seconds:.2f}"
    )


def _detection_line(result: ShadowDetectionResult) -> str:
    from qdcnn.experiments.shadow_batch import median_seconds

    med = median_seconds(result.records)
    timing = f"; median {1e3 * med:.2f} ms per image (measured)" if med is not None else ""
    return (
        f"{len(result.records)} masks in {result.out}, {len(result.failures)} failed, "
        f"{len(result.skipped)} skipped{timing}"
    )


def score_shadows_cmd(
    pred: Annotated[Path, typer.Option(help="Folder of <stem>_mask.png predictions.")],
    gt: Annotated[Path, typer.Option(help="Folder of <stem>.png ground-truth masks.")],
    as_json: JsonOpt = False,
) -> None:
    """Balanced error rate of predicted masks against ground truth (counts summed over the set)."""
    from qdcnn.experiments.shadow_batch import score_folders

    try:
        report = score_folders(pred, gt)
    except QdcnnError as exc:
        raise fail(exc) from None
    for f in report.failures:
        report_error(f.error)
    if as_json:
        emit(report.to_dict())
    elif report.scores:
        s = report.scores
        out.print(
            f"BER {s.ber:.2f}  shadow error {s.shadow_error:.2f}  non-shadow error "
            f"{s.nonshadow_error:.2f}  IoU {s.iou:.2f}  n {s.n}"
        )
    raise typer.Exit(1 if report.failures or report.scores is None else 0)


def train_shadows_cmd(
    *,
    shadow_set: Annotated[
        Path | None,
        typer.Option(help="Shadow set (required): DIR/images/* and DIR/masks/<stem>.png."),
    ] = None,
    out_file: Annotated[Path, typer.Option("--out", help="Model file to write (JSON).")],
    features: Annotated[
        str, typer.Option(help="intensity | chromaticity | intensity,chromaticity")
    ] = "intensity",
    centroids: Annotated[
        int, typer.Option(help="Components (1: the paper's single centroid).")
    ] = 1,
    search_threshold: Annotated[
        bool, typer.Option(help="Pick the threshold with the lowest training BER.")
    ] = True,
    seed: Annotated[int, typer.Option(help="Seed of the k-means start.")] = 0,
    as_json: JsonOpt = False,
    data: Annotated[Path | None, typer.Option("--data", hidden=True)] = None,
    quiet: QuietOpt = False,
) -> None:
    """Train a UU-dagger shadow model on images with masks.

    One feature and one centroid is the paper's model (centroid by the propagation
    algorithm, threshold from a grid that holds the paper's 0.75 and 0.97). Several
    features or centroids train the multi-centroid model: one centroid and threshold
    per feature and component.
    """
    from qdcnn.experiments.shadow_batch import ShadowTrainingSpec, train_shadows

    shadow_set = deprecated_spelling(shadow_set, data, "--data", "--shadow-set")
    if shadow_set is None:
        raise click.exceptions.UsageError("Missing option '--shadow-set'.")
    names = tuple(f.strip() for f in features.split(",") if f.strip())
    try:
        spec = ShadowTrainingSpec(shadow_set, out_file, names, centroids, search_threshold, seed)
        result = train_shadows(spec, CliReporter(False, quiet=quiet))
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json:
        emit(result.to_dict())
    else:
        out.print(f"{result.model.describe()}; written to {result.path}")
    raise typer.Exit(result.exit_code)
