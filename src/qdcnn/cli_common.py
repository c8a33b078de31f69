"""Shared pieces of the command line: consoles, JSON output, error lines and progress bars.

stdout carries results (only JSON with ``--json``); stderr carries progress bars and
one-line errors.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

from qdcnn.errors import QdcnnError

T = TypeVar("T")

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


def report_note(message: str) -> None:
    """One line on stderr about something left out on purpose (not a failure)."""
    err.print(f"[yellow]note:[/yellow] {message}", soft_wrap=True, markup=True)


class ProgressBar:
    """A progress bar on stderr, shown only when stderr is a terminal.

    Use as a context manager and call :meth:`advance` per finished item, or
    iterate with :func:`progress`.
    """

    def __init__(self, total: int, description: str) -> None:
        self._bar = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeRemainingColumn(),
            console=err,
            transient=True,
            disable=not err.is_terminal,
        )
        self._task = self._bar.add_task(description, total=total)

    def __enter__(self) -> ProgressBar:
        self._bar.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._bar.stop()

    def advance(self, *_: object) -> None:
        self._bar.advance(self._task)


def progress(items: Iterable[T], total: int, description: str) -> Iterator[T]:
    """Iterate with a :class:`ProgressBar`."""
    with ProgressBar(total, description) as bar:
        for item in items:
            yield item
            bar.advance()


def fail_on_error(exc: QdcnnError) -> typer.Exit:
    report_error(" ".join(str(exc).split()))
    return typer.Exit(2)
