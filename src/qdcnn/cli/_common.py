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
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, TypeVar

import typer
from rich.console import Console
from rich.markup import escape

from qdcnn.errors import ParameterError, QdcnnError
from qdcnn.runtime.reporting import Advance, Failure, Reporter

if TYPE_CHECKING:
    from qdcnn.config import PipelineConfig

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
WaitOpt = Annotated[float, typer.Option(help="Seconds to wait for another run's lock.")]
BuiltinMethodOpt = Annotated[
    str | None,
    typer.Option(
        help="Lane method whose built-in lane model decides when no --model is given "
        "(default: the built-in QDCNN model with torch, image-split-uu without)."
    ),
]
InnerFoldsOpt = Annotated[
    int, typer.Option(help="Inner contiguous folds choosing hyperparameters (0: none).")
]
EpochsOpt = Annotated[int, typer.Option(help="CNN epochs (dnn-* methods; paper: 25).")]
ThreadsOpt = Annotated[
    int | None, typer.Option(help="torch CPU threads for dnn-* (default: the usable CPUs).")
]
SteeringUnitOpt = Annotated[
    str, typer.Option(help="Unit of the recorded steering: auto | norm ([-1, 1]) | rad | deg.")
]
LabelThresholdOpt = Annotated[
    float | None,
    typer.Option(help="Label threshold in the steering unit (default: the unit's own, 0.05 norm)."),
]

# The lane options: every command that runs the lane stage takes all of them, and
# LaneOptions.config turns them into the PipelineConfig.
LanesOpt = Annotated[
    str,
    typer.Option(
        help="Lane settings: udacity (1 smoothing pass) | paper (30, the paper's ROI) | dashcam"
        " | auto (ROI estimated per recording)."
    ),
]
FeaturesOpt = Annotated[
    str,
    typer.Option(
        help="Two classifier inputs: slopes (the paper) | far-offsets | road-centre"
        " | vanishing-points."
    ),
]
EdgesOpt = Annotated[
    str, typer.Option(help="What Canny sees: grey (the paper) | rgb (colour Canny).")
]
ShadowRemovalOpt = Annotated[
    bool, typer.Option(help="UU-dagger shadow removal before the lane stage (the paper: on).")
]
MarksOpt = Annotated[
    str, typer.Option(help="Lane-mark evidence before Canny: none (the paper) | lab | hls.")
]
SegmentAnglesOpt = Annotated[
    str | None, typer.Option(help="Keep Hough segments between MIN,MAX degrees from horizontal.")
]
InnerLinesOpt = Annotated[bool, typer.Option(help="Keep each side's innermost line.")]
TrackOpt = Annotated[str, typer.Option(help="Track lines across frames: none | ema | kalman.")]


@dataclass(frozen=True)
class LaneOptions:
    """The lane options of the command line (``--lanes`` to ``--track``); the defaults are
    the paper's pipeline with one smoothing pass (``PipelineConfig()``)."""

    lanes: str = "udacity"
    features: str = "slopes"
    edges: str = "grey"
    shadow_removal: bool = True
    marks: str = "none"
    segment_angles: str | None = None
    inner_lines: bool = False
    track: str = "none"

    def config(
        self, seed: int, steering_unit: str = "auto", label_threshold: float | None = None
    ) -> PipelineConfig:
        """The pipeline config of these options, the seed and the label options."""
        from qdcnn.config import PipelineConfig

        config = PipelineConfig.preset(self.lanes, seed=seed)
        config = config.with_labels(steering_unit=steering_unit, threshold=label_threshold)
        config = config.with_lane_evidence(
            marks=self.marks,
            segment_angles=self._angles(),
            inner_lines=self.inner_lines,
            track=self.track,
        )
        return config.with_lane_options(
            features=self.features, edges=self.edges, shadow_removal=self.shadow_removal
        )

    def _angles(self) -> tuple[float, float] | None:
        if self.segment_angles is None:
            return None
        try:
            lo, hi = (float(v) for v in self.segment_angles.split(","))
        except ValueError:
            raise ParameterError(
                "segment-angles", self.segment_angles, "MIN,MAX in degrees, e.g. 20,80"
            ) from None
        return lo, hi


T = TypeVar("T")


def deprecated_spelling(value: T, old_value: T | None, old: str, new: str) -> T:
    """``value``, or ``old_value`` when the option was given under its old name ``old``
    (a hidden alias of ``new``), with a one-line note on stderr that ``old`` is deprecated."""
    if old_value is None:
        return value
    report_note(f"{old} is deprecated; use {new}")
    return old_value


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


@contextmanager
def warnings_as_notes() -> Iterator[None]:
    """Show each Python warning as one ``note:`` line on stderr, without Python's source
    line: qdcnn's own (a :class:`~qdcnn.direction.feature_cache.FeatureCacheWarning`) as
    its message, another package's with its category name in front."""
    import warnings

    def show(message: Warning | str, category: type[Warning], *_: Any, **__: Any) -> None:
        own = category.__module__.split(".")[0] == "qdcnn"
        report_note(message if own else f"{category.__name__}: {message}")

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield


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
