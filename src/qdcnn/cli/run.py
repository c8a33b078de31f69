"""``run``: videos, image folders and recordings to per-frame decisions and overlays."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.table import Table

from qdcnn.cli._common import (
    BuiltinMethodOpt,
    CliReporter,
    EdgesOpt,
    FeaturesOpt,
    InnerLinesOpt,
    JsonOpt,
    LaneOptions,
    LanesOpt,
    MarksOpt,
    QuietOpt,
    SegmentAnglesOpt,
    ShadowRemovalOpt,
    TrackOpt,
    WaitOpt,
    emit,
    fail,
    out,
)
from qdcnn.errors import QdcnnError

if TYPE_CHECKING:
    from qdcnn.runtime.engine import RunResult


def run_cmd(
    inputs: Annotated[
        list[str],
        typer.Argument(help="Video files, image folders or udacity:/carla:/synthetic: specs."),
    ],
    out_dir: Annotated[Path, typer.Option("--out", help="Output folder.")],
    model: Annotated[Path | None, typer.Option(help="Model file from train-direction.")] = None,
    method: BuiltinMethodOpt = None,
    smooth: Annotated[int, typer.Option(help="Majority vote of the decision over K frames.")] = 1,
    video: Annotated[bool, typer.Option(help="Write overlay.mp4 per input.")] = True,
    scheduler: Annotated[
        str | None, typer.Option(help="local:N (N worker processes) or tcp://HOST:PORT (Dask).")
    ] = None,
    chunk: Annotated[int, typer.Option(help="Frames per chunk (the unit of resume).")] = 512,
    force: Annotated[bool, typer.Option(help="Redo finished chunks too.")] = False,
    wait: WaitOpt = 0.0,
    seed: Annotated[int, typer.Option(help="Seed of shot sampling and of the default model.")] = 0,
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
    """Per-frame direction, shadow fraction and lanes of every input; resumable after a crash.

    Writes DIR/<name>/frames.csv, timings.csv (measured ms), overlay.mp4 and DIR/summary.json.
    Frames keep the input's numbering (video frame, place in the sorted image folder, data
    row of the recording's label file): a bad one stays a row with status bad-row (a label
    row that cannot be used), unreadable or failed and a note, gets one error: line, and
    makes the exit status 1; the rest are still processed.
    A re-run with the same arguments skips finished chunks (--force redoes them). The lane
    options set the pipeline of the built-in lane model; without --model, --method or lane
    options the built-in QDCNN model decides when torch is installed (the output names the
    model). A --model file carries the lane settings it was trained with.
    """
    from qdcnn.experiments.run import RunSpec, run_with_model
    from qdcnn.runtime.engine import RunOptions

    try:
        options = RunOptions(
            chunk_frames=chunk, smooth=smooth, overlay=video, force=force, wait=wait
        )
        lane = LaneOptions(
            lanes, features, edges, shadow_removal, marks, segment_angles, inner_lines, track
        )
        spec = RunSpec(
            tuple(inputs), out_dir, model, method, options, scheduler, seed, lane.config(seed)
        )
        result, name = run_with_model(spec, CliReporter(as_json, quiet=quiet))
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json:
        emit({**result.to_dict(), "model": name})
    else:
        out.print(_run_table(result, name))
    raise typer.Exit(0 if result.ok else 1)


def _run_table(result: RunResult, model: str) -> Table:
    table = Table(
        "input", "frames", "frames / s", "directions", "first bad frame", title=f"run: {result.out}"
    )
    for r in result.inputs:
        fps = "-" if r.frames_per_second is None else f"{r.frames_per_second:.0f}"
        bad = "-" if r.first_bad_frame is None else str(r.first_bad_frame)
        directions = ", ".join(f"{k} {v}" for k, v in r.directions.items())
        table.add_row(r.name, str(r.frames), fps, r.error or directions, bad)
    table.caption = f"model: {model}; frames / s: this run's processing, measured"
    return table
