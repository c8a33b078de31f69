"""One chunk of one input, processed: its rows, timings and overlay segment, in memory.

A chunk (:class:`ChunkTask`) is frames ``start`` to ``stop - 1`` of an input, the unit of
resuming and of distribution. :func:`run_chunk` reads its frames, hands them to the
injected :class:`FrameProcessor` (up to :data:`BATCH_FRAMES` at a time when it has
``process_batch``), writes one ``frames.csv`` row and one ``timings.csv`` row per frame
and draws the overlay segment; with ``smooth=K`` the decision is the
:func:`majority_vote` over the frame and the K - 1 frames before it, and the K - 1
frames before the chunk are processed too, only for their votes, so decisions do not
depend on where chunks start. It writes no file: the client stores the result
(:mod:`qdcnn.runtime.assembly`).
"""

from __future__ import annotations

import csv
import io
import math
import time
from collections import Counter
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn.data.images import read_image
from qdcnn.data.recording import RowError
from qdcnn.data.video import VideoIndex, VideoReader, VideoWriter
from qdcnn.errors import QdcnnError
from qdcnn.runtime.inputs import FolderInput, Input, SourceInput, VideoInput

#: Frames handed to a processor's ``process_batch`` at once.
BATCH_FRAMES = 32


@dataclass
class FrameOutcome:
    """What a processor found in one frame.

    Attributes
    ----------
    direction : str or None
        The decision (``"left"``, ``"straight"``, ``"right"``), or None for no decision.
    probabilities : tuple of float or None
        One per class of the processor's ``classes``.
    shadow_fraction : float or None
        Fraction of the frame's pixels detected as shadow.
    lane_status : str
        ``"ok"``, ``"one-line"``, ``"no-lines"``, ``"crossed"``, ``"wrong-side"`` (lane
        stage, :func:`qdcnn.vision.grouping.pair_status`) or another short word.
    drawing : object
        Whatever the processor's ``draw`` needs (segments, lines, mask); never written out.
    """

    direction: str | None
    probabilities: tuple[float, ...] | None
    shadow_fraction: float | None
    lane_status: str
    drawing: Any = None


@runtime_checkable
class FrameProcessor(Protocol):
    """Per-frame work injected into :func:`run_inputs`.

    ``classes`` names the probability columns (``None``: no probabilities). ``settings``
    returns plain JSON of everything that changes the outputs (it goes into the config
    hash, so a changed model or setting redoes the work). ``process`` must be
    deterministic given the image and the frame index (seed any randomness from the
    index). ``draw`` returns the RGB overlay frame of the same size, captioned with
    ``decision`` (the smoothed decision when smoothing).

    A processor may also have ``process_batch(images, indices)`` returning one
    :class:`FrameOutcome` or :class:`~qdcnn.errors.QdcnnError` per frame; the runner then
    hands it up to :data:`BATCH_FRAMES` frames at a time (a classifier decides a batch in
    one call), with the same results as frame by frame.
    """

    classes: tuple[str, ...] | None

    def settings(self) -> dict[str, Any]: ...

    def process(self, image: NDArray[np.uint8], index: int) -> FrameOutcome: ...

    def draw(
        self, image: NDArray[np.uint8], outcome: FrameOutcome, decision: str | None
    ) -> NDArray[np.uint8]: ...


@dataclass(frozen=True)
class ChunkTask:
    """One chunk of one input: frames ``start`` to ``stop - 1`` (idempotent)."""

    input: Input
    chunk: int
    start: int
    stop: int
    smooth: int
    overlay: bool
    overlay_size: tuple[int, int] | None
    overlay_fps: float
    use_timestamps: bool
    decoder: str
    max_pixels: int
    encoder: str


@dataclass
class ChunkResult:
    """Rows, timings and overlay segment of one chunk (in memory, for the client to write)."""

    task: ChunkTask
    rows: str
    timings: str
    overlay: bytes | None
    overlay_start: float
    bad_frames: list[tuple[int, str]]
    directions: dict[str, int]
    frames: int
    seconds: float


#: ``status`` of a frame in ``frames.csv``: processed; a row of the recording's label file
#: that was skipped; a frame or file that could not be read or decoded; processing failed.
STATUSES = ("ok", "bad-row", "unreadable", "failed")


@dataclass(frozen=True)
class _Frame:
    index: int
    timestamp: float | None
    image: NDArray[np.uint8] | None
    error: str | None = None
    status: str = "unreadable"  # why ``image`` is None


