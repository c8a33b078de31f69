"""Shared pieces of the command line: consoles, JSON output, error lines, progress bars.

stdout carries results (only JSON with ``--json``); stderr carries progress bars,
notes and one-line errors. Every printed message is escaped, so text in square
brackets (``pip install 'qdcnn[quantum]'``, a file named ``frame[left].png``) is shown
as written instead of being read as Rich markup.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape

from qdcnn.errors import QdcnnError
from qdcnn.runtime.reporting import Advance, Failure, Reporter

try:  # Typer 0.24+ carries its own copy of click and does not install click
    from typer import _click as click
except ImportError:  # pragma: no cover - older Typer depends on click itself
    import click  # type: ignore[no-redef]

#: What a bad command line raises (a bad option value, a missing or unknown option).
USAGE_ERRORS: tuple[type[Exception], ...] = (click.exceptions.UsageError,)
#: Ctrl-C at a prompt.
ABORTS: tuple[type[BaseException], ...] = tuple(
    {typer.Abort, getattr(click.exceptions, "Abort", typer.Abort)}
)
#: ``qdcnn`` with no arguments (Typer shows the help).
NO_ARGS: tuple[type[Exception], ...] = tuple(
    c for c in (getattr(click.exceptions, "NoArgsIsHelpError", None),) if c is not None
)

out = Console(highlight=False)
err = Console(stderr=True, highlight=False)

JsonOpt = Annotated[
    bool, typer.Option("--json", help="Print only JSON on stdout (one object per line).")
]
SeedOpt = Annotated[int, typer.Option(help="Seed of every random choice.")]
CacheOpt = Annotated[bool, typer.Option(help="Reuse cached lane features.")]
FoldsOpt = Annotated[int, typer.Option(help="Contiguous cross-validation folds.")]
GapOpt = Annotated[
    int, typer.Option(help="Frames left out of training on each side of a test block.")
]


def emit(obj: Mapping[str, Any]) -> None:
    """Print one JSON object on its own line and flush, so finished results are never lost."""
    sys.stdout.write(json.dumps(obj, default=_jsonable) + "\n")
    sys.stdout.flush()


def _jsonable(value: Any) -> Any:
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    if hasattr(value, "to_dict"):
        return value.to_dict()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def one_line(message: object) -> str:
    return " ".join(str(message).split())


def report_error(message: object) -> None:
    """One line on stderr: ``error: <message>``."""
    err.print(f"[red]error:[/red] {escape(one_line(message))}", soft_wrap=True)


def report_note(message: object) -> None:
    """One line on stderr about something left out on purpose (not a failure)."""
    err.print(f"[yellow]note:[/yellow] {escape(one_line(message))}", soft_wrap=True)


def fail(exc: QdcnnError) -> typer.Exit:
    """Report ``exc`` as one line; the exit (status 2) for the caller to raise."""
    report_error(exc)
    return typer.Exit(2)


class CliReporter(Reporter):
    """Renders a runner's events: JSON lines with ``--json``, stderr lines and bars otherwise.

    Parameters
    ----------
    as_json : bool
        Print each finished item and failure as a JSON line on stdout.
    on_result : callable, optional
        Without ``--json``, called with each finished item (to fill a table).
    """

    def __init__(self, as_json: bool, on_result: Any = None) -> None:
        self.as_json = as_json
        self.on_result = on_result

    def result(self, item: Mapping[str, Any]) -> None:
        if self.as_json:
            emit(item)
        elif self.on_result is not None:
            self.on_result(item)

    def failure(self, failure: Failure) -> None:
        report_error(failure.error)
        if self.as_json:
            emit(failure.to_dict())

    def note(self, message: str) -> None:
        report_note(message)

    @contextmanager
    def progress(self, total: int, description: str) -> Iterator[Advance]:
        from rich.progress import (  # only commands that run load the progress bar
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TaskProgressColumn,
            TextColumn,
            TimeRemainingColumn,
        )

        bar = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TaskProgressColumn(),
            TimeRemainingColumn(),
            console=err,
            transient=True,
            disable=not err.is_terminal,
        )
        task = bar.add_task(escape(description), total=total)
        with bar:
            yield lambda *_: bar.advance(task)
