"""The ``qdcnn`` command line: thin commands over the runners of :mod:`qdcnn.experiments`.

With ``--json`` stdout carries only JSON (one object per line); progress bars, notes
and one-line errors go to stderr. Exit status: 0 when everything worked, 1 when some
items failed (the others are still processed and reported), 2 for bad options or
unusable input.
"""

from __future__ import annotations

import sys

import typer

from qdcnn.cli._common import report_error
from qdcnn.cli.bench import bench_app
from qdcnn.cli.data import synth_cmd
from qdcnn.cli.direction import detect_lanes_cmd, evaluate_cmd, train_direction_cmd
from qdcnn.cli.noise import circuit_cmd, noise_sweep_cmd
from qdcnn.cli.report import demo_cmd
from qdcnn.cli.run import run_cmd
from qdcnn.cli.shadows import detect_shadows_cmd, score_shadows_cmd, train_shadows_cmd
from qdcnn.errors import QdcnnError

__all__ = ["app", "main"]

app = typer.Typer(
    name="qdcnn",
    help="QDCNN: UU-dagger shadow detection, quantum lane-direction classifiers, noise studies.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
app.add_typer(bench_app, name="bench")
app.command("detect-shadows")(detect_shadows_cmd)
app.command("score-shadows")(score_shadows_cmd)
app.command("train-shadows")(train_shadows_cmd)
app.command("synth")(synth_cmd)
app.command("evaluate")(evaluate_cmd)
app.command("train-direction")(train_direction_cmd)
app.command("detect-lanes")(detect_lanes_cmd)
app.command("noise-sweep")(noise_sweep_cmd)
app.command("circuit")(circuit_cmd)
app.command("run")(run_cmd)
app.command("demo")(demo_cmd)


def main() -> None:
    """Entry point of the ``qdcnn`` script."""
    try:
        app()
    except QdcnnError as exc:
        report_error(exc)
        sys.exit(2)
