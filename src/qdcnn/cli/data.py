"""``synth``: synthetic drives with exact ground truth."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from qdcnn.cli._common import JsonOpt, emit, fail, out
from qdcnn.data.synthetic_presets import PRESETS
from qdcnn.errors import QdcnnError


def synth_cmd(
    out_dir: Annotated[Path, typer.Option("--out", help="Output folder.")],
    preset: Annotated[str, typer.Option(help=" | ".join(PRESETS))] = "track1",
    n: Annotated[int, typer.Option("--n", help="Number of frames.")] = 100,
    seed: Annotated[int, typer.Option(help="Seed of the generator.")] = 0,
    width: Annotated[int, typer.Option(help="Frame width in pixels.")] = 320,
    height: Annotated[int, typer.Option(help="Frame height in pixels.")] = 160,
    layout: Annotated[str, typer.Option(help="udacity | shadows | carla | all")] = "all",
    video: Annotated[bool, typer.Option(help="Also write the drive as an mp4.")] = False,
    force: Annotated[
        bool, typer.Option("--force/--no-force", help="Replace what a non-empty --out holds.")
    ] = False,
    as_json: JsonOpt = False,
) -> None:
    """Render a synthetic drive with exact ground truth in the layouts real data use."""
    from qdcnn.experiments.synth import SynthSpec, run_synth

    try:
        result = run_synth(SynthSpec(out_dir, preset, n, seed, width, height, layout, video, force))
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json:
        emit(result.to_dict())
        return
    for lay, where in result.written.items():
        out.print(f"{lay}: {where}")
    out.print(
        f"{n} frames, directions {result.directions}, "
        f"mean shadow fraction {result.mean_shadow_fraction:.3f}"
    )
