"""Shared pieces of the command line: consoles, JSON output, error lines, progress bars.

stdout carries results (only JSON with ``--json``); stderr carries progress bars (plain
``progress:`` lines at least every 10 seconds when stderr is not a terminal), notes and
one-line errors; ``--quiet`` leaves out the progress and the notes. Every printed
message is escaped, so text in square brackets (``pip install 'qdcnn[quantum]'``, a file
named ``frame[left].png``) is shown as written instead of being read as Rich markup.
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
QuietOpt = Annotated[
    bool,
    typer.Option(
        "--quiet", "-q", help="No progress or notes on stderr (errors and results still print)."
    ),
]
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

    Progress is a bar on a terminal; otherwise (a log, a pipe) plain ``progress:`` lines,
    at least one every ``$QDCNN_PROGRESS_INTERVAL`` seconds (10), so long work is never
    silent. A piece of work inside another gets its own bar or lines; the outer one's
    heartbeat waits meanwhile.

    Parameters
    ----------
    as_json : bool
        Print each finished item and failure as a JSON line on stdout.
    on_result : callable, optional
        Without ``--json``, called with each finished item (to fill a table).
    quiet : bool
        No progress and no notes (``--quiet``); errors and results still print.
    """

    def __init__(self, as_json: bool, on_result: Any = None, *, quiet: bool = False) -> None:
        self.as_json = as_json
        self.on_result = on_result
        self.quiet = quiet
        self._open_lines: list[Any] = []  # the ProgressLines open, innermost last
        self._bar: Any = None

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
        if not self.quiet:
            report_note(message)

    @contextmanager
    def progress(self, total: int, description: str) -> Iterator[Advance]:
        if self.quiet:
            yield lambda *_: None
        elif err.is_terminal:
            with self._bar_task(total, description) as advance:
                yield advance
        else:
            with self._plain_lines(total, description) as lines:
                yield lines.advance

    @contextmanager
    def _plain_lines(self, total: int, description: str) -> Iterator[Any]:
        from qdcnn.runtime.reporting import ProgressLines, progress_interval

        outer = self._open_lines[-1] if self._open_lines else None
        if outer is not None:
            outer.pause()
        lines = ProgressLines(total, description, _plain_line, interval=progress_interval())
        self._open_lines.append(lines)
        try:
            with lines:
                yield lines
        finally:
            self._open_lines.pop()
            if outer is not None:
                outer.resume()

    @contextmanager
    def _bar_task(self, total: int, description: str) -> Iterator[Advance]:
        """A task on the open bar (Rich before 14 allows one live display), or on a new one."""
        if self._bar is None:
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
            )
            with bar:
                self._bar = bar
                try:
                    with self._bar_task(total, description) as advance:
                        yield advance
                finally:
                    self._bar = None
            return
        bar = self._bar
        task = bar.add_task(escape(description), total=total)
        try:
            yield lambda *_: bar.advance(task)
        finally:
            bar.remove_task(task)


def _plain_line(line: str) -> None:
    err.print(line, markup=False, highlight=False, soft_wrap=True)
