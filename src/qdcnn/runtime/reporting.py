"""How runners tell the outside world what happens while they work.

A runner (``run_evaluation``, ``detect_lanes``, ...) computes and returns a result
object; while it works it calls a :class:`Reporter`: :meth:`~Reporter.result` for each
finished item (so a command can print it at once and never lose it),
:meth:`~Reporter.failure` for each bad item, :meth:`~Reporter.note` for something left
out on purpose, and :meth:`~Reporter.progress` around long loops. The base class does
nothing, which is what Python callers get by default; the command line renders the
calls (JSON lines, one-line errors and progress bars on stderr).

:class:`ProgressLines` is the plain form of a progress bar, for a log that is not a
terminal: a line when the work starts, at most one every few seconds while it goes on
(also while a single long step never advances), and one with the total time at the end.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import Any

from qdcnn.batch import Failure

__all__ = [
    "Collector",
    "Failure",
    "ProgressLines",
    "Reporter",
    "StageReporter",
    "progress_interval",
]

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


#: Seconds between two plain progress lines (``$QDCNN_PROGRESS_INTERVAL`` overrides it).
PROGRESS_INTERVAL = 10.0


def progress_interval() -> float:
    """Seconds between plain progress lines: ``$QDCNN_PROGRESS_INTERVAL`` if a positive number."""
    try:
        seconds = float(os.environ.get("QDCNN_PROGRESS_INTERVAL", ""))
    except ValueError:
        return PROGRESS_INTERVAL
    return seconds if seconds > 0 and math.isfinite(seconds) else PROGRESS_INTERVAL


class ProgressLines:
    """Plain progress lines for a log that is not a terminal (a context manager).

    ``progress: <description>: <done>/<total>, <elapsed> s`` when the work starts; then at
    most one line every ``interval`` seconds: after a step once the last line is that old,
    and from a heartbeat thread while no step comes (one long model fit), so the log is
    never silent for longer; and a last line with the total time (``done in`` or, when the
    work raised, ``stopped after``).

    Parameters
    ----------
    total : int
        Steps of the work.
    description : str
        What is being done.
    write : callable
        Called with each line (without a newline); from the heartbeat thread too.
    interval : float
        Seconds between lines.
    clock : callable
        Seconds, monotonic (a fake one in tests).
    heartbeat : bool
        Start the heartbeat thread (tests of the step lines leave it off).
    """

    def __init__(
        self,
        total: int,
        description: str,
        write: Callable[[str], None],
        *,
        interval: float = PROGRESS_INTERVAL,
        clock: Callable[[], float] = time.monotonic,
        heartbeat: bool = True,
    ) -> None:
        self.total = total
        self.description = description
        self.interval = interval
        self.done = 0
        self._write = write
        self._clock = clock
        self._heartbeat = heartbeat
        self._start = self._last = clock()
        self._paused = False
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __enter__(self) -> ProgressLines:
        with self._lock:
            self._start = self._clock()
            self._say()
        if self._heartbeat:
            self._thread = threading.Thread(target=self._beat_until_stopped, daemon=True)
            self._thread.start()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *_: object) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        with self._lock:
            self._say("done in" if exc_type is None else "stopped after")

    def advance(self, *_: object) -> None:
        """One step done; a line when the last one is ``interval`` seconds old."""
        with self._lock:
            self.done += 1
            self._say_if_due()

    def beat(self) -> None:
        """The heartbeat: the last known state again when the last line is ``interval`` old."""
        with self._lock:
            if not self._paused:
                self._say_if_due()

    def pause(self) -> None:
        """Stop the heartbeat's lines (a nested piece of work prints its own)."""
        with self._lock:
            self._paused = True

    def resume(self) -> None:
        """Heartbeat lines again, the first ``interval`` seconds from now."""
        with self._lock:
            self._paused = False
            self._last = self._clock()

    def _beat_until_stopped(self) -> None:
        while not self._stop.wait(self._seconds_to_next_line()):
            self.beat()

    def _seconds_to_next_line(self) -> float:
        with self._lock:
            due = self._last + self.interval - self._clock()
        return max(due, self.interval / 100)

    def _say_if_due(self) -> None:
        if self._clock() - self._last >= self.interval:
            self._say()

    def _say(self, elapsed_label: str = "") -> None:
        now = self._clock()
        self._last = now
        elapsed = f"{elapsed_label} {now - self._start:.1f} s".lstrip()
        self._write(f"progress: {self.description}: {self.done}/{self.total}, {elapsed}")
