"""``reproduce`` and ``demo``: the paper's tables and figures, measured, as one HTML report.

The reproduce runner is imported when a command runs, so ``qdcnn --help`` loads none of it.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer
from rich.table import Table

from qdcnn.cli._common import (
    CacheOpt,
    CliReporter,
    EpochsOpt,
    JsonOpt,
    QuietOpt,
    SeedOpt,
    ThreadsOpt,
    emit,
    err,
    fail,
    out,
)
from qdcnn.errors import QdcnnError
from qdcnn.runtime.reporting import StageReporter

if TYPE_CHECKING:
    from qdcnn.experiments.reproduce import ReproduceResult, ReproduceSpec

OutOpt = Annotated[Path, typer.Option("--out", help="Folder of index.html, report.json, figures.")]
ForceOpt = Annotated[bool, typer.Option(help="Overwrite an existing report folder.")]
ResumeOpt = Annotated[
    bool, typer.Option("--resume", help="Continue a run in --out, keeping finished sections.")
]


class _StageLines(CliReporter, StageReporter):
    """CLI reporter that also prints one line on stderr as each section begins (not quiet)."""

    def stage(self, index: int, total: int, title: str) -> None:
        if not self.quiet:
            err.print(f"[{index}/{total}] {title}", style="dim", markup=False, highlight=False)

    def result(self, item: Mapping[str, Any]) -> None:
        super().result(item)
        if not self.as_json and "method" in item:
            line = (
                f"  {item['dataset']} {item['mode']} pipeline, {item['method']}: "
                f"{item['accuracy']:.3f} ({item['seconds']:.0f} s)"
            )
            err.print(line, style="dim", markup=False, highlight=False)


def _finish(spec: ReproduceSpec, as_json: bool, quiet: bool) -> None:
    from qdcnn.experiments.reproduce import run_reproduce

    try:
        result = run_reproduce(spec, _StageLines(as_json, quiet=quiet))
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json:
        emit({"summary": True, **result.to_dict()})
    else:
        out.print(_summary(result))
        out.print(f"report: {result.html} (numbers in {result.json})")
    raise typer.Exit(result.exit_code)


def _summary(result: ReproduceResult) -> Table:
    table = Table("section", "status", "seconds (measured)", title=f"{result.out}")
    for s in result.sections:
        reused = " (reused)" if s.id in result.reused else ""
        table.add_row(s.title, s.status + reused, f"{s.seconds:.1f}")
    return table


DataOpt = Annotated[
    list[str] | None,
    typer.Option(
        "--data",
        help="LABEL=SPEC, LABEL one of track1, track2, carla (repeatable; a label may come "
        "twice), e.g. track1=udacity:PATH. None: the synthetic presets.",
    ),
]
QuickOpt = Annotated[bool, typer.Option(help="The quick profile (a few minutes).")]
CnnOpt = Annotated[
    bool | None,
    typer.Option("--cnn/--no-cnn", help="Train the CNNs (default: with torch, not quick)."),
]
CnnMethodsOpt = Annotated[
    str,
    typer.Option(
        help="Frame methods: paper (PilotNet; ResNet-50 with a GPU), all (also the hybrids "
        "and their twins), or a comma list."
    ),
]
ShadowSetOpt = Annotated[Path | None, typer.Option(help="Shadow set DIR with images/ and masks/.")]
MaxFramesOpt = Annotated[
    int | None, typer.Option(help="At most this many frames from each recording's start.")
]
SyntheticOpt = Annotated[int | None, typer.Option(help="Frames of each synthetic drive.")]


def reproduce_cmd(
    out_dir: OutOpt = Path("reproduce-output"),
    data: DataOpt = None,
    quick: QuickOpt = False,
    cnn: CnnOpt = None,
    cnn_methods: CnnMethodsOpt = "paper",
    epochs: EpochsOpt = 25,
    threads: ThreadsOpt = None,
    shadow_set: ShadowSetOpt = None,
    max_frames: MaxFramesOpt = None,
    synthetic_frames: SyntheticOpt = None,
    force: ForceOpt = False,
    resume: ResumeOpt = False,
    seed: SeedOpt = 0,
    cache: CacheOpt = True,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Every table and figure of the paper next to the same thing measured on your data."""
    from qdcnn.experiments.reproduce import ReproduceSpec, parse_data_option

    try:
        spec = ReproduceSpec(
            out_dir,
            [parse_data_option(d) for d in data or []],
            quick=quick,
            force=force,
            resume=resume,
            seed=seed,
            cnn=cnn,
            cnn_methods=cnn_methods,
            epochs=epochs,
            threads=threads,
            shadow_set=shadow_set,
            max_frames=max_frames,
            synthetic_frames=synthetic_frames,
            use_cache=cache,
        )
        spec.check_paths()
    except QdcnnError as exc:
        raise fail(exc) from None
    _finish(spec, as_json, quiet)


def demo_cmd(
    out_dir: OutOpt = Path("demo-output"),
    quick: Annotated[
        bool, typer.Option(help="The quick profile (default); --no-quick: the full one.")
    ] = True,
    seed: SeedOpt = 0,
    force: ForceOpt = False,
    resume: ResumeOpt = False,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """`reproduce --quick` on the built-in synthetic presets: the whole paper in minutes."""
    from qdcnn.experiments.reproduce import ReproduceSpec

    try:
        spec = ReproduceSpec(out_dir, quick=quick, force=force, resume=resume, seed=seed)
    except QdcnnError as exc:
        raise fail(exc) from None
    _finish(spec, as_json, quiet)
