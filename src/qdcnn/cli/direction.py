"""``evaluate``, ``train-direction`` and ``detect-lanes``: lane lines to a direction.

The runners, the config and the method registry are imported when a command runs, so
``qdcnn --help`` and option errors load none of them.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.table import Table

from qdcnn.cli._common import (
    BuiltinMethodOpt,
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
    from qdcnn.direction.protocol import MethodResult
    from qdcnn.experiments.detect_lanes import DetectLanesResult
    from qdcnn.experiments.evaluate import EvaluationResult
    from qdcnn.experiments.train_direction import TrainDirectionResult

DataOpt = Annotated[str, typer.Option(help="udacity:PATH | carla:PATH | synthetic:PRESET[:N]")]
DataListOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--data",
        help="udacity:PATH | carla:PATH | synthetic:PRESET[:N]; repeat for leave-one-out.",
    ),
]
TrainOpt = Annotated[
    list[str] | None,
    typer.Option("--train", help="Training recording (repeatable); needs --test."),
]
TestOpt = Annotated[
    list[str] | None,
    typer.Option("--test", help="Test recording (repeatable), scored on its own."),
]
ProtocolOpt = Annotated[
    str,
    typer.Option(help="k-fold (inside one --data) | leave-one-out (each --data the test set)."),
]
SeedsOpt = Annotated[
    int, typer.Option(help="Retrain every model with seeds SEED .. SEED+K-1; figures are means.")
]
PairedOpt = Annotated[
    bool,
    typer.Option(help="Balanced-accuracy difference of each method to the first, paired interval."),
]
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
TransferOpt = Annotated[
    bool,
    typer.Option(
        help="Hybrids: train the trunk with a linear head, then the head on the frozen trunk, "
        "then fine-tune all at a tenth of the rate."
    ),
]
BalancedOpt = Annotated[
    bool,
    typer.Option(
        help="CNNs (PilotNet, and so the hybrids' stage 1) train as the hybrids do: "
        "class-balanced loss, the epoch of the best validation balanced accuracy, "
        "restarts of one-class runs."
    ),
]
StandardiseOpt = Annotated[
    bool,
    typer.Option(
        "--standardise-frames",
        help="PilotNet and qdcnn-head (twin, ablations): put each frame on its own scale first "
        "(its planes minus their means, over its Y spread), so shade and dusk look like sun.",
    ),
]
EdgeFramesOpt = Annotated[
    bool,
    typer.Option(
        "--edge-frames",
        help="PilotNet and qdcnn-head (twin, ablations): see each frame's edges (Sobel "
        "gradients of Y and their size, over twice the frame's mean size): only them, or with "
        "--standardise-frames both (six planes a frame).",
    ),
]
EnsembleOpt = Annotated[
    int,
    typer.Option(
        help="CNNs and hybrids: train K networks (1-9; seeds SEED, SEED+1000, ...) and decide "
        "by the mean of their class probabilities.",
    ),
]
FromOpt = Annotated[
    Path | None,
    typer.Option(
        "--from",
        help="Hybrids: start from this saved network's trunk (same architecture, input size "
        "and context), then train the head and fine-tune.",
    ),
]


def training_options(
    epochs: int,
    weights: Path | None,
    threads: int | None,
    progress: bool,
    context: int = 1,
    transfer: bool = False,
    balanced: bool = False,
    standardise_frames: bool = False,
    edge_frames: bool = False,
    ensemble: int = 1,
    *,
    from_model: Path | None = None,
) -> TrainingOptions:
    from qdcnn.direction.methods import TrainingOptions
    from qdcnn.models.ensemble import MAX_ENSEMBLE

    if threads is not None and threads < 1:
        raise ParameterError("threads", threads, "a positive integer")
    if not 1 <= ensemble <= MAX_ENSEMBLE:
        raise ParameterError("ensemble", ensemble, f"1 to {MAX_ENSEMBLE} networks")
    return TrainingOptions(
        epochs=epochs,
        weights=weights,
        threads=threads,
        progress=progress,
        context=context,
        transfer=transfer,
        from_model=from_model,
        balanced=balanced,
        standardise_frames=standardise_frames,
        edge_frames=edge_frames,
        params={"ensemble": ensemble} if ensemble > 1 else {},
    )


def evaluate_cmd(
    data: DataListOpt = None,
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
    transfer: TransferOpt = False,
    balanced: BalancedOpt = False,
    std: StandardiseOpt = False,
    edge: EdgeFramesOpt = False,
    ensemble: EnsembleOpt = 1,
    steering_unit: SteeringUnitOpt = "auto",
    label_threshold: LabelThresholdOpt = None,
    marks: MarksOpt = "none",
    segment_angles: SegmentAnglesOpt = None,
    inner_lines: InnerLinesOpt = False,
    track: TrackOpt = "none",
    scheduler: SchedulerOpt = None,
    train: TrainOpt = None,
    test: TestOpt = None,
    protocol: ProtocolOpt = "k-fold",
    seeds: SeedsOpt = 1,
    paired: PairedOpt = False,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Direction scores with intervals: contiguous folds inside one recording (the paper's
    accuracy table), or trained on some recordings and tested on others."""
    from qdcnn.direction.methods import with_head
    from qdcnn.experiments.evaluate import EvaluationSpec, run_evaluation

    try:
        lane = LaneOptions(
            lanes, features, edges, shadow_removal, marks, segment_angles, inner_lines, track
        )
        config = lane.config(seed, steering_unit, label_threshold)
        one, loo = recordings(data or [], protocol)
        progress = not as_json
        spec = EvaluationSpec(
            one,
            with_head(method, head),
            config,
            folds,
            gap,
            inner_folds,
            training_options(
                epochs, weights, threads, progress, context, transfer, balanced, std, edge, ensemble
            ),
            use_cache=cache,
            scheduler=scheduler,
            train=tuple(train or ()),
            test=tuple(test or ()),
            leave_one_out=loo,
            seeds=seeds,
            paired=paired,
        )
        result = run_evaluation(spec, CliReporter(as_json, quiet=quiet))
    except QdcnnError as exc:
        raise fail(exc) from None
    _finish_evaluation(result, as_json)


