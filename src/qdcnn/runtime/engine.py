"""The core of ``qdcnn run``: per-frame decisions and an annotated video, resumable after any crash.

:func:`run_inputs` takes inputs (video files, image folders, or frame-source objects such
as :class:`qdcnn.data.frames.FrameSet`) and a per-frame processor, and writes per
input ``DIR/<name>/frames.csv``, ``DIR/<name>/timings.csv``, optionally
``DIR/<name>/overlay.mp4``, and ``DIR/summary.json``.

Chunks. Each input is cut into chunks of ``chunk_frames`` frames (512 by default), the unit
of resuming and of distribution (:class:`qdcnn.runtime.scheduler.Executor`). A chunk's
rows, timings and overlay segment are written atomically into ``DIR/<name>/.chunks/`` and
then recorded in the folder's manifest (:mod:`qdcnn.outputs`); when all chunks are there,
the final files are assembled (rows concatenated, the overlay segments remuxed into one
mp4 without re-encoding, each segment starting with a keyframe), recorded, and the chunk
files removed. A run killed at any point (``kill -9`` included) and run again with the same
arguments redoes only the chunks not recorded, and its ``frames.csv`` is byte-identical to
an uninterrupted run's: every value in it is deterministic (randomness is seeded per frame
index, never per chunk), and the one value that is not, processing time, is written to
``timings.csv`` instead.

``frames.csv`` columns (csv module, rows in frame order): ``frame``, ``timestamp`` (seconds,
empty for image folders), ``direction`` (the decision; with ``smooth=K`` the majority vote
over the frame and the K - 1 frames before it), ``direction_raw`` (the frame's own decision
before the vote; always present, equal to ``direction`` without smoothing),
``p_<class>`` per class when the processor gives probabilities, ``shadow_fraction``,
``lane_status`` (or ``error`` for a frame that could not be decoded or processed).
``timings.csv``: ``frame``, ``process_ms`` (for a processor that works in batches, the
frame's share of its batch of :data:`BATCH_FRAMES`) and ``overlay_ms`` (drawing and
encoding), **measured**, different on every run.

The processor is injected (:class:`FrameProcessor`);
:class:`qdcnn.direction.processor.LaneDirectionProcessor` is today's pipeline
(UU-dagger shadow detection and removal, lanes, a fitted direction model).
"""

from __future__ import annotations

import csv
import hashlib
import io
import os
import time
from collections import Counter
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn import __version__
from qdcnn.data.images import list_images, read_image
from qdcnn.data.video import (
    MAX_VIDEO_PIXELS,
    VideoIndex,
    VideoReader,
    VideoWriter,
    check_decoder,
    check_encoder,
    concat_mp4,
    default_encoder,
    is_video_file,
)
from qdcnn.errors import InputError, ParameterError, QdcnnError
from qdcnn.outputs import OutputFolder, config_hash, file_identity
from qdcnn.runtime.scheduler import Executor, TaskFailure

CHUNK_FRAMES = 512
FRAMES_CSV, TIMINGS_CSV, OVERLAY, SUMMARY = (
    "frames.csv",
    "timings.csv",
    "overlay.mp4",
    "summary.json",
)
CHUNK_DIR = ".chunks"
#: Frames handed to a processor's ``process_batch`` at once.
BATCH_FRAMES = 32
FORMAT_VERSION = 1
#: Frame rate of overlays of inputs without one (image folders, frame sources).
DEFAULT_OVERLAY_FPS = 10.0


# ---------------------------------------------------------------------------- processors


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
        ``"ok"``, ``"one-line"``, ``"no-lines"`` (lane stage) or another short word.
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


# ---------------------------------------------------------------------------- inputs


@dataclass(frozen=True)
class VideoInput:
    """A video file."""

    name: str
    path: Path

    kind = "video"

    def describe(self) -> str:
        return str(self.path)


@dataclass(frozen=True)
class FolderInput:
    """A folder of images, in name order."""

    name: str
    path: Path
    files: tuple[Path, ...]

    kind = "images"

    def describe(self) -> str:
        return str(self.path)


