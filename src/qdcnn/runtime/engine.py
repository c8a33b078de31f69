"""The core of ``qdcnn run``: per-frame decisions and an annotated video, resumable after any crash.

:func:`run_inputs` takes inputs (video files, image folders, or frame-source objects such
as :class:`qdcnn.data.frames.FrameSet`) and a per-frame processor, and writes per
input ``DIR/<name>/frames.csv``, ``DIR/<name>/timings.csv``, optionally
``DIR/<name>/overlay.mp4``, and ``DIR/summary.json`` (with the processor's settings: what
decided).

Chunks. Each input is cut into chunks of ``chunk_frames`` frames (512 by default), the unit
of resuming and of distribution (:class:`qdcnn.runtime.scheduler.Executor`). A chunk's
rows, timings and overlay segment are written atomically into ``DIR/<name>/.chunks/`` and
then recorded in the folder's manifest (:mod:`qdcnn.outputs`); when all chunks are there,
the final files are assembled (rows concatenated, the overlay segments remuxed into one
mp4 without re-encoding, each segment starting with a keyframe), recorded, and the chunk
files removed (:mod:`qdcnn.runtime.assembly`, :mod:`qdcnn.runtime.manifest`). A run
killed at any point (``kill -9`` included) and run again with the same arguments redoes
only the chunks not recorded, and its ``frames.csv`` is byte-identical to an
uninterrupted run's: every value in it is deterministic (randomness is seeded per frame
index, never per chunk), and the one value that is not, processing time, is written to
``timings.csv`` instead.

``frames.csv`` columns (csv module, rows in frame order): ``frame``, ``timestamp`` (seconds,
empty for image folders), ``direction`` (the decision; with ``smooth=K`` the majority vote
over the frame and the K - 1 frames before it), ``direction_raw`` (the frame's own decision
before the vote; always present, equal to ``direction`` without smoothing),
``p_<class>`` per class when the processor gives probabilities, ``shadow_fraction``,
``lane_status`` (or ``error`` for a frame that could not be decoded or processed),
``status`` (``ok``; ``bad-row``: a row of a recording's label file that was skipped, kept
as a frame so the frame numbers stay the recording's rows; ``unreadable``: a frame or
image file that could not be read or decoded; ``failed``: processing failed) and ``note``
(why, naming the file or row; empty for ``ok``). Frame numbers are never renumbered: a
video's frame index, a file's place in the sorted image folder, a recording's data row.
``timings.csv``: ``frame``, ``process_ms`` (for a processor that works in batches, the
frame's share of its batch of :data:`BATCH_FRAMES`) and ``overlay_ms`` (drawing and
encoding), **measured**, different on every run.

The processor is injected (:class:`~qdcnn.runtime.chunks.FrameProcessor`; a chunk's
work is :func:`qdcnn.runtime.chunks.run_chunk`, its inputs :mod:`qdcnn.runtime.inputs`);
:class:`qdcnn.direction.processor.LaneDirectionProcessor` is today's pipeline
(UU-dagger shadow detection and removal, lanes, a fitted direction model).
"""

from __future__ import annotations

import os
import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from qdcnn import __version__
from qdcnn.data.video import MAX_VIDEO_PIXELS, check_decoder, check_encoder, default_encoder
from qdcnn.errors import ParameterError, QdcnnError
from qdcnn.outputs import OutputFolder, config_hash, refuse_output_in_inputs
from qdcnn.runtime.assembly import (
    ChunkVanishedError,
    assemble,
    final_outputs,
    remove_chunks,
    store_chunk,
)
from qdcnn.runtime.chunks import ChunkResult, ChunkTask, FrameProcessor, csv_header, run_chunk
from qdcnn.runtime.inputs import (
    FolderInput,
    Input,
    Probe,
    VideoInput,
    input_identity,
    probe_input,
    resolve_inputs,
)
from qdcnn.runtime.manifest import SUMMARY, InputLedger
from qdcnn.runtime.scheduler import Executor, TaskFailure

_CHUNK_FRAMES = 512
FORMAT_VERSION = 1


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
    #: the processor's settings (what decided: model, method, seed): its ``settings()``
    processor: dict[str, Any] = field(default_factory=dict)

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
            "processor": self.processor,
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

    chunk_frames: int = _CHUNK_FRAMES
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
    """One input's work: its manifest records, chunk tasks to run, and its result."""

    inp: Input
    result: InputResult
    ledger: InputLedger
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
    refuse_output_in_inputs(out_dir, [i.path for i in resolved if isinstance(i, FolderInput)])
    own_executor = executor is None
    ex = executor or Executor()
    t0 = time.perf_counter()
    try:
        with OutputFolder(out_dir, wait=opts.wait) as folder:
            settings = processor.settings()  # in every input's config hash and the summary
            plans = [_plan(inp, processor, settings, sources, folder, opts) for inp in resolved]
            _execute(plans, processor, sources, folder, ex, progress)
            result = RunResult(
                str(out_dir), [p.result for p in plans], 0.0, ex.describe(), settings
            )
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


