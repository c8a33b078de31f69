"""The ``qdcnn`` command line: thin commands over the library.

With ``--json`` stdout carries only JSON (one object per line); progress bars
and error lines go to stderr. Exit status: 0 when everything worked, 1 when
some items failed (the others are still processed and reported), 2 for bad
options or unusable input.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

from qdcnn.config import ShadowConfig
from qdcnn.errors import QdcnnError

T = TypeVar("T")

app = typer.Typer(
    name="qdcnn",
    help="QDCNN: UU-dagger shadow detection, quantum lane-direction classifiers, noise studies.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
bench_app = typer.Typer(
    help="Benchmarks: measured times and ratios against reference implementations.",
    no_args_is_help=True,
)
app.add_typer(bench_app, name="bench")

out = Console(highlight=False)
err = Console(stderr=True, highlight=False)

JsonOpt = Annotated[
    bool, typer.Option("--json", help="Print only JSON on stdout (one object per line).")
]


def emit(obj: dict[str, Any]) -> None:
    """Print one JSON object on its own line and flush, so finished results are never lost."""
    sys.stdout.write(json.dumps(obj, default=_jsonable) + "\n")
    sys.stdout.flush()


def _jsonable(value: Any) -> Any:
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def report_error(message: str) -> None:
    """One line on stderr."""
    err.print(f"[red]error:[/red] {message}", soft_wrap=True, markup=True)


def progress(items: Iterable[T], total: int, description: str) -> Iterator[T]:
    """Iterate with a progress bar on stderr (hidden when stderr is not a terminal)."""
    bar = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeRemainingColumn(),
        console=err,
        transient=True,
        disable=not err.is_terminal,
    )
    with bar:
        task = bar.add_task(description, total=total)
        for item in items:
            yield item
            bar.advance(task)


def fail_on_error(exc: QdcnnError) -> typer.Exit:
    report_error(" ".join(str(exc).split()))
    return typer.Exit(2)


@app.command("detect-shadows")
def detect_shadows_cmd(
    paths: Annotated[list[Path], typer.Argument(help="Image files and/or folders of images.")],
    out_dir: Annotated[Path, typer.Option("--out", help="Folder for <stem>_mask.png files.")],
    method: Annotated[str, typer.Option(help="uu | uu-chroma | ibt | cbs | lbp")] = "uu",
    exact: Annotated[
        bool, typer.Option("--exact", help="Exact probabilities instead of shots.")
    ] = False,
    shots: Annotated[int, typer.Option(help="Shots per block circuit (paper: 1024).")] = 1024,
    backend: Annotated[str, typer.Option(help="numpy | aer")] = "numpy",
    threshold: Annotated[
        float | None, typer.Option(help="Fidelity threshold (default 0.97).")
    ] = None,
    centroid: Annotated[float | None, typer.Option(help="Shadow centroid in [0, 255].")] = None,
    model: Annotated[Path | None, typer.Option(help="Model file from train-shadows.")] = None,
    seed: Annotated[int, typer.Option(help="Seed of shot sampling.")] = 0,
    as_json: JsonOpt = False,
) -> None:
    """Detect shadows; write a 0/255 mask per image at input size."""
    from qdcnn.experiments.shadow_batch import (
        MaskRecord,
        detect_files,
        median_seconds,
        plan_detection,
    )
    from qdcnn.quantum.execute import check_backend
    from qdcnn.vision.detectors import check_method
    from qdcnn.vision.shadows import ShadowModel

    try:
        check_method(method)
        check_backend(backend)
        cfg = ShadowConfig(shots=None if exact else shots)
        if threshold is not None:
            cfg = replace(cfg, threshold=threshold)
        if centroid is not None:
            cfg = replace(cfg, centroid=centroid)
        trained = ShadowModel.load(model) if model else None
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    plan = plan_detection(paths)
    failures = list(plan.failures)
    for f in failures:
        report_error(f.error)
        if as_json:
            emit(f.to_dict())
    records: list[MaskRecord] = []
    results = detect_files(
        plan.images, method, out_dir, cfg, model=trained, backend=backend, seed=seed
    )
    table = Table("file", "shadow %", "ms", title=f"shadow detection: {method}")
    for item in progress(results, len(plan.images), f"detect-shadows {method}"):
        if isinstance(item, MaskRecord):
            records.append(item)
            if as_json:
                emit(item.to_dict())
            else:
                table.add_row(
                    Path(item.file).name,
                    f"{100 * item.shadow_fraction:.1f}",
                    f"{1e3 * item.seconds:.2f}",
                )
        else:
            failures.append(item)
            report_error(item.error)
            if as_json:
                emit(item.to_dict())
    med = median_seconds(records)
    summary = {
        "summary": True,
        "method": method,
        "n_images": len(records),
        "n_failed": len(failures),
        "failures": [f.to_dict() for f in failures],
        "skipped": [str(p) for p in plan.skipped],
        "median_seconds": med,
        "shots": cfg.shots if method in ("uu", "uu-chroma") else None,
        "out": str(out_dir),
    }
    if as_json:
        emit(summary)
    else:
        out.print(table)
        out.print(
            f"{len(records)} masks in {out_dir}, {len(failures)} failed, "
            f"{len(plan.skipped)} skipped"
            + (f"; median {1e3 * med:.2f} ms per image (measured)" if med is not None else "")
        )
    raise typer.Exit(1 if failures or not records else 0)


@app.command("score-shadows")
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
        raise fail_on_error(exc) from None
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


@bench_app.command("shadows")
def bench_shadows_cmd(
    frames: Annotated[int, typer.Option(help="Synthetic track2 frames per size.")] = 5,
    repeats: Annotated[int, typer.Option(help="Timed passes; the median is reported.")] = 5,
    aer_blocks: Annotated[
        int, typer.Option(help="Blocks timed one by one on Aer (0: skip).")
    ] = 200,
    lbp: Annotated[bool, typer.Option(help="Include the (slow) LBP baseline.")] = True,
    as_json: JsonOpt = False,
) -> None:
    """Per-frame time of UU-dagger (exact, 1024 shots), per-block Aer, IBT, CBS and LBP."""
    from qdcnn.experiments.shadow_bench import bench_shadows

    try:
        result = bench_shadows(
            frames=frames,
            repeats=repeats,
            aer_blocks=aer_blocks,
            include_lbp=lbp,
            progress=lambda msg: err.print(f"[dim]timing {msg}[/dim]") if not as_json else None,
        )
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    if as_json:
        emit(result)
        return
    for row in result["results"]:
        table = Table(
            "detector",
            "ms / frame (measured)",
            "x IBT",
            title=f"{row['size']}, {row['blocks']} blocks",
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
        out.print(table)
        if "ratio_aer_per_block_to_uu_shots" in row:
            out.print(
                "per-block Aer / UU-dagger 1024 shots: "
                f"{row['ratio_aer_per_block_to_uu_shots']:,.0f}x"
            )
    est = Table(
        "profile",
        "seconds (estimate)",
        "source",
        title="hardware-time model (estimates, not measured)",
    )
    for e in result["hardware_estimates"]:
        est.add_row(e["profile"], f"{e['seconds']:.6g}", e["source"])
    out.print(est)


def main() -> None:
    """Entry point of the ``qdcnn`` script."""
    try:
        app()
    except QdcnnError as exc:
        report_error(" ".join(str(exc).split()))
        sys.exit(2)