@dataclass(frozen=True)
class SourceInput:
    """A frame-source object (``__len__``, ``image(i)``, ``timestamps``), by its name; the
    object itself travels to workers once, beside the tasks."""

    name: str
    spec: str

    kind = "source"

    def describe(self) -> str:
        return self.spec


Input = VideoInput | FolderInput | SourceInput


def resolve_inputs(items: Sequence[Any]) -> tuple[list[Input], dict[str, Any]]:
    """Inputs from paths and frame-source objects, with unique deterministic names.

    Returns the inputs and the frame-source objects by name. A name is the file's stem,
    the folder's name or the object's ``name`` attribute; a repeated name gets ``-2``,
    ``-3``, ... in input order.

    Raises
    ------
    InputError
        A path that does not exist, a file that is not a video, a folder without images.
    """
    out: list[Input] = []
    sources: dict[str, Any] = {}
    used: set[str] = {SUMMARY}  # an input folder must not take the summary's name

    def unique(name: str) -> str:
        base = _safe_name(name)
        candidate, k = base, 2
        while candidate in used:
            candidate, k = f"{base}-{k}", k + 1
        used.add(candidate)
        return candidate

    for item in items:
        if isinstance(item, str | os.PathLike):
            path = Path(item)
            if path.is_dir():
                files = tuple(list_images([path]).images)
                if not files:
                    raise InputError(path, "no image files in this folder")
                out.append(FolderInput(unique(path.resolve().name), path, files))
            elif not path.exists():
                raise InputError(path, "file not found")
            elif is_video_file(path):
                out.append(VideoInput(unique(path.stem), path))
            else:
                raise InputError(path, f"not a video file or folder (suffix {path.suffix!r})")
        elif hasattr(item, "image") and hasattr(item, "__len__"):
            name = unique(str(getattr(item, "name", "frames")))
            sources[name] = item
            out.append(SourceInput(name, str(getattr(item, "spec", name))))
        else:
            raise ParameterError(
                "inputs", type(item).__name__, "paths or objects with __len__ and image(i)"
            )
    return out, sources


def _safe_name(name: str) -> str:
    cleaned = "".join(c if c.isalnum() or c in "-_." else "_" for c in name).strip(".")
    return cleaned or "input"


# ---------------------------------------------------------------------------- chunks


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


@dataclass(frozen=True)
class _Frame:
    index: int
    timestamp: float | None
    image: NDArray[np.uint8] | None
    error: str | None = None


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
            yield _Frame(index, stamp, None, " ".join(str(exc).split()))
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
    return "" if value is None else f"{value:.{digits}f}"


def csv_header(processor: FrameProcessor, smooth: int) -> list[str]:
    """Columns of ``frames.csv`` for this processor: the same with and without smoothing
    (``direction_raw`` equals ``direction`` when ``smooth`` is 1)."""
    cols = ["frame", "timestamp", "direction", "direction_raw"]
    cols += [f"p_{c}" for c in processor.classes or ()]
    return [*cols, "shadow_fraction", "lane_status"]


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
            self.rows.writerow(_row(item, outcome, decision, self.task.smooth, self.n_classes))
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
    item: _Frame, outcome: FrameOutcome | None, decision: str | None, smooth: int, n_classes: int
) -> list[Any]:
    row: list[Any] = [item.index, _fmt(item.timestamp), decision or ""]
    row.append("" if outcome is None else outcome.direction or "")
    probs = outcome.probabilities if outcome is not None else None
    row += [_fmt(p) for p in probs] if probs is not None else [""] * n_classes
    if outcome is None:
        return [*row, "", "error"]
    return [*row, _fmt(outcome.shadow_fraction), outcome.lane_status]


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


# ---------------------------------------------------------------------------- results


@dataclass(frozen=True)
class Progress:
    """Frames finished of one input (per frame in this process, per chunk on Dask)."""

    input: str
    done: int
    total: int