def _finish_evaluation(result: EvaluationResult, as_json: bool) -> None:
    """Emit or print ``result`` (comparisons, failures), then exit with its code."""
    if as_json and result.comparisons:
        emit({"comparisons": result.comparisons})
    if as_json and result.failures:
        emit({"summary": True, "failures": [f.to_dict() for f in result.failures]})
    elif not as_json:
        _print_evaluation(result)
    raise typer.Exit(result.exit_code)


def recordings(data: list[str], protocol: str) -> tuple[str, tuple[str, ...]]:
    """``--data`` as the k-fold recording, or the leave-one-out recordings."""
    if protocol == "leave-one-out":
        return "", tuple(data)
    if protocol != "k-fold":
        raise ParameterError("protocol", protocol, "'k-fold' or 'leave-one-out'")
    if len(data) > 1:
        raise ParameterError(
            "data", ",".join(data), "one recording for k-fold (several: --protocol leave-one-out)"
        )
    return (data[0] if data else ""), ()


#: The line under every table saying what the majority baseline is.
MAJORITY_LINE = (
    "majority: the training frames' most frequent class for every test frame; with contiguous "
    "folds its accuracy can fall below chance, as that class may be rare in the test block"
)


def _print_evaluation(result: EvaluationResult) -> None:
    out.print(_evaluation_table(result))
    for line in _evaluation_lines(result):
        out.print(line, markup=False, soft_wrap=True)
    if result.comparisons:
        out.print(_comparison_table(result))


def _evaluation_lines(result: EvaluationResult) -> list[str]:
    """What goes under the table: baselines, recordings, labels, notes."""
    lines = [MAJORITY_LINE, "chance: balanced accuracy 1/3 (0.33) for any guess"]
    if len(result.trained_on) == len(result.tested_on) > 1:  # leave-one-out
        for train, test in zip(result.trained_on, result.tested_on, strict=True):
            lines.append(f"tested on {test}, trained on {', '.join(train)}")
    elif result.tested_on:
        lines.append(f"trained on {', '.join(result.trained_on[0])}")
        lines.append(f"tested on {', '.join(result.tested_on)} (each on its own)")
    labels = result.labels if "description" not in result.labels else {"": result.labels}
    for name, info in labels.items():
        balance = ", ".join(f"{k} {v}" for k, v in info["class_balance"].items())
        lines.append(f"{name + ': ' if name else ''}{info['description']}; classes: {balance}")
    seen: set[str] = set()
    for r in result.results:
        for note in r.notes:
            if note not in seen:
                seen.add(note)
                lines.append(f"note: {r.method} on {r.dataset}: {note}")
    return lines


def _comparison_table(result: EvaluationResult) -> Table:
    table = Table(
        "balanced accuracy: A - B [95 %]",
        "test set",
        title="paired differences on the same test frames (block bootstrap)",
    )
    for c in result.comparisons:
        table.add_row(f"{c['a']} - {c['b']}: {c['text']}", c["dataset"])
    return table


