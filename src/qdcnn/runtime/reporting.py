"""How runners tell the outside world what happens while they work.

A runner (``run_evaluation``, ``detect_lanes``, ...) computes and returns a result
object; while it works it calls a :class:`Reporter`: :meth:`~Reporter.result` for each
finished item (so a command can print it at once and never lose it),
:meth:`~Reporter.failure` for each bad item, :meth:`~Reporter.note` for something left
out on purpose, and :meth:`~Reporter.progress` around long loops. The base class does
nothing, which is what Python callers get by default; the command line renders the
calls (JSON lines, one-line errors and progress bars on stderr).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import Any

from qdcnn.batch import Failure

__all__ = ["Collector", "Failure", "Reporter", "StageReporter"]

Advance = Callable[..., None]


class Reporter:
    """Receives a runner's events; every method does nothing unless overridden."""

    def result(self, item: Mapping[str, Any]) -> None:
        """A finished item (one image, one method's score): plain JSON values."""

    def failure(self, failure: Failure) -> None:
        """An item that failed, with its one-line reason; the run goes on."""

    def note(self, message: str) -> None:
        """Something left out or chosen on purpose (not a failure)."""

    @contextmanager
    def progress(self, total: int, description: str) -> Iterator[Advance]:
        """Context around a loop of ``total`` steps; call the yielded function per step."""
        yield _nothing


class StageReporter(Reporter):
    """A reporter that is also told when each stage of a long run begins."""

    def stage(self, index: int, total: int, title: str) -> None:
        """Stage ``index`` (1-based) of ``total`` begins."""


def _nothing(*_: object) -> None:
    return None


class Collector(Reporter):
    """A reporter that keeps everything it is told (tests, notebooks)."""

    def __init__(self) -> None:
        self.results: list[Mapping[str, Any]] = []
        self.failures: list[Failure] = []
        self.notes: list[str] = []

    def result(self, item: Mapping[str, Any]) -> None:
        self.results.append(item)

    def failure(self, failure: Failure) -> None:
        self.failures.append(failure)

    def note(self, message: str) -> None:
        self.notes.append(message)