@dataclass
class InputResult:
    """What a run did with one input.

    ``frames`` counts the rows of ``frames.csv``; ``frames_processed`` the frames worked
    on in this run (chunks found finished are not); ``seconds`` is the compute time of
    this run's chunks of the input (measured) and ``frames_per_second`` their ratio.
    """

    name: str
    source: str
    kind: str
    frames: int = 0
    frames_processed: int = 0
    seconds: float = 0.0
    chunks: int = 0
    chunks_skipped: int = 0
    decoder: str | None = None
    outputs: dict[str, str] = field(default_factory=dict)
    directions: dict[str, int] = field(default_factory=dict)
    bad_frames: list[tuple[int, str]] = field(default_factory=list)
    error: str | None = None
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def frames_per_second(self) -> float | None:
        return self.frames_processed / self.seconds if self.seconds > 0 else None

    @property
    def first_bad_frame(self) -> int | None:
        return min((b[0] for b in self.bad_frames), default=None)

    @property
    def ok(self) -> bool:
        return self.error is None and not self.bad_frames

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "input": self.source,
            "kind": self.kind,
            "frames": self.frames,
            "frames_processed": self.frames_processed,
            "seconds": self.seconds,
            "frames_per_second": self.frames_per_second,
            "chunks": self.chunks,
            "chunks_skipped": self.chunks_skipped,
            "decoder": self.decoder,
            "outputs": self.outputs,
            "directions": self.directions,
            "first_bad_frame": self.first_bad_frame,
            "bad_frames": len(self.bad_frames),
            "bad_frame_examples": [{"frame": i, "reason": r} for i, r in self.bad_frames[:20]],
            "error": self.error,
            "ok": self.ok,
            "video": self.info,
        }


@dataclass
class RunResult:
    """A whole run: its inputs, wall time and where tasks ran."""

    out: str
    inputs: list[InputResult]
    seconds: float
    executor: dict[str, Any]

    @property
    def frames(self) -> int:
        return sum(r.frames for r in self.inputs)

    @property
    def frames_processed(self) -> int:
        return sum(r.frames_processed for r in self.inputs)

    @property
    def frames_per_second(self) -> float | None:
        return self.frames_processed / self.seconds if self.seconds > 0 else None

    @property
    def ok(self) -> bool:
        return all(r.ok for r in self.inputs)

    def to_dict(self) -> dict[str, Any]:
        return {
            "summary": True,
            "out": self.out,
            "frames": self.frames,
            "frames_processed": self.frames_processed,
            "seconds": self.seconds,
            "frames_per_second": self.frames_per_second,
            "n_inputs": len(self.inputs),
            "n_failed": sum(not r.ok for r in self.inputs),
            "ok": self.ok,
            "executor": self.executor,
            "timing": "measured",
            "inputs": [r.to_dict() for r in self.inputs],
        }


@dataclass(frozen=True)
class RunOptions:
    """Settings of :func:`run_inputs` besides the processor.

    Attributes
    ----------
    chunk_frames : int
        Frames per chunk (the unit of resuming and distribution).
    smooth : int
        Majority vote of the decision over this many frames (1: none).
    overlay : bool
        Write ``overlay.mp4``.
    force : bool
        Redo every chunk and input, finished or not.
    decoder : {"auto", "pyav", "opencv"}
        Video decoder.
    max_pixels : int
        Largest frame decoded.
    wait : float
        Seconds to wait for another run's lock on the output folder.
    overlay_fps : float or None
        Frame rate of overlays of inputs without timestamps (image folders, sources).
    encoder : str
        Overlay encoder (``"auto"``: libx264, else mpeg4, else OpenCV).
    """

    chunk_frames: int = CHUNK_FRAMES
    smooth: int = 1
    overlay: bool = True
    force: bool = False
    decoder: str = "auto"
    max_pixels: int = MAX_VIDEO_PIXELS
    wait: float = 0.0
    overlay_fps: float | None = None
    encoder: str = "auto"

    def __post_init__(self) -> None:
        from qdcnn._validation import check_bool, check_float, check_int

        check_int("chunk_frames", self.chunk_frames, 1, 1_000_000)
        check_float("wait", self.wait, 0.0, 86_400.0)
        if self.overlay_fps is not None:
            check_float("overlay_fps", self.overlay_fps, 0.0, 1000.0, open_lo=True)
        check_int("smooth", self.smooth, 1, 1001)
        check_bool("overlay", self.overlay)
        check_bool("force", self.force)
        check_decoder(self.decoder)
        check_encoder(self.encoder)


