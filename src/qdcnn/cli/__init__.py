"""The ``qdcnn`` command line: thin commands over the runners of :mod:`qdcnn.experiments`.

With ``--json`` stdout carries only JSON (one object per line); progress bars, notes
and one-line errors go to stderr. Exit status: 0 when everything worked, 1 when some
items failed (the others are still processed and reported), 2 for bad options or
unusable input.
"""

from __future__ import annotations

import sys
from typing import Any

import typer
from typer.core import TyperGroup

from qdcnn.cli._common import ABORTS, NO_ARGS, USAGE_ERRORS, report_error, warnings_as_notes
from qdcnn.cli.bench import bench_app
from qdcnn.cli.data import synth_cmd
from qdcnn.cli.direction import detect_lanes_cmd, evaluate_cmd, train_direction_cmd
from qdcnn.cli.noise import circuit_cmd, noise_sweep_cmd
from qdcnn.cli.report import demo_cmd, reproduce_cmd
from qdcnn.cli.run import run_cmd
from qdcnn.cli.score import score_cmd
from qdcnn.cli.shadows import detect_shadows_cmd, score_shadows_cmd, train_shadows_cmd
from qdcnn.errors import QdcnnError

__all__ = ["app", "main"]


class OneLineErrors(TyperGroup):
    """The command group, with usage errors (a bad option value, a missing option) as one
    ``error:`` line on stderr and exit status 2, like every other error of qdcnn."""

    def main(  # type: ignore[override]
        self,
        args: Any = None,
        prog_name: str | None = None,
        complete_var: str | None = None,
        standalone_mode: bool = True,
        **extra: Any,
    ) -> Any:
        try:
            with warnings_as_notes():
                code = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except NO_ARGS as exc:  # ``qdcnn`` alone: the help
            context = getattr(exc, "ctx", None)
            typer.echo(context.get_help() if context is not None else str(exc))
            code = 0
        except USAGE_ERRORS as exc:
            report_error(getattr(exc, "format_message", exc.__str__)())
            code = int(getattr(exc, "exit_code", 2))
        except ABORTS:
            report_error("aborted")
            code = 1
        code = code if isinstance(code, int) else 0
        if standalone_mode:
            sys.exit(code)
        return code


app = typer.Typer(
    cls=OneLineErrors,
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
app.command("score")(score_cmd)
app.command("noise-sweep")(noise_sweep_cmd)
app.command("circuit")(circuit_cmd)
app.command("run")(run_cmd)
app.command("demo")(demo_cmd)
app.command("reproduce")(reproduce_cmd)


def main() -> None:
    """Entry point of the ``qdcnn`` script."""
    try:
        app()
    except QdcnnError as exc:
        report_error(exc)
        sys.exit(2)
