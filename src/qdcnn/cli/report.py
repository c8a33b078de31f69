"""``demo``: every stage on built-in synthetic scenes, as an HTML report."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from qdcnn.cli._common import JsonOpt, emit, err, fail, out
from qdcnn.errors import QdcnnError
from qdcnn.experiments.report import run_demo


def demo_cmd(
    out_dir: Annotated[
        Path, typer.Option("--out", help="Folder for index.html and figures.")
    ] = Path("demo-output"),
    quick: Annotated[bool, typer.Option(help="Fewer scenes and repeats.")] = False,
    seed: Annotated[int, typer.Option(help="Seed.")] = 0,
    as_json: JsonOpt = False,
) -> None:
    """Run every stage on built-in synthetic scenes and write an HTML report."""
    try:
        result = run_demo(
            out_dir, quick=quick, seed=seed, say=lambda m: err.print(m, style="dim", markup=False)
        )
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json:
        emit(result)
    else:
        out.print(f"report: {result['html']} (numbers in {result['json']})")