# ---------------------------------------------------------------------------- the run


@dataclass
class _Plan:
    """One input's work: identity, config hash, chunk tasks to run, and its result."""

    inp: Input
    result: InputResult
    identity: dict[str, Any]
    config: str
    header: list[str]
    n_frames: int
    chunks: list[ChunkTask]
    todo: list[ChunkTask]
    done_chunks: set[int] = field(default_factory=set)
    truncated_from: int | None = None
    finished: bool = False


def run_inputs(
    inputs: Sequence[Any],
    processor: FrameProcessor,
    out_dir: str | os.PathLike[str],
    *,
    options: RunOptions | None = None,
    executor: Executor | None = None,
    progress: Callable[[Progress], None] | None = None,
) -> RunResult:
    """Process every input; write ``DIR/<name>/frames.csv``, ``timings.csv``,
    ``overlay.mp4`` and ``DIR/summary.json`` (see the module docstring).

    Parameters
    ----------
    inputs : sequence
        Video file paths, image folder paths, or frame-source objects.
    processor : FrameProcessor
        The per-frame work.
    out_dir : path-like
        Output folder, locked for the run (:class:`qdcnn.outputs.OutputFolder`).
    options : RunOptions, optional
        Chunking, smoothing, overlay, force, decoder.
    executor : Executor, optional
        Where chunks run (default: this process).
    progress : callable, optional
        Called with a :class:`Progress` after each frame (in this process) or chunk (Dask).

    Returns
    -------
    RunResult
        Per input: frames, time, outputs, bad frames; a bad input never stops the others.

    Raises
    ------
    OutputLockedError
        Another run is writing to ``out_dir``.
    InputError
        ``out_dir`` cannot be written, or a path in ``inputs`` does not exist or is not a
        video or image folder.
    """
    opts = options or RunOptions()
    if not isinstance(processor, FrameProcessor):
        raise ParameterError("processor", type(processor).__name__, "a FrameProcessor")
    resolved, sources = resolve_inputs(inputs)
    own_executor = executor is None
    ex = executor or Executor()
    t0 = time.perf_counter()
    try:
        with OutputFolder(out_dir, wait=opts.wait) as folder:
            plans = [_plan(inp, processor, sources, folder, opts) for inp in resolved]
            _execute(plans, processor, sources, folder, ex, progress)
            result = RunResult(str(out_dir), [p.result for p in plans], 0.0, ex.describe())
            result.seconds = time.perf_counter() - t0
            result.executor["stats"] = ex.stats.to_dict()
            folder.write_text(SUMMARY, _json(result.to_dict()))
    finally:
        if own_executor:
            ex.close()
    return result


def _json(data: Mapping[str, Any]) -> str:
    import json

    return json.dumps(data, indent=1, allow_nan=False) + "\n"


def _config_of(processor: FrameProcessor, opts: RunOptions, header: list[str], decoder: str) -> str:
    return config_hash(
        {
            "format": FORMAT_VERSION,
            "qdcnn": __version__,
            "processor": processor.settings(),
            "chunk_frames": opts.chunk_frames,
            "smooth": opts.smooth,
            "overlay": opts.overlay,
            "overlay_fps": opts.overlay_fps,
            "encoder": default_encoder() if opts.encoder == "auto" else opts.encoder,
            "decoder": decoder,
            "header": header,
        }
    )


