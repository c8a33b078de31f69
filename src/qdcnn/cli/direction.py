"""``evaluate``, ``train-direction`` and ``detect-lanes``: lane lines to a direction.

The runners, the config and the method registry are imported when a command runs, so
``qdcnn --help`` and option errors load none of them.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.table import Table

from qdcnn.cli._common import (
    CacheOpt,
    CliReporter,
    EdgesOpt,
    EpochsOpt,
    FeaturesOpt,
    FoldsOpt,
    GapOpt,
    InnerFoldsOpt,
    InnerLinesOpt,
    JsonOpt,
    LabelThresholdOpt,
    LaneOptions,
    LanesOpt,
    MarksOpt,
    QuietOpt,
    SeedOpt,
    SegmentAnglesOpt,
    ShadowRemovalOpt,
    SteeringUnitOpt,
    ThreadsOpt,
    TrackOpt,
    WaitOpt,
    emit,
    fail,
    out,
)
from qdcnn.errors import ParameterError, QdcnnError

if TYPE_CHECKING:
    from qdcnn.direction.methods import TrainingOptions
    from qdcnn.experiments.detect_lanes import DetectLanesResult
    from qdcnn.experiments.evaluate import EvaluationResult

DataOpt = Annotated[str, typer.Option(help="udacity:PATH | carla:PATH | synthetic:PRESET[:N]")]
SchedulerOpt = Annotated[
    str | None, typer.Option(help="Run folds on Dask: local:N (N workers) or tcp://HOST:PORT.")
]
HeadOpt = Annotated[
    str, typer.Option(help="Hybrid qdcnn-* methods: quantum | classical (the twin) | both.")
]
ContextOpt = Annotated[
    int, typer.Option(help="Frames stacked as one CNN/hybrid input (this and the K-1 before).")
]
WeightsOpt = Annotated[
    Path | None, typer.Option(help="ImageNet weights for dnn-resnet50 (state_dict).")
]
ForceOpt = Annotated[bool, typer.Option(help="Redo images already done.")]


def training_options(
    epochs: int, weights: Path | None, threads: int | None, progress: bool, context: int = 1
) -> TrainingOptions:
    from qdcnn.direction.methods import TrainingOptions

    if threads is not None and threads < 1:
        raise ParameterError("threads", threads, "a positive integer")
    return TrainingOptions(
        epochs=epochs, weights=weights, threads=threads, progress=progress, context=context
    )


def evaluate_cmd(
    data: DataOpt,
    method: Annotated[
        str,
        typer.Option(
            help="A method, a comma list or 'all' (every registered method; those needing "
            "torch are left out without the dnn extra, dnn-resnet50 without a GPU)."
        ),
    ] = "all",
    folds: FoldsOpt = 5,
    gap: GapOpt = 5,
    inner_folds: InnerFoldsOpt = 3,
    lanes: LanesOpt = "udacity",
    epochs: EpochsOpt = 25,
    weights: WeightsOpt = None,
    seed: SeedOpt = 0,
    cache: CacheOpt = True,
    features: FeaturesOpt = "slopes",
    edges: EdgesOpt = "grey",
    shadow_removal: ShadowRemovalOpt = True,
    threads: ThreadsOpt = None,
    head: HeadOpt = "quantum",
    context: ContextOpt = 1,
    steering_unit: SteeringUnitOpt = "auto",
    label_threshold: LabelThresholdOpt = None,
    marks: MarksOpt = "none",
    segment_angles: SegmentAnglesOpt = None,
    inner_lines: InnerLinesOpt = False,
    track: TrackOpt = "none",
    scheduler: SchedulerOpt = None,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Cross-validated direction accuracy with contiguous folds (the paper's accuracy table)."""
    from qdcnn.direction.methods import with_head
    from qdcnn.experiments.evaluate import EvaluationSpec, run_evaluation

    try:
        lane = LaneOptions(
            lanes, features, edges, shadow_removal, marks, segment_angles, inner_lines, track
        )
        config = lane.config(seed, steering_unit, label_threshold)
        spec = EvaluationSpec(
            data,
            with_head(method, head),
            config,
            folds,
            gap,
            inner_folds,
            training_options(epochs, weights, threads, not as_json, context),
            use_cache=cache,
            scheduler=scheduler,
        )
        result = run_evaluation(spec, CliReporter(as_json, quiet=quiet))
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json and result.failures:
        emit({"summary": True, "failures": [f.to_dict() for f in result.failures]})
    elif not as_json:
        out.print(_evaluation_table(result))
        balance = ", ".join(f"{k} {v}" for k, v in result.labels["class_balance"].items())
        out.print(
            f"{result.labels['description']}; classes: {balance}", markup=False, soft_wrap=True
        )
    raise typer.Exit(result.exit_code)


