"""Chunk outputs into files: each finished chunk's files, then one input's final files.

:func:`store_chunk` writes a chunk's rows, timings and overlay segment atomically into
``DIR/<name>/.chunks/`` and records it in the manifest; when all of an input's chunks
are there, :func:`assemble` joins them into ``frames.csv``, ``timings.csv`` (rows
concatenated under their header) and ``overlay.mp4`` (segments remuxed into one mp4
without re-encoding, each segment starting with a keyframe), and
:func:`remove_chunks` drops the chunk files once the final files are recorded.
"""

from __future__ import annotations

import csv
import io
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from qdcnn._fileio import atomic_write_bytes
from qdcnn.data.video import VideoReader, VideoWriter, concat_mp4
from qdcnn.outputs import OutputFolder, OutputRecord
from qdcnn.runtime.chunks import ChunkResult, ChunkTask
from qdcnn.runtime.manifest import (
    CHUNK_DIR,
    FRAMES_CSV,
    OVERLAY,
    TIMINGS_CSV,
    InputLedger,
    chunk_files,
)

_TIMINGS_HEADER = "frame,process_ms,overlay_ms\n"


class ChunkVanishedError(Exception):
    """A recorded chunk's entry or files disappeared before the final files were joined."""


def store_chunk(folder: OutputFolder, ledger: InputLedger, chunk: ChunkResult) -> None:
    """Write one chunk's files atomically, then record the chunk in the manifest."""
    task = chunk.task
    rows, timings, video = chunk_files(ledger.name, task.chunk)
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
    ledger.record_chunk(folder, task.chunk, (task.start, task.stop), outputs, summary)


@dataclass
class Assembled:
    """An input's final files, written, and what its chunks found."""

    outputs: dict[str, OutputRecord]
    directions: dict[str, int]
    bad_frames: list[tuple[int, str]]


@dataclass
class _Parts:
    rows: list[str]
    timings: list[str]
    segments: list[tuple[bytes, float]] = field(default_factory=list)
    directions: Counter[str] = field(default_factory=Counter)
    bad: list[tuple[int, str]] = field(default_factory=list)


def assemble(
    folder: OutputFolder,
    ledger: InputLedger,
    header: Sequence[str],
    chunks: Sequence[ChunkTask],
) -> Assembled:
    """Join the recorded chunks of one input into ``frames.csv``, ``timings.csv`` and
    ``overlay.mp4`` (when the chunks have segments), written atomically.

    Raises
    ------
    ChunkVanishedError
        A chunk's entry or files are gone.
    """
    parts = _read_chunks(folder, ledger, header, chunks)
    name = ledger.name
    frames_csv, timings_csv = f"{name}/{FRAMES_CSV}", f"{name}/{TIMINGS_CSV}"
    outputs = {
        frames_csv: folder.write_text(frames_csv, "".join(parts.rows)),
        timings_csv: folder.write_text(timings_csv, "".join(parts.timings)),
    }
    if parts.segments:
        fps, segments = chunks[0].overlay_fps, parts.segments
        outputs[f"{name}/{OVERLAY}"] = folder.write_file(
            f"{name}/{OVERLAY}", lambda path: _join_segments(segments, path, fps)
        )
    return Assembled(outputs, dict(parts.directions), parts.bad)


def _read_chunks(
    folder: OutputFolder, ledger: InputLedger, header: Sequence[str], chunks: Sequence[ChunkTask]
) -> _Parts:
    header_buf = io.StringIO()
    csv.writer(header_buf, lineterminator="\n").writerow(header)
    parts = _Parts([header_buf.getvalue()], [_TIMINGS_HEADER])
    for task in chunks:
        entry = ledger.chunk_entry(folder, task.chunk)
        rows, timings, video = chunk_files(ledger.name, task.chunk)
        data = [folder.read_bytes(rows), folder.read_bytes(timings)]
        if entry is None or data[0] is None or data[1] is None:
            raise ChunkVanishedError(
                f"{ledger.name}: chunk {task.chunk} vanished while assembling"
            )
        parts.rows.append(data[0].decode("utf-8"))
        parts.timings.append(data[1].decode("utf-8"))
        parts.directions.update(entry.result.get("directions", {}))
        parts.bad += [(int(i), str(r)) for i, r in entry.result.get("bad_frames", [])]
        if entry.result.get("overlay"):
            segment = folder.read_bytes(video)
            if segment is not None:
                parts.segments.append((segment, float(entry.result["overlay_start"])))
    return parts


def _join_segments(segments: list[tuple[bytes, float]], path: Path, fps: float) -> None:
    """Write the overlay segments as one mp4 at ``path``: remuxed with PyAV, else decoded
    and encoded again with OpenCV."""
    from qdcnn._optional import has_module

    if has_module("av"):
        concat_mp4(segments, path, atomic=False)
        return
    import tempfile

    writer = VideoWriter(path, fps, encoder="opencv")
    with tempfile.TemporaryDirectory() as tmp:
        for k, (data, _start) in enumerate(segments):
            seg = Path(tmp) / f"{k}.mp4"
            atomic_write_bytes(seg, data)
            with VideoReader(seg, decoder="opencv") as reader:
                for frame in reader:
                    writer.write(frame.image)
    writer.close()


def remove_chunks(folder: OutputFolder, ledger: InputLedger, chunks: Sequence[ChunkTask]) -> None:
    """Drop every chunk's entry and files, and the input's chunk folder."""
    for task in chunks:
        ledger.forget_chunk(folder, task.chunk)
    folder.remove_folder(f"{ledger.name}/{CHUNK_DIR}")


def final_outputs(folder: OutputFolder, outputs: dict[str, Any]) -> dict[str, str]:
    """Absolute path of each final file, by its name inside the input's folder."""
    return {k.split("/", 1)[1]: str(folder.path(k)) for k in outputs}