def _identity(inp: Input, sources: Mapping[str, Any]) -> dict[str, Any]:
    if isinstance(inp, VideoInput):
        return {"kind": "video", **file_identity(inp.path)}
    if isinstance(inp, FolderInput):
        h = hashlib.sha256()
        for f in inp.files:
            ident = file_identity(f)
            h.update(f"{f.name}:{ident['size']}:{ident['mtime_ns']}\n".encode())
        return {"kind": "images", "path": str(inp.path.resolve()), "files": h.hexdigest()}
    source = sources[inp.name]
    fingerprint = getattr(source, "fingerprint", None)
    # without a fingerprint a source cannot be recognised again: never skip its work
    mark = fingerprint() if callable(fingerprint) else f"unrecognisable:{time.time_ns()}"
    return {"kind": "source", "spec": inp.spec, "frames": len(source), "fingerprint": mark}


def _plan(
    inp: Input,
    processor: FrameProcessor,
    sources: dict[str, Any],
    folder: OutputFolder,
    opts: RunOptions,
) -> _Plan:
    result = InputResult(inp.name, inp.describe(), inp.kind)
    header = csv_header(processor, opts.smooth)
    decoder = check_decoder(opts.decoder) if isinstance(inp, VideoInput) else "images"
    plan = _Plan(inp, result, {}, "", header, 0, [], [])
    try:
        n, size, use_stamps, fps, truncated = _probe(inp, sources, opts, result)
        plan.identity = _identity(inp, sources)
    except QdcnnError as exc:
        result.error = " ".join(str(exc).split())
        plan.finished = True
        return plan
    result.decoder = decoder if isinstance(inp, VideoInput) else None
    if opts.overlay and size is not None and (size[0] % 2 or size[1] % 2):
        # 4:2:0 video needs even sizes: the overlay gets one replicated edge pixel more
        result.info["overlay_padded_to"] = [size[0] + size[0] % 2, size[1] + size[1] % 2]
    plan.n_frames, plan.truncated_from = n, truncated
    plan.config = _config_of(processor, opts, header, decoder)
    step = opts.chunk_frames
    for k, start in enumerate(range(0, n, step)):
        plan.chunks.append(
            ChunkTask(
                inp,
                k,
                start,
                min(start + step, n),
                opts.smooth,
                opts.overlay,
                size,
                fps,
                use_stamps,
                decoder,
                opts.max_pixels,
                opts.encoder,
            )
        )
    result.chunks = len(plan.chunks)
    if not opts.force and _final_is_complete(plan, folder):
        plan.finished = True
        _cleanup_chunks(plan, folder)
        return plan
    for task in plan.chunks:
        status = folder.manifest.status(
            _chunk_key(plan, task), _chunk_identity(plan, task), plan.config
        )
        if status == "complete" and not opts.force:
            plan.done_chunks.add(task.chunk)
            result.chunks_skipped += 1
        else:
            plan.todo.append(task)
    return plan


def _probe(
    inp: Input, sources: dict[str, Any], opts: RunOptions, result: InputResult
) -> tuple[int, tuple[int, int] | None, bool, float, int | None]:
    """Frames, overlay size, whether the overlay follows the input's timestamps, its frame
    rate, and where a truncated video's missing frames start."""
    if isinstance(inp, VideoInput):
        with VideoReader(inp.path, decoder=opts.decoder, max_pixels=opts.max_pixels) as reader:  # type: ignore[arg-type]
            info = reader.info
            sources[inp.name] = reader.index  # chunks reopen the file with it
        result.info = info.to_dict()
        fps = opts.overlay_fps or info.fps or DEFAULT_OVERLAY_FPS
        truncated = info.frames if info.truncated else None
        return info.frames, (info.width, info.height), True, fps, truncated
    fps = opts.overlay_fps or DEFAULT_OVERLAY_FPS
    if isinstance(inp, FolderInput):
        n = len(inp.files)
        first = _first_readable(lambda i: read_image(inp.files[i]), n)
    else:
        source = sources[inp.name]
        n = len(source)
        if n == 0:
            raise InputError(inp.spec, "no frames")
        first = _first_readable(lambda i: np.asarray(source.image(i)), n)
    size = None if first is None else (int(first.shape[1]), int(first.shape[0]))
    return n, size, False, fps, None