def _evaluation_table(result: EvaluationResult) -> Table:
    p = result.protocol
    table = Table(
        "method",
        "accuracy",
        "± std",
        "majority",
        "no lines",
        "seconds",
        title=f"{result.dataset}: {result.n_frames} frames, {p['folds']} contiguous folds "
        f"(gap {p['gap']}); accuracy pooled over test frames",
    )
    for r in result.results:
        table.add_row(
            r.method,
            f"{r.accuracy:.3f}",
            f"{r.accuracy_std:.3f}",
            f"{r.majority_baseline:.3f}",
            str(r.frames_without_lines),
            f"{r.seconds:.1f}",
        )
    return table


def train_direction_cmd(
    data: DataOpt,
    out_file: Annotated[Path, typer.Option("--out", help="Model file to write (.safetensors).")],
    method: Annotated[
        str, typer.Option(help="A registered method (see evaluate).")
    ] = "image-split-uu",
    lanes: LanesOpt = "udacity",
    inner_folds: InnerFoldsOpt = 3,
    gap: GapOpt = 5,
    epochs: EpochsOpt = 25,
    weights: WeightsOpt = None,
    threads: ThreadsOpt = None,
    seed: SeedOpt = 0,
    features: FeaturesOpt = "slopes",
    edges: EdgesOpt = "grey",
    shadow_removal: ShadowRemovalOpt = True,
    head: HeadOpt = "quantum",
    context: ContextOpt = 1,
    steering_unit: SteeringUnitOpt = "auto",
    label_threshold: LabelThresholdOpt = None,
    marks: MarksOpt = "none",
    segment_angles: SegmentAnglesOpt = None,
    inner_lines: InnerLinesOpt = False,
    track: TrackOpt = "none",
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Train a direction classifier on all frames of a dataset and save it.

    Hyperparameters are chosen by the inner contiguous cross-validation evaluate uses.
    """
    from qdcnn.direction.methods import with_head
    from qdcnn.experiments.train_direction import TrainDirectionSpec, train_direction

    try:
        lane = LaneOptions(
            lanes, features, edges, shadow_removal, marks, segment_angles, inner_lines, track
        )
        config = lane.config(seed, steering_unit, label_threshold)
        spec = TrainDirectionSpec(
            data,
            out_file,
            with_head(method, "classical" if head == "classical" else "quantum"),
            config,
            inner_folds,
            gap,
            training_options(epochs, weights, threads, not as_json, context),
        )
        result = train_direction(spec, CliReporter(False, quiet=quiet))
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json:
        emit(result.to_dict())
    else:
        s = result.model.summary
        out.print(
            f"{result.model.method} trained on {s['n']} frames of {data} "
            f"(training accuracy {s['training_accuracy']:.3f}); written to {result.path}"
        )
    raise typer.Exit(result.exit_code)


def detect_lanes_cmd(
    paths: Annotated[list[Path], typer.Argument(help="Image files and/or folders of images.")],
    out_dir: Annotated[Path, typer.Option("--out", help="Folder for overlays and predictions.")],
    model: Annotated[Path | None, typer.Option(help="Model from train-direction.")] = None,
    method: Annotated[str, typer.Option(help="Method when no model is given.")] = "image-split-uu",
    seed: SeedOpt = 0,
    force: ForceOpt = False,
    wait: WaitOpt = 0.0,
    lanes: LanesOpt = "udacity",
    features: FeaturesOpt = "slopes",
    edges: EdgesOpt = "grey",
    shadow_removal: ShadowRemovalOpt = True,
    marks: MarksOpt = "none",
    segment_angles: SegmentAnglesOpt = None,
    inner_lines: InnerLinesOpt = False,
    track: TrackOpt = "none",
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Lane overlays and a left/straight/right decision per frame; resumable.

    Without --model, the built-in model of --method is used: trained once on 300 frames of
    each synthetic preset (track1, track2, rain) with the lane options, cached, and named
    in the output. A --model file carries the lane settings it was trained with.
    """
    from qdcnn.experiments.detect_lanes import DetectLanesSpec, detect_lanes

    try:
        lane = LaneOptions(
            lanes, features, edges, shadow_removal, marks, segment_angles, inner_lines, track
        )
        spec = DetectLanesSpec(
            tuple(paths), out_dir, model, method, seed, force, wait, lane.config(seed)
        )
        result = detect_lanes(spec, CliReporter(as_json, quiet=quiet))
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json:
        emit(result.to_dict())
    else:
        out.print(_lanes_table(result))
    raise typer.Exit(result.exit_code)


def _lanes_table(result: DetectLanesResult) -> Table:
    table = Table("file", "direction", "lines", "ms", title=f"lanes: {result.model.method}")
    for r in result.records:
        table.add_row(Path(r.file).name, r.direction, r.status, f"{1e3 * r.seconds:.2f}")
    table.caption = (
        f"{len(result.records)} overlays and predictions.csv in {result.out}; "
        f"{len(result.failures)} failed; model {result.model.method} trained on "
        f"{result.model.trained_on}"
    )
    return table