def _iter_frames(task: ChunkTask, first: int, sources: Mapping[str, Any]) -> Iterator[_Frame]:
    """Frames ``first`` to ``task.stop - 1`` of the task's input, bad ones with a reason."""
    inp = task.input
    if isinstance(inp, VideoInput):
        index = sources.get(inp.name)  # the client's index: no pass over the whole file
        with VideoReader(
            inp.path,
            decoder=task.decoder,  # type: ignore[arg-type]
            max_pixels=task.max_pixels,
            index=index if isinstance(index, VideoIndex) else None,
        ) as reader:
            stop = min(task.stop, len(reader))
            frames = reader.read(first, stop)
            expected = first
            for frame in frames:
                for bad in frames.bad_frames:
                    if expected <= bad.index < frame.index:
                        yield _Frame(bad.index, None, None, bad.reason)
                expected = frame.index + 1
                yield _Frame(frame.index, frame.timestamp, frame.image)
            for bad in frames.bad_frames:
                if bad.index >= expected:
                    yield _Frame(bad.index, None, None, bad.reason)
            for index in range(stop, task.stop):
                yield _Frame(index, None, None, "truncated: no data")
        return
    source = sources[inp.name] if isinstance(inp, SourceInput) else None
    stamps = getattr(source, "timestamps", None) if source is not None else None
    for index in range(first, task.stop):
        stamp = float(stamps[index]) if stamps is not None else None
        try:
            if isinstance(inp, FolderInput):
                image = read_image(inp.files[index])
            else:
                image = np.asarray(source.image(index))  # type: ignore[union-attr]
        except QdcnnError as exc:
            status = "bad-row" if isinstance(exc, RowError) else "unreadable"
            yield _Frame(index, stamp, None, " ".join(str(exc).split()), status)
            continue
        yield _Frame(index, stamp, image)


def majority_vote(history: Sequence[str | None]) -> str | None:
    """The most frequent decision in ``history`` (None skipped); ties go to the one seen
    most recently.

    Examples
    --------
    >>> majority_vote(["left", "right", "right", None, "left"])
    'left'
    """
    counts = Counter(d for d in history if d is not None)
    if not counts:
        return None
    best = max(counts.values())
    return next(d for d in reversed(history) if d is not None and counts[d] == best)


def _fmt(value: float | None, digits: int = 6) -> str:
    return "" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def csv_header(processor: FrameProcessor) -> list[str]:
    """Columns of ``frames.csv`` for this processor, the same with and without smoothing
    (``direction_raw``, the frame's own decision, equals ``direction`` without a vote)."""
    cols = ["frame", "timestamp", "direction", "direction_raw"]
    cols += [f"p_{c}" for c in processor.classes or ()]
    return [*cols, "shadow_fraction", "lane_status", "status", "note"]


def run_chunk(
    task: ChunkTask,
    processor: FrameProcessor,
    sources: Mapping[str, Any],
    progress: Callable[[str, int], None] | None = None,
) -> ChunkResult:
    """Process one chunk: rows, timings and (optionally) its overlay segment, in memory.

    With ``smooth=K`` the ``K - 1`` frames before the chunk are processed too, only for
    their votes, so the decisions do not depend on where chunks start.
    """
    t_start = time.perf_counter()
    first = max(0, task.start - (task.smooth - 1))
    state = _ChunkState(task, processor, progress)
    batch: list[_Frame] = []
    try:
        for item in _iter_frames(task, first, sources):
            batch.append(item)
            if len(batch) >= BATCH_FRAMES:
                state.take(batch)
                batch = []
        state.take(batch)
        data = state.finish_overlay()
    except BaseException:
        state.abort()
        raise
    return ChunkResult(
        task,
        state.rows_buf.getvalue(),
        state.times_buf.getvalue(),
        data,
        state.overlay_start or 0.0,
        state.bad,
        dict(state.directions),
        task.stop - task.start,
        time.perf_counter() - t_start,
    )


