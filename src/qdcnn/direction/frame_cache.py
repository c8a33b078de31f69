"""Frames decoded and resized once per recording, for every CNN fold, seed and method.

A frame method (a CNN or a hybrid) sees each frame cropped and resized to its network
input (:func:`qdcnn.models.preprocess.prepare_frames`). :func:`network_frames` decodes a
recording's frames once, prepares them, and keeps them on disk in ``$QDCNN_CACHE``
(default ``~/.cache/qdcnn``) as a memory-mapped ``.npy`` array, keyed like the lane
feature cache: the recording's fingerprint (frame names, sizes, modification times) and
the input (crop rows and size). Every later fold, seed, method and run at that input
reads the array back instead of decoding thousands of JPEG files again.

An entry is two files: ``frames-<key>.npy``, uint8 ``(N, height, width, 3)`` (NumPy's
format, no pickle; unreadable frames are zero), written first, and ``frames-<key>.json``
(which frames were readable, why the others were not, the array's shape and byte size),
written last, so a reader that finds the JSON finds a complete array. Both are written
atomically (:func:`qdcnn._fileio.atomic_write_npy`, :func:`~qdcnn._fileio.atomic_write_bytes`).
A reader checks the JSON, the array's header, shape, dtype and file size against the
recording; an entry that fails (truncated, garbage, another layout) is reported in a
note naming the file, removed and built again.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from qdcnn import __version__
from qdcnn._fileio import atomic_write_bytes, atomic_write_npy, discard
from qdcnn.batch import Failure, run_batch
from qdcnn.data.frames import FrameSet
from qdcnn.direction.features import cache_dir
from qdcnn.errors import InputError

if TYPE_CHECKING:
    from qdcnn.models.specs import InputSpec

#: Layout of an entry; a change makes every old entry a miss.
FORMAT = 1
#: Frames decoded before they are resized together.
_CHUNK = 256

_Note = Callable[[str], None]


class _BadEntry(Exception):
    """Why an entry cannot be used (internal: :func:`network_frames` turns it into a note)."""


def entry_paths(frames: FrameSet, spec: InputSpec) -> tuple[Path, Path]:
    """The ``.npy`` array and ``.json`` record of ``frames`` prepared for ``spec``."""
    payload = json.dumps(
        {
            "data": frames.fingerprint(),
            "crop": list(spec.crop),
            "size": [spec.height, spec.width],
            "format": FORMAT,
            "version": __version__,
        },
        sort_keys=True,
    )
    key = hashlib.sha256(payload.encode()).hexdigest()[:32]
    folder = cache_dir()
    return folder / f"frames-{key}.npy", folder / f"frames-{key}.json"


def network_frames(
    frames: FrameSet,
    spec: InputSpec,
    *,
    use_cache: bool = True,
    on_note: _Note | None = None,
) -> tuple[NDArray[np.uint8], NDArray[np.bool_], list[Failure]]:
    """Every frame of ``frames`` cropped and resized for ``spec``, decoded once per recording.

    Parameters
    ----------
    frames : FrameSet
        The recording.
    spec : InputSpec
        The network input (crop rows and size).
    use_cache : bool
        Read and write the on-disk entry; without it the frames are decoded and kept in
        memory only.
    on_note : callable, optional
        Told one line for each unusable entry (rebuilt) or entry that cannot be written.

    Returns
    -------
    images : PreparedFrames
        ``(N, height, width, 3)`` uint8 (memory-mapped from the cache, read-only); what a
        network of ``spec`` is fed for each frame (zero for unreadable ones).
    readable : ndarray of bool, shape (N,)
    failures : list of Failure
        Unreadable frames and frames of another size than the first, as
        :func:`qdcnn.data.frames.stack_images` reports them.
    """
    from qdcnn.models.preprocess import PreparedFrames

    if not use_cache:  # nor a fingerprint: any source of frames will do
        images, readable, failures = _decode_prepared(frames, spec)
        return PreparedFrames(images, spec), readable, failures
    tell = on_note or (lambda _line: None)
    array_path, record_path = entry_paths(frames, spec)
    if record_path.exists():
        try:
            images, readable, failures = _read_entry(array_path, record_path, len(frames), spec)
        except _BadEntry as exc:
            tell(f"frame cache {array_path}: {exc}; decoding the frames again")
            discard(record_path)
            discard(array_path)
        else:
            return PreparedFrames(images, spec), readable, failures
    images, readable, failures = _decode_prepared(frames, spec)
    _write_entry(array_path, record_path, images, readable, failures, tell)
    return PreparedFrames(images, spec), readable, failures


def _decode_prepared(
    frames: FrameSet, spec: InputSpec
) -> tuple[NDArray[np.uint8], NDArray[np.bool_], list[Failure]]:
    """Decode every frame once and prepare it, :data:`_CHUNK` frames at a time."""
    from qdcnn.models.preprocess import prepare_frames

    n = len(frames)
    out = np.zeros((n, spec.height, spec.width, 3), dtype=np.uint8)
    readable = np.zeros(n, dtype=bool)
    failures: list[Failure] = []
    first: tuple[int, ...] | None = None
    pending: list[tuple[int, NDArray[np.uint8]]] = []
    for outcome in run_batch(range(n), frames.image, name=lambda i: frames.sources[i]):
        image = outcome.result
        if image is not None and (first is None or image.shape == first):
            first = first or image.shape
            pending.append((outcome.item, image))
            readable[outcome.item] = True
        else:
            failures.append(_failure(frames, outcome.item, outcome.failure, image, first))
        if len(pending) >= _CHUNK:
            _prepare_into(out, pending, spec, prepare_frames)
    _prepare_into(out, pending, spec, prepare_frames)
    return out, readable, failures


def _prepare_into(
    out: NDArray[np.uint8],
    pending: list[tuple[int, NDArray[np.uint8]]],
    spec: InputSpec,
    prepare: Callable[[NDArray[np.uint8], InputSpec], NDArray[np.uint8]],
) -> None:
    """Prepare the decoded frames of ``pending`` into their rows of ``out``; empty it."""
    if pending:
        rows = [i for i, _ in pending]
        out[rows] = prepare(np.stack([image for _, image in pending]), spec)
        pending.clear()


def _failure(
    frames: FrameSet,
    item: int,
    failure: Failure | None,
    image: NDArray[np.uint8] | None,
    first: tuple[int, ...] | None,
) -> Failure:
    if failure is not None:
        return failure
    source = frames.sources[item]
    shape = None if image is None else image.shape
    return Failure(source, f"{source}: frame size {shape} differs from the first frame's {first}")


def _write_entry(
    array_path: Path,
    record_path: Path,
    images: NDArray[np.uint8],
    readable: NDArray[np.bool_],
    failures: list[Failure],
    tell: _Note,
) -> None:
    """Store an entry (the array first, the record last); a failed write is only a note."""
    record = {
        "format": FORMAT,
        "shape": list(images.shape),
        "bytes": 0,
        "readable": "".join("1" if r else "0" for r in readable),
        "failures": [{"file": f.file, "error": f.error} for f in failures],
    }
    try:
        atomic_write_npy(array_path, images)
        record["bytes"] = array_path.stat().st_size
        atomic_write_bytes(record_path, json.dumps(record).encode())
    except (InputError, OSError) as exc:
        tell(f"frame cache {array_path} not written: {exc}")


def _read_entry(
    array_path: Path, record_path: Path, n: int, spec: InputSpec
) -> tuple[NDArray[np.uint8], NDArray[np.bool_], list[Failure]]:
    """The entry's array (memory-mapped), readable flags and failures, all checked."""
    record = _read_record(record_path)
    shape = (n, spec.height, spec.width, 3)
    if record.get("format") != FORMAT or tuple(record.get("shape", ())) != shape:
        raise _BadEntry(f"made for another layout than {shape}")
    flags = str(record.get("readable", ""))
    if len(flags) != n or set(flags) - {"0", "1"}:
        raise _BadEntry("its record of readable frames does not fit the recording")
    try:
        size = array_path.stat().st_size
        images = np.load(array_path, mmap_mode="r", allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise _BadEntry(f"unreadable ({exc})") from None
    if size != record.get("bytes") or images.dtype != np.uint8 or images.shape != shape:
        raise _BadEntry(f"truncated or altered ({size} bytes, {images.dtype} {images.shape})")
    readable = np.array([c == "1" for c in flags], dtype=bool)
    failures = [Failure(str(f["file"]), str(f["error"])) for f in record.get("failures", [])]
    return images, readable, failures


def _read_record(path: Path) -> dict[str, Any]:
    try:
        record = json.loads(path.read_bytes())
    except (OSError, ValueError) as exc:
        raise _BadEntry(f"its record {path.name} is unreadable ({exc})") from None
    if not isinstance(record, dict):
        raise _BadEntry(f"its record {path.name} is not a JSON object")
    return record


def method_inputs(
    method: Any,
    config: Any,
    options: Any,
    frames: FrameSet,
    *,
    use_cache: bool = True,
    on_note: _Note | None = None,
) -> tuple[NDArray[np.uint8], NDArray[np.bool_], list[Failure]]:
    """The frames a frame method is fitted and scored on: for a CNN or hybrid (a
    :class:`~qdcnn.models.training.CNNDirectionClassifier`), :func:`network_frames` at its
    input; for another frame method (HOG), :func:`qdcnn.data.frames.stack_images`."""
    from qdcnn.data.frames import stack_images

    estimator, grid = method.estimator(config, options)
    spec = _network_input(estimator)
    if spec is None or "crop" in grid or "arch" in grid:
        return stack_images(frames)
    return network_frames(frames, spec, use_cache=use_cache, on_note=on_note)


def _network_input(estimator: Any) -> InputSpec | None:
    from qdcnn._optional import has_torch

    if not has_torch():
        return None
    from qdcnn.models.networks import input_spec
    from qdcnn.models.training import CNNDirectionClassifier

    if not isinstance(estimator, CNNDirectionClassifier):
        return None
    return input_spec(estimator.arch, estimator.crop)
