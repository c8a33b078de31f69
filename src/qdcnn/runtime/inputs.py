"""What a run reads: video files, image folders and frame-source objects, by unique name.

:func:`resolve_inputs` turns paths and objects into :data:`Input` values (the object of a
frame source stays with the client, in the ``sources`` mapping, and travels to workers
once, beside the tasks); :func:`probe_input` reads what planning needs (frame count,
size, frame rate); :func:`input_identity` names an input's contents for the manifest.
"""

from __future__ import annotations

import hashlib
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn.data.images import list_named_images, read_image, require_file
from qdcnn.data.video import VideoReader, is_video_file
from qdcnn.errors import InputError, ParameterError, QdcnnError
from qdcnn.outputs import file_identity
from qdcnn.runtime.manifest import SUMMARY

#: Frame rate of overlays of inputs without one (image folders, frame sources).
DEFAULT_OVERLAY_FPS = 10.0


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
            out.append(_path_input(Path(item), unique))
        elif hasattr(item, "image") and hasattr(item, "__len__"):
            name = unique(str(getattr(item, "name", "frames")))
            sources[name] = item
            out.append(SourceInput(name, str(getattr(item, "spec", name))))
        else:
            raise ParameterError(
                "inputs", type(item).__name__, "paths or objects with __len__ and image(i)"
            )
    return out, sources


def _path_input(path: Path, unique: Callable[[str], str]) -> Input:
    if path.is_dir():
        files = tuple(list_named_images([path]).images)
        return FolderInput(unique(path.resolve().name), path, files)
    if is_video_file(path) or not path.exists():
        return VideoInput(unique(path.stem), require_file(path, "file"))
    raise InputError(path, f"not a video file or folder (suffix {path.suffix!r})")


def _safe_name(name: str) -> str:
    cleaned = "".join(c if c.isalnum() or c in "-_." else "_" for c in name).strip(".")
    return cleaned or "input"


@dataclass(frozen=True)
class Probe:
    """What planning needs of an input.

    Attributes
    ----------
    frames : int
        Frames (rows of ``frames.csv``).
    size : (int, int) or None
        Width and height of the overlay (None: no frame could be read).
    use_timestamps : bool
        Whether the overlay follows the input's timestamps (videos).
    fps : float
        Frame rate of the overlay.
    truncated_from : int or None
        Where a truncated video's missing frames start.
    info : dict or None
        The video's description (:meth:`qdcnn.data.video.VideoInfo.to_dict`); None for
        other inputs.
    """

    frames: int
    size: tuple[int, int] | None
    use_timestamps: bool
    fps: float
    truncated_from: int | None = None
    info: dict[str, Any] | None = field(default=None)


def probe_input(
    inp: Input,
    sources: dict[str, Any],
    *,
    decoder: str,
    max_pixels: int,
    overlay_fps: float | None,
) -> Probe:
    """Frames, overlay size and frame rate of ``inp``; a video's index goes into ``sources``
    (chunks reopen the file with it).

    Raises
    ------
    QdcnnError
        The input cannot be read.
    """
    if isinstance(inp, VideoInput):
        with VideoReader(inp.path, decoder=decoder, max_pixels=max_pixels) as reader:  # type: ignore[arg-type]
            info = reader.info
            sources[inp.name] = reader.index  # chunks reopen the file with it
        fps = overlay_fps or info.fps or DEFAULT_OVERLAY_FPS
        truncated = info.frames if info.truncated else None
        return Probe(info.frames, (info.width, info.height), True, fps, truncated, info.to_dict())
    fps = overlay_fps or DEFAULT_OVERLAY_FPS
    if isinstance(inp, FolderInput):
        n = len(inp.files)
        first = _first_readable(lambda i: read_image(inp.files[i]), n)
    else:
        source = sources[inp.name]
        n = len(source)
        if n == 0:
            raise InputError(inp.spec, "no frames")
        first = _first_readable(lambda i: np.asarray(source.image(i)), n)
    found = None if first is None else (int(first.shape[1]), int(first.shape[0]))
    return Probe(n, found, False, fps)


def _first_readable(read: Callable[[int], NDArray[np.uint8]], n: int) -> NDArray[np.uint8] | None:
    for i in range(min(n, 16)):
        try:
            return read(i)
        except QdcnnError:
            continue
    return None


def _file_mark(path: Path) -> str:
    """Size and modification time of a folder's file; for one that cannot be examined (a
    broken symbolic link) why, so that file is a bad frame rather than the whole folder."""
    try:
        ident = file_identity(path)
    except InputError as exc:
        return f"unusable:{exc.reason}"
    return f"{ident['size']}:{ident['mtime_ns']}"


def input_identity(inp: Input, sources: Mapping[str, Any]) -> dict[str, Any]:
    """What names ``inp``'s contents in the manifest (a changed input redoes its work)."""
    if isinstance(inp, VideoInput):
        return {"kind": "video", **file_identity(inp.path)}
    if isinstance(inp, FolderInput):
        h = hashlib.sha256()
        for f in inp.files:
            h.update(f"{f.name}:{_file_mark(f)}\n".encode())
        return {"kind": "images", "path": str(inp.path.resolve()), "files": h.hexdigest()}
    source = sources[inp.name]
    fingerprint = getattr(source, "fingerprint", None)
    # without a fingerprint a source cannot be recognised again: never skip its work
    mark = fingerprint() if callable(fingerprint) else f"unrecognisable:{time.time_ns()}"
    return {"kind": "source", "spec": inp.spec, "frames": len(source), "fingerprint": mark}