class _ChunkState:
    """Rows, timings, votes and the overlay writer of a chunk being processed."""

    def __init__(
        self,
        task: ChunkTask,
        processor: FrameProcessor,
        progress: Callable[[str, int], None] | None,
    ) -> None:
        self.task, self.processor, self.progress = task, processor, progress
        self.rows_buf, self.times_buf = io.StringIO(), io.StringIO()
        self.rows = csv.writer(self.rows_buf, lineterminator="\n")
        self.times = csv.writer(self.times_buf, lineterminator="\n")
        self.history: list[str | None] = []
        self.bad: list[tuple[int, str]] = []
        self.directions: Counter[str] = Counter()
        self.writer = _overlay_writer(task)
        self.overlay_start: float | None = None
        self.last_stamp: float | None = None
        self.n_classes = len(processor.classes or ())

    def take(self, batch: list[_Frame]) -> None:
        """Process a batch of frames and write their rows and overlay frames in order."""
        if not batch:
            return
        for item, (outcome, ms, error) in zip(
            batch, _process_batch(self.processor, batch), strict=True
        ):
            self.history = [*self.history, None if outcome is None else outcome.direction]
            self.history = self.history[-self.task.smooth :]
            if item.index < self.task.start:
                continue  # a frame before the chunk: only its vote counts
            decision = majority_vote(self.history) if outcome is not None else None
            if error is not None:
                self.bad.append((item.index, error))
            self.rows.writerow(_row(item, outcome, decision, self.n_classes, error))
            if decision is not None:
                self.directions[decision] += 1
            overlay_ms = self._draw(item, outcome, decision)
            self.times.writerow([item.index, _fmt(ms, 3), _fmt(overlay_ms, 3)])
            if self.progress is not None:
                self.progress(self.task.input.name, 1)

    def _draw(self, item: _Frame, outcome: FrameOutcome | None, decision: str | None) -> float:
        if self.writer is None or outcome is None or item.image is None:
            return 0.0
        t0 = time.perf_counter()
        stamp = _overlay_time(self.task, item)
        if self.overlay_start is None:
            self.overlay_start = stamp
        if self.last_stamp is not None and stamp <= self.last_stamp:
            stamp = self.last_stamp + 0.001  # a repeated time stamp in the input
        self.last_stamp = stamp
        picture = _fit(self.processor.draw(item.image, outcome, decision), self.task.overlay_size)
        self.writer.write(picture, stamp - self.overlay_start)
        return 1e3 * (time.perf_counter() - t0)

    def finish_overlay(self) -> bytes | None:
        if self.writer is None:
            return None
        if self.overlay_start is None:  # no frame could be drawn
            self.writer.abort()
            return None
        self.writer.close()
        return self.writer.data

    def abort(self) -> None:
        if self.writer is not None:
            self.writer.abort()


def _process_batch(
    processor: FrameProcessor, batch: list[_Frame]
) -> list[tuple[FrameOutcome | None, float | None, str | None]]:
    """Outcome, processing ms and error per frame; batches when the processor can."""
    readable = [item for item in batch if item.image is not None]
    results: dict[int, tuple[FrameOutcome | None, float | None, str | None]] = {}
    batch_fn = getattr(processor, "process_batch", None)
    if batch_fn is not None and readable:
        t0 = time.perf_counter()
        outcomes = batch_fn([i.image for i in readable], [i.index for i in readable])
        ms = 1e3 * (time.perf_counter() - t0) / len(readable)
        for item, outcome in zip(readable, outcomes, strict=True):
            if isinstance(outcome, QdcnnError):
                results[item.index] = (None, None, " ".join(str(outcome).split()))
            else:
                results[item.index] = (outcome, ms, None)
    else:
        for item in readable:
            results[item.index] = _process_one(processor, item)
    return [results.get(item.index, (None, None, item.error or "not decoded")) for item in batch]


def _process_one(
    processor: FrameProcessor, item: _Frame
) -> tuple[FrameOutcome | None, float | None, str | None]:
    assert item.image is not None
    t0 = time.perf_counter()
    try:
        outcome = processor.process(item.image, item.index)
    except QdcnnError as exc:
        return None, None, " ".join(str(exc).split())
    return outcome, 1e3 * (time.perf_counter() - t0), None


def _row(
    item: _Frame,
    outcome: FrameOutcome | None,
    decision: str | None,
    n_classes: int,
    error: str | None,
) -> list[Any]:
    """One ``frames.csv`` row; a frame without an outcome gets its status and the reason."""
    raw = "" if outcome is None else outcome.direction or ""
    row: list[Any] = [item.index, _fmt(item.timestamp), decision or "", raw]
    probs = outcome.probabilities if outcome is not None else None
    row += [_fmt(p) for p in probs] if probs is not None else [""] * n_classes
    if outcome is None:
        status = item.status if item.image is None else "failed"
        return [*row, "", "error", status, error or ""]
    return [*row, _fmt(outcome.shadow_fraction), outcome.lane_status, "ok", ""]


def _overlay_writer(task: ChunkTask) -> VideoWriter | None:
    if not task.overlay:
        return None
    return VideoWriter(None, task.overlay_fps, encoder=task.encoder)  # type: ignore[arg-type]


def _overlay_time(task: ChunkTask, item: _Frame) -> float:
    if task.use_timestamps and item.timestamp is not None:
        return item.timestamp
    return item.index / task.overlay_fps


def _fit(image: NDArray[np.uint8], size: tuple[int, int] | None) -> NDArray[np.uint8]:
    """Frames of another size than the overlay's (image folders) are resized to it."""
    if size is None or image.shape[1::-1] == size:
        return image
    return np.asarray(cv2.resize(image, size, interpolation=cv2.INTER_AREA), dtype=np.uint8)