def _first_readable(read: Callable[[int], NDArray[np.uint8]], n: int) -> NDArray[np.uint8] | None:
    for i in range(min(n, 16)):
        try:
            return read(i)
        except QdcnnError:
            continue
    return None


def _chunk_key(plan: _Plan, task: ChunkTask) -> str:
    return f"{plan.inp.name}/chunk-{task.chunk:05d}"


def _final_key(plan: _Plan) -> str:
    return f"{plan.inp.name}/final"


def _chunk_identity(plan: _Plan, task: ChunkTask) -> dict[str, Any]:
    return {**plan.identity, "start": task.start, "stop": task.stop}


def _chunk_files(plan: _Plan, chunk: int) -> tuple[str, str, str]:
    base = f"{plan.inp.name}/{CHUNK_DIR}/{chunk:05d}"
    return f"{base}.rows.csv", f"{base}.timings.csv", f"{base}.mp4"


def _final_is_complete(plan: _Plan, folder: OutputFolder) -> bool:
    key = _final_key(plan)
    if folder.manifest.status(key, plan.identity, plan.config) != "complete":
        return False
    entry = folder.manifest.get(key)
    assert entry is not None
    _restore_result(plan.result, entry.result)
    return True


def _restore_result(result: InputResult, saved: Mapping[str, Any]) -> None:
    result.frames = int(saved.get("frames", 0))
    result.outputs = dict(saved.get("outputs", {}))
    result.directions = dict(saved.get("directions", {}))
    result.bad_frames = [(int(i), str(r)) for i, r in saved.get("bad_frames", [])]
    result.chunks_skipped = result.chunks


def _execute(
    plans: list[_Plan],
    processor: FrameProcessor,
    sources: Mapping[str, Any],
    folder: OutputFolder,
    ex: Executor,
    progress: Callable[[Progress], None] | None,
) -> None:
    by_name = {p.inp.name: p for p in plans}
    done: Counter[str] = Counter()
    for plan in plans:
        done[plan.inp.name] = (
            plan.n_frames
            if plan.finished
            else sum(t.stop - t.start for t in plan.chunks if t.chunk in plan.done_chunks)
        )
        if progress is not None:
            progress(Progress(plan.inp.name, done[plan.inp.name], plan.n_frames))
        if not plan.finished and not plan.todo:
            _assemble(plan, folder)

    def tick(name: str, frames: int) -> None:
        done[name] += frames
        if progress is not None:
            progress(Progress(name, done[name], by_name[name].n_frames))

    tasks = [t for p in plans if not p.finished for t in p.todo]
    shared: tuple[Any, ...] = (processor, sources, tick) if ex.in_process else (processor, sources)
    for task, outcome in ex.map_unordered(run_chunk, tasks, *shared):
        plan = by_name[task.input.name]
        if isinstance(outcome, TaskFailure):
            plan.result.error = plan.result.error or outcome.error
            continue
        if not ex.in_process:
            tick(plan.inp.name, task.stop - task.start)
        _store_chunk(plan, outcome, folder)
        if len(plan.done_chunks) == len(plan.chunks) and plan.result.error is None:
            _assemble(plan, folder)


def _store_chunk(plan: _Plan, chunk: ChunkResult, folder: OutputFolder) -> None:
    task = chunk.task
    rows, timings, video = _chunk_files(plan, task.chunk)
    outputs = {
        rows: folder.write_text(rows, chunk.rows),
        timings: folder.write_text(timings, chunk.timings),
    }
    if chunk.overlay is not None:
        outputs[video] = folder.write_bytes(video, chunk.overlay)
    summary = {
        "frames": chunk.frames,
        "bad_frames": chunk.bad_frames,
        "directions": chunk.directions,
        "overlay_start": chunk.overlay_start,
        "overlay": chunk.overlay is not None,
    }
    folder.manifest.record(
        _chunk_key(plan, task), _chunk_identity(plan, task), plan.config, outputs, summary
    )
    plan.done_chunks.add(task.chunk)
    plan.result.frames_processed += chunk.frames
    plan.result.seconds += chunk.seconds