def _config_of(settings: dict[str, Any], opts: RunOptions, header: list[str], decoder: str) -> str:
    return config_hash(
        {
            "format": FORMAT_VERSION,
            "qdcnn": __version__,
            "processor": settings,
            "chunk_frames": opts.chunk_frames,
            "smooth": opts.smooth,
            "overlay": opts.overlay,
            "overlay_fps": opts.overlay_fps,
            "encoder": default_encoder() if opts.encoder == "auto" else opts.encoder,
            "decoder": decoder,
            "header": header,
        }
    )


def _plan(
    inp: Input,
    processor: FrameProcessor,
    settings: dict[str, Any],
    sources: dict[str, Any],
    folder: OutputFolder,
    opts: RunOptions,
) -> _Plan:
    """The chunks of ``inp`` and which of them are still to do (none when it is finished)."""
    result = InputResult(inp.name, inp.describe(), inp.kind)
    header = csv_header(processor)
    decoder = check_decoder(opts.decoder) if isinstance(inp, VideoInput) else "images"
    plan = _Plan(inp, result, InputLedger(inp.name, {}, ""), header, 0, [], [])
    try:
        probe = probe_input(
            inp,
            sources,
            decoder=opts.decoder,
            max_pixels=opts.max_pixels,
            overlay_fps=opts.overlay_fps,
        )
        if probe.info is not None:
            result.info = probe.info
        identity = input_identity(inp, sources)
    except QdcnnError as exc:
        result.error = " ".join(str(exc).split())
        plan.finished = True
        return plan
    result.decoder = decoder if isinstance(inp, VideoInput) else None
    size = probe.size
    if opts.overlay and size is not None and (size[0] % 2 or size[1] % 2):
        # 4:2:0 video needs even sizes: the overlay gets one replicated edge pixel more
        result.info["overlay_padded_to"] = [size[0] + size[0] % 2, size[1] + size[1] % 2]
    plan.n_frames, plan.truncated_from = probe.frames, probe.truncated_from
    config = _config_of(settings, opts, header, decoder)
    plan.ledger = InputLedger(inp.name, identity, config)
    plan.chunks = _chunk_tasks(inp, probe, decoder, opts)
    result.chunks = len(plan.chunks)
    _find_finished_work(plan, folder, opts.force)
    return plan


def _chunk_tasks(inp: Input, probe: Probe, decoder: str, opts: RunOptions) -> list[ChunkTask]:
    step, n = opts.chunk_frames, probe.frames
    return [
        ChunkTask(
            inp,
            k,
            start,
            min(start + step, n),
            opts.smooth,
            opts.overlay,
            probe.size,
            probe.fps,
            probe.use_timestamps,
            decoder,
            opts.max_pixels,
            opts.encoder,
        )
        for k, start in enumerate(range(0, n, step))
    ]


def _find_finished_work(plan: _Plan, folder: OutputFolder, force: bool) -> None:
    """Mark the plan finished when its final files are recorded, else list the chunks to do."""
    saved = None if force else plan.ledger.finished(folder)
    if saved is not None:
        _restore_result(plan.result, saved)
        plan.finished = True
        remove_chunks(folder, plan.ledger, plan.chunks)
        return
    for task in plan.chunks:
        complete = plan.ledger.chunk_is_complete(folder, task.chunk, task.start, task.stop)
        if complete and not force:
            plan.done_chunks.add(task.chunk)
            plan.result.chunks_skipped += 1
        else:
            plan.todo.append(task)


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
    """Run the chunks still to do; assemble each input as soon as its chunks are done."""
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
            _finish(plan, folder)

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
            _finish(plan, folder)


def _store_chunk(plan: _Plan, chunk: ChunkResult, folder: OutputFolder) -> None:
    store_chunk(folder, plan.ledger, chunk)
    plan.done_chunks.add(chunk.task.chunk)
    plan.result.frames_processed += chunk.frames
    plan.result.seconds += chunk.seconds


def _finish(plan: _Plan, folder: OutputFolder) -> None:
    """Join the chunks into the final files, record them, then drop the chunk files."""
    try:
        joined = assemble(folder, plan.ledger, plan.header, plan.chunks)
    except ChunkVanishedError as exc:
        plan.result.error = str(exc)
        return
    bad = joined.bad_frames
    if plan.truncated_from is not None:
        declared = int(plan.result.info.get("declared_frames") or plan.truncated_from)
        bad.append((plan.truncated_from, f"truncated: the file declares {declared} frames"))
    result = plan.result
    result.frames = plan.n_frames
    result.directions = joined.directions
    result.bad_frames = sorted(bad)
    result.outputs = final_outputs(folder, joined.outputs)
    saved = {
        "frames": result.frames,
        "outputs": result.outputs,
        "directions": result.directions,
        "bad_frames": result.bad_frames,
    }
    plan.ledger.record_final(folder, joined.outputs, saved)
    plan.finished = True
    remove_chunks(folder, plan.ledger, plan.chunks)
