"""``noise-sweep`` (the paper's Fig. 7) and ``circuit`` (inspect and export a circuit).

The runners and the config are imported when a command runs, so ``qdcnn --help`` loads
none of the quantum stack.
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
    deprecated_spelling,
    emit,
    fail,
    out,
)
from qdcnn.cli.direction import SchedulerOpt, training_options
from qdcnn.errors import QdcnnError

if TYPE_CHECKING:
    from qdcnn.experiments.circuit import CircuitInspection
    from qdcnn.experiments.noise.runner import NoiseSweepRun

DataOpt = Annotated[
    str | None,
    typer.Option(help="Direction data: udacity:PATH | carla:PATH | synthetic:PRESET[:N]."),
]
MethodOpt = Annotated[
    str, typer.Option(help="Comma list of uu, vqc, uu-shadow, all or registered quantum methods.")
]
#: The old spelling of --method, hidden; it still works, with a note that it is deprecated.
MethodsAlias = Annotated[str | None, typer.Option("--methods", hidden=True)]
ChannelsOpt = Annotated[
    str,
    typer.Option(
        help="'all' (the six of Fig. 7) or a comma list: bit-flip, phase-flip, bit-phase-flip, "
        "depolarizing, amplitude-damping, phase-damping, phase-damping-paper."
    ),
]
StrengthsOpt = Annotated[
    str, typer.Option("--p", help="Strengths: START:STOP:STEP (STOP included) or a comma list.")
]
PhaseDampingOpt = Annotated[
    str,
    typer.Option(
        help="What 'phase-damping' means: textbook (Qiskit's phase_damping_error) or paper "
        "(the printed operators)."
    ),
]
GroupingOpt = Annotated[
    str, typer.Option(help="Lane grouping(s) of uu/vqc, comma list: image-split, kmeans, spectral.")
]
TrainNoiseOpt = Annotated[
    bool,
    typer.Option(
        "--train-under-noise",
        help="Retrain under each noise setting (default: train once, noiseless).",
    ),
]
ShotsOpt = Annotated[
    int | None, typer.Option(help="Shots per circuit at evaluation (default: exact probabilities).")
]
ReadoutOpt = Annotated[float, typer.Option(help="Readout error added at every point, in [0, 1].")]
ShadowSetOpt = Annotated[
    Path | None,
    typer.Option(
        help="Shadow set DIR/images/* + DIR/masks/<stem>.png for uu-shadow (implies uu-shadow; "
        "default: synthetic track2 scenes)."
    ),
]
ShadowFramesOpt = Annotated[
    int, typer.Option(help="Synthetic track2 scenes for uu-shadow (half train, half test).")
]
ThresholdsOpt = Annotated[
    str,
    typer.Option(help="Shadow threshold candidates: grid (as train-shadows) | paper (0.75, 0.97)."),
]
PlotOpt = Annotated[
    Path | None, typer.Option(help="Write the accuracy figure here (shadow BER: NAME_shadow.EXT).")
]


def noise_sweep_cmd(
    data: DataOpt = None,
    method: MethodOpt = "uu,vqc",
    channels: ChannelsOpt = "all",
    p: StrengthsOpt = "0:0.99:0.11",
    phase_damping: PhaseDampingOpt = "textbook",
    grouping: GroupingOpt = "image-split",
    train_under_noise: TrainNoiseOpt = False,
    shots: ShotsOpt = None,
    readout: ReadoutOpt = 0.0,
    folds: FoldsOpt = 5,
    gap: GapOpt = 5,
    inner_folds: InnerFoldsOpt = 3,
    lanes: LanesOpt = "udacity",
    shadow_set: ShadowSetOpt = None,
    shadow_frames: ShadowFramesOpt = 24,
    shadow_thresholds: ThresholdsOpt = "grid",
    plot: PlotOpt = None,
    seed: SeedOpt = 0,
    cache: CacheOpt = True,
    steering_unit: SteeringUnitOpt = "auto",
    label_threshold: LabelThresholdOpt = None,
    epochs: EpochsOpt = 25,
    threads: ThreadsOpt = None,
    scheduler: SchedulerOpt = None,
    features: FeaturesOpt = "slopes",
    edges: EdgesOpt = "grey",
    shadow_removal: ShadowRemovalOpt = True,
    marks: MarksOpt = "none",
    segment_angles: SegmentAnglesOpt = None,
    inner_lines: InnerLinesOpt = False,
    track: TrackOpt = "none",
    as_json: JsonOpt = False,
    methods: MethodsAlias = None,
    quiet: QuietOpt = False,
) -> None:
    """Accuracy against noise strength for each channel and method (the paper's Fig. 7).

    Models are trained once without noise and evaluated under each (channel, p) with exact
    density-matrix probabilities, unless --train-under-noise or --shots say otherwise.
    Noise acts after every gate on every qubit the gate touches, as in a Qiskit Aer
    NoiseModel. uu-shadow adds the UU-dagger shadow detector's BER on images with masks.
    """
    from qdcnn.experiments.noise import options
    from qdcnn.experiments.noise.runner import NoiseSweepSpec, run_noise_sweep

    method = deprecated_spelling(method, methods, "--methods", "--method")
    try:
        lane = LaneOptions(
            lanes, features, edges, shadow_removal, marks, segment_angles, inner_lines, track
        )
        config = lane.config(seed, steering_unit, label_threshold)
        spec = NoiseSweepSpec(
            data,
            options.parse_methods(method),
            options.parse_channels(channels, phase_damping),
            options.parse_strengths(p),
            options.parse_groupings(grouping),
            train_under_noise, shots, readout, folds, gap, inner_folds, config, shadow_set,
            shadow_frames, plot, seed, cache,
            options.parse_shadow_thresholds(shadow_thresholds),
            training_options(epochs, None, threads, False), scheduler,
        )  # fmt: skip
        run = run_noise_sweep(spec, CliReporter(False, quiet=quiet))
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json:
        for obj in run.to_dicts():
            emit(obj)
    else:
        _print_sweep(run)
    raise typer.Exit(run.exit_code)


def _print_sweep(run: NoiseSweepRun) -> None:
    for sweep in run.result.tables():
        table = Table(*sweep.headers)
        for cells in sweep.cells():
            table.add_row(*cells)
        out.print(sweep.title, markup=False)
        out.print(table)
    for line in run.result.summary_lines():
        out.print(line, markup=False)
    for path in run.figures:
        out.print(f"figure written to {path}", markup=False)


def circuit_cmd(
    kind: Annotated[
        str, typer.Argument(help="uu (UU-dagger test) | vqc (2-qubit VQC) | head (hybrid head)")
    ],
    theta_c: Annotated[
        str | None, typer.Option("--theta-c", help="uu: centroid angle in radians (1.2, pi/2).")
    ] = None,
    theta_x: Annotated[str | None, typer.Option("--theta-x", help="uu: test-value angle.")] = None,
    x: Annotated[
        str | None, typer.Option("--x", help="vqc: X1,X2; head: one encoding angle per qubit.")
    ] = None,
    weights: Annotated[
        str | None,
        typer.Option(help="vqc: W1..W4 (2 (reps + 1)); head: layers x qubits x 3 Rot angles."),
    ] = None,
    qubits: Annotated[int | None, typer.Option(help="head: qubits (1 to 8).")] = None,
    layers: Annotated[int | None, typer.Option(help="head: entangling layers.")] = None,
    model: Annotated[
        Path | None, typer.Option(help="head: the trained head of a saved qdcnn-* model.")
    ] = None,
    feature_map_reps: Annotated[int, typer.Option(help="vqc: repetitions of the ZZ map.")] = 2,
    noise: Annotated[
        str | None, typer.Option(help="CHANNEL:P[,readout:E], e.g. depolarizing:0.1.")
    ] = None,
    shots: Annotated[int | None, typer.Option(help="Shot estimates (default: exact).")] = None,
    backend: Annotated[str, typer.Option(help="numpy | aer")] = "numpy",
    seed: Annotated[int, typer.Option(help="Seed of the shots.")] = 0,
    qasm: Annotated[
        Path | None, typer.Option(help="Write the circuit as OpenQASM 3 (measured) to this file.")
    ] = None,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Print a circuit's diagram and outcome probabilities; optionally export OpenQASM 3.

    Probabilities are indexed by basis state with qubit 0 the least significant bit, as in
    Qiskit. With --noise the channel acts after every gate on every qubit it touches.
    """
    from qdcnn.experiments.circuit import CircuitSpec, inspect_circuit

    try:
        spec = CircuitSpec(
            kind, theta_c, theta_x, x, weights, feature_map_reps, noise, shots, backend, seed,
            qasm, qubits, layers, False, model,
        )  # fmt: skip
        result = inspect_circuit(spec, CliReporter(False, quiet=quiet))
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json:
        emit(result.to_dict())
    else:
        _print_circuit(result)


def _print_circuit(result: CircuitInspection) -> None:
    out.print(result.diagram, markup=False, highlight=False, soft_wrap=True)
    out.print(result.header, markup=False)
    table = Table(result.state_header, "index", "probability")
    for i, (s, v) in enumerate(zip(result.states, result.probabilities, strict=True)):
        table.add_row(s, str(i), f"{v:.6f}")
    out.print(table)
    if result.qasm is not None:
        out.print(f"OpenQASM 3 written to {result.qasm}", markup=False)