def _assemble(plan: _Plan, folder: OutputFolder) -> None:
    """Join the chunks into the final files, record them, then drop the chunk files."""
    name = plan.inp.name
    header_buf = io.StringIO()
    csv.writer(header_buf, lineterminator="\n").writerow(plan.header)
    rows_parts, times_parts = [header_buf.getvalue()], ["frame,process_ms,overlay_ms\n"]
    segments: list[tuple[bytes, float]] = []
    directions: Counter[str] = Counter()
    bad: list[tuple[int, str]] = []
    for task in plan.chunks:
        entry = folder.manifest.get(_chunk_key(plan, task))
        rows, timings, video = _chunk_files(plan, task.chunk)
        parts = [folder.read_bytes(rows), folder.read_bytes(timings)]
        if entry is None or parts[0] is None or parts[1] is None:
            plan.result.error = f"{name}: chunk {task.chunk} vanished while assembling"
            return
        rows_parts.append(parts[0].decode("utf-8"))
        times_parts.append(parts[1].decode("utf-8"))
        directions.update(entry.result.get("directions", {}))
        bad += [(int(i), str(r)) for i, r in entry.result.get("bad_frames", [])]
        if entry.result.get("overlay"):
            data = folder.read_bytes(video)
            if data is not None:
                segments.append((data, float(entry.result["overlay_start"])))
    if plan.truncated_from is not None:
        declared = int(plan.result.info.get("declared_frames") or plan.truncated_from)
        bad.append((plan.truncated_from, f"truncated: the file declares {declared} frames"))
    outputs = {
        f"{name}/{FRAMES_CSV}": folder.write_text(f"{name}/{FRAMES_CSV}", "".join(rows_parts)),
        f"{name}/{TIMINGS_CSV}": folder.write_text(f"{name}/{TIMINGS_CSV}", "".join(times_parts)),
    }
    if segments:
        fps = plan.chunks[0].overlay_fps
        outputs[f"{name}/{OVERLAY}"] = folder.write_file(
            f"{name}/{OVERLAY}", lambda path: _join_segments(segments, path, fps)
        )
    result = plan.result
    result.frames = plan.n_frames
    result.directions = dict(directions)
    result.bad_frames = sorted(bad)
    result.outputs = {k.split("/", 1)[1]: str(folder.path(k)) for k in outputs}
    saved = {
        "frames": result.frames,
        "outputs": result.outputs,
        "directions": result.directions,
        "bad_frames": result.bad_frames,
    }
    folder.manifest.record(_final_key(plan), plan.identity, plan.config, outputs, saved)
    plan.finished = True
    _cleanup_chunks(plan, folder)


def _join_segments(segments: list[tuple[bytes, float]], path: Path, fps: float) -> None:
    from qdcnn._optional import has_module

    if has_module("av"):
        concat_mp4(segments, path, atomic=False)
        return
    # OpenCV only: decode the segments and encode them again into one file
    import tempfile

    writer = VideoWriter(path, fps, encoder="opencv")
    with tempfile.TemporaryDirectory() as tmp:
        for k, (data, _start) in enumerate(segments):
            seg = Path(tmp) / f"{k}.mp4"
            seg.write_bytes(data)
            with VideoReader(seg, decoder="opencv") as reader:
                for frame in reader:
                    writer.write(frame.image)
    writer.close()


def _cleanup_chunks(plan: _Plan, folder: OutputFolder) -> None:
    for task in plan.chunks:
        folder.manifest.forget(_chunk_key(plan, task))
        for rel in _chunk_files(plan, task.chunk):
            folder.remove(rel)
    folder.remove_folder(f"{plan.inp.name}/{CHUNK_DIR}")
