"""``bench shadows`` and ``bench pipeline``: measured times and ratios against references.

Each command imports its runner when it runs, so ``qdcnn --help`` loads none of them.
"""

from __future__ import annotations

from typing import Annotated, Any

import typer
from rich.table import Table

from qdcnn.cli._common import JsonOpt, QuietOpt, emit, err, fail, out
from qdcnn.errors import QdcnnError

bench_app = typer.Typer(
    help="Benchmarks: measured times and ratios against reference implementations.",
    no_args_is_help=True,
)


def _say(silent: bool, prefix: str = "") -> Any:
    return None if silent else lambda m: err.print(f"[dim]{prefix}{m}[/dim]", markup=True)


@bench_app.command("shadows")
def bench_shadows_cmd(
    frames: Annotated[int, typer.Option(help="Synthetic track2 frames per size.")] = 5,
    repeats: Annotated[int, typer.Option(help="Timed passes over the frames.")] = 15,
    aer_blocks: Annotated[
        int, typer.Option(help="Blocks timed one by one on Aer (0: skip).")
    ] = 200,
    lbp: Annotated[bool, typer.Option(help="Include the (slow) LBP baseline.")] = True,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Per-frame time of UU-dagger (exact, 1024 shots), per-block Aer, IBT, CBS and LBP."""
    from qdcnn.experiments.shadow_bench import bench_shadows

    try:
        result = bench_shadows(
            frames=frames,
            repeats=repeats,
            aer_blocks=aer_blocks,
            include_lbp=lbp,
            progress=_say(as_json or quiet, "timing "),
        )
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json:
        emit(result)
        return
    for row in result["results"]:
        out.print(_shadow_table(row))
        out.print(_ratio_line(row))
        if "ratio_aer_per_block_to_uu_shots" in row:
            ratio = row["ratio_aer_per_block_to_uu_shots"]
            out.print(f"per-block Aer / UU-dagger 1024 shots: {ratio:,.0f}x")
    out.print(_estimate_table(result["hardware_estimates"]))


def _shadow_table(row: dict[str, Any]) -> Table:
    table = Table(
        "detector", "ms / frame (measured)", "x IBT", title=f"{row['size']}, {row['blocks']} blocks"
    )
    ibt = row["seconds"]["ibt"]
    for name, sec in row["seconds"].items():
        table.add_row(name, f"{1e3 * sec:.3f}", f"{sec / ibt:.2f}")
    if "aer_per_block" in row:
        aer = row["aer_per_block"]
        table.add_row(
            f"aer per block (scaled from {aer['blocks_timed']} blocks)",
            f"{1e3 * aer['seconds_per_frame']:.1f}",
            f"{aer['seconds_per_frame'] / ibt:.0f}",
        )
    return table


def _ratio_line(row: dict[str, Any]) -> str:
    """UU-dagger / IBT for each variant, beside its target (issue 22)."""
    from qdcnn.experiments.shadow_bench import IBT_TARGETS

    parts = [
        f"{name.removeprefix('uu-')} {ratio:.2f}x (target {IBT_TARGETS[name]:g}x)"
        for name, ratio in row["ratios_to_ibt"].items()
    ]
    return f"UU-dagger / IBT, {row['size']}: " + ", ".join(parts)


def _estimate_table(estimates: list[dict[str, Any]]) -> Table:
    table = Table(
        "profile",
        "seconds (estimate)",
        "source",
        title="hardware-time model (estimates, not measured)",
    )
    for e in estimates:
        table.add_row(e["profile"], f"{e['seconds']:.6g}", e["source"])
    return table


@bench_app.command("pipeline")
def bench_pipeline_cmd(
    data: Annotated[
        str, typer.Option(help="Frames to time (a dataset spec).")
    ] = "synthetic:track1:200",
    frames: Annotated[int, typer.Option(help="Frames timed per pass.")] = 100,
    one_core: Annotated[bool, typer.Option(help="Pin the process to one CPU core.")] = True,
    cnn: Annotated[bool, typer.Option(help="Also time CNN inference (needs torch).")] = True,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Frames/s of the whole per-frame pipeline (shadow, lanes, decision) per method."""
    from qdcnn.experiments.pipeline_bench import bench_pipeline

    try:
        result = bench_pipeline(
            data=data, frames=frames, one_core=one_core, cnn=cnn, say=_say(as_json or quiet)
        )
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json:
        emit(result)
    else:
        out.print(_pipeline_table(result))


def _pipeline_table(result: dict[str, Any]) -> Table:
    where = "one core" if result["one_core"] else "all cores"
    w, h = result["size"]
    table = Table(
        "pipeline",
        "ms / frame",
        "frames / s",
        title=f"{result['frames']} frames of {result['data']} at {w}x{h}, {where} (measured)",
    )
    for row in result["pipeline"]:
        table.add_row(
            row["method"], f"{row['ms_per_frame']:.2f}", f"{row['frames_per_second']:.0f}"
        )
    for row in result.get("cnn_inference", []):
        fps = row["frames_per_second"]
        table.add_row(f"CNN {row['arch']} (inference only)", f"{1e3 / fps:.2f}", f"{fps:.0f}")
    return table