def _evaluation_table(result: EvaluationResult) -> Table:
    p = result.protocol
    cross = "folds" not in p
    if cross:
        title = f"{p['protocol']}: scores per test recording, 95 % block-bootstrap intervals"
    else:
        title = (
            f"{result.dataset}: {result.n_frames} frames, {p['folds']} contiguous folds "
            f"(gap {p['gap']}); scores pooled over test frames, 95 % block-bootstrap intervals"
        )
    columns = ["method", *(["test set"] if cross else [])]
    table = Table(
        *columns, "balanced accuracy", "accuracy", "macro-F1", "no lines", "seconds", title=title
    )
    order = {name: i for i, name in enumerate(dict.fromkeys(r.dataset for r in result.results))}
    done: set[str] = set()
    for r in sorted(result.results, key=lambda r: order[r.dataset]):
        where = [r.dataset] if cross else []
        if r.dataset not in done:
            done.add(r.dataset)
            _baseline_rows(table, r, where)
        table.add_row(
            r.method,
            *where,
            _with_interval(r.balanced_accuracy, r.balanced_accuracy_ci),
            _with_interval(r.accuracy, r.accuracy_ci),
            f"{r.macro_f1:.2f}",
            str(r.frames_without_lines),
            f"{r.seconds:.1f}",
        )
    return table


def _baseline_rows(table: Table, r: MethodResult, where: list[str]) -> None:
    """The training majority and chance rows of ``r``'s test set."""
    m = r.majority
    table.add_row(
        "majority (training)",
        *where,
        _with_interval(m.get("balanced_accuracy"), None),
        _with_interval(m.get("accuracy", r.majority_baseline), None),
        f"{m.get('macro_f1', 0.0):.2f}",
        "",
        "",
    )
    table.add_row("chance", *where, "0.33", "", "", "", "")


def _with_interval(value: float | None, interval: dict[str, Any] | None) -> str:
    from qdcnn.direction.scores import format_value

    return format_value(value, interval)


def train_direction_cmd(
    data: Annotated[
        list[str],
        typer.Option(
            help="udacity:PATH | carla:PATH | synthetic:PRESET[:N]; repeat to train on several."
        ),
    ],
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
    transfer: TransferOpt = False,
    balanced: BalancedOpt = False,
    standardise_frames: StandardiseOpt = False,
    edge_frames: EdgeFramesOpt = False,
    ensemble: EnsembleOpt = 1,
    from_model: FromOpt = None,
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
            tuple(data),
            out_file,
            with_head(method, "classical" if head == "classical" else "quantum"),
            config,
            inner_folds,
            gap,
            training_options(
                epochs,
                weights,
                threads,
                not as_json,
                context,
                transfer=transfer,
                balanced=balanced,
                from_model=from_model,
                standardise_frames=standardise_frames,
                edge_frames=edge_frames,
                ensemble=ensemble,
            ),
        )
        result = train_direction(spec, CliReporter(False, quiet=quiet))
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json:
        emit(result.to_dict())
    else:
        _print_trained(result, data)
    raise typer.Exit(result.exit_code)


def _print_trained(result: TrainDirectionResult, data: list[str]) -> None:
    """What ``train-direction`` trained, where it went, and any restarted run."""
    s = result.model.summary
    out.print(
        f"{result.model.method} trained on {s['n']} frames of {' + '.join(data)} "
        f"(training accuracy {s['training_accuracy']:.3f}); written to {result.path}"
    )
    for r in s.get("restarts", []):
        out.print(
            f"note: the run with seed {r['seed']} predicted one class on its validation "
            f"frames ({r['val_predictions']}); restarted with seed {r['next_seed']}"
        )


def detect_lanes_cmd(
    paths: Annotated[list[Path], typer.Argument(help="Image files and/or folders of images.")],
    out_dir: Annotated[Path, typer.Option("--out", help="Folder for overlays and predictions.")],
    model: Annotated[Path | None, typer.Option(help="Model from train-direction.")] = None,
    method: BuiltinMethodOpt = None,
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

    Without --model the built-in model decides, named in the output: with torch the
    built-in QDCNN model shipped with qdcnn (a qdcnn-head hybrid); without torch, or with
    --method or lane options, the built-in lane model of --method (default image-split-uu),
    trained once on 300 frames of each synthetic preset with the lane options and cached.
    A --model file carries the lane settings it was trained with.
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
        f"{len(result.failures)} failed; model: {result.model_name}"
    )
    return table
