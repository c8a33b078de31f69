"""Entries of the on-disk lane-feature cache: atomic writes, checked reads, eviction.

One entry is an ``.npz`` file (NumPy's zip of arrays, read with
``allow_pickle=False``) holding, for ``N`` frames and each grouping ``g``:

``features/g``  float64 ``(N, width)``; ``status/g``  str ``(N,)`` (``ok``,
``one-line``, ``no-lines``, ``crossed``, ``wrong-side``, ``unreadable``);
``readable``  bool ``(N,)``; ``seconds``  float64 scalar; ``failures``  str ``(M,)``, one
JSON object ``{"file", "error"}`` per unreadable frame.

Writers put the whole file in place in one rename under a unique temporary name
(:func:`qdcnn._fileio.atomic_write_bytes`), so processes computing the same entry
at the same time never see or leave a half-written one. A reader checks every key,
shape, dtype and value against the frame count it expects; an entry that fails
(truncated, garbage, another layout) is reported with the cache file's path
(:class:`FeatureCacheWarning`, or a callback), removed, and treated as a miss so
the features are computed again.
"""

from __future__ import annotations

import io
import json
import math
import os
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from qdcnn._fileio import write_cache_entry
from qdcnn.batch import Failure

_STATUSES = frozenset({"ok", "one-line", "no-lines", "crossed", "wrong-side", "unreadable"})
#: ``(path, reason)`` -> None: told about every unusable entry before it is removed.
_BadEntryHandler = Callable[[Path, str], None]


class FeatureCacheWarning(UserWarning):
    """A feature cache entry could not be used (it is removed and recomputed) or written."""


class _BadEntry(Exception):
    """Why a cache entry is unusable (internal: :func:`read_entry` turns it into a report)."""


@dataclass(frozen=True)
class CachedFeatures:
    """The content of one cache entry (the fields of ``FeatureTable`` that are stored)."""

    features: dict[str, NDArray[np.float64]]
    status: dict[str, NDArray[np.str_]]
    readable: NDArray[np.bool_]
    failures: list[Failure]
    seconds_per_frame: float


def entry_path(directory: Path, key: str) -> Path:
    """Where the entry of cache ``key`` lives in ``directory``."""
    return directory / f"features-{key}.npz"


def write_entry(
    path: Path,
    entry: CachedFeatures,
    groupings: Sequence[str],
    *,
    on_error: Callable[[Path, str], None] | None = None,
) -> bool:
    """Store ``entry`` at ``path`` atomically; return whether it was written.

    A cache that cannot be written (read-only folder, full disk) is reported like a
    bad entry and the run goes on: the cache only saves time.
    """
    arrays: dict[str, NDArray[np.generic]] = {
        "readable": np.asarray(entry.readable, dtype=bool),
        "seconds": np.array(entry.seconds_per_frame, dtype=np.float64),
        "failures": np.array([json.dumps(f.to_dict()) for f in entry.failures], dtype=str),
    }
    for g in groupings:
        arrays[f"features/{g}"] = np.asarray(entry.features[g], dtype=np.float64)
        arrays[f"status/{g}"] = np.asarray(entry.status[g], dtype=str)
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **arrays)  # type: ignore[arg-type]
    error = write_cache_entry(path, buffer.getvalue())
    if error is not None:
        _report(on_error, path, f"not written ({error.reason})")
    return error is None


def read_entry(
    path: Path,
    groupings: Sequence[str],
    n_frames: int,
    width: int,
    *,
    on_bad: _BadEntryHandler | None = None,
) -> CachedFeatures | None:
    """The entry at ``path`` if it exists and matches; ``None`` for a miss.

    Parameters
    ----------
    path : Path
        The entry (:func:`entry_path`).
    groupings : sequence of str
        Groupings it must hold, and no others.
    n_frames, width : int
        Frames and feature columns it must have.
    on_bad : callable, optional
        Called with ``(path, reason)`` for an unusable entry; by default a
        :class:`FeatureCacheWarning` naming the file is issued. The entry is then
        removed (unless another process replaced it meanwhile) and ``None`` returned.
    """
    try:
        before = os.stat(path)
    except FileNotFoundError:
        return None
    except OSError as exc:
        _report(on_bad, path, f"cannot be read ({exc.strerror or exc})")
        return None
    try:
        arrays = _load_arrays(path)
        return _checked(arrays, groupings, n_frames, width)
    except _BadEntry as exc:
        _report(on_bad, path, f"{exc}; removed, the features are computed again")
        evict(path, before)
        return None


def evict(path: Path, seen: os.stat_result | None = None) -> bool:
    """Remove the entry at ``path``; with ``seen``, only if it is still that same file.

    A concurrent writer may have replaced a bad entry with a good one between the
    read and the removal; comparing inode, size and modification time keeps the
    good one. Returns whether a file was removed.
    """
    try:
        now = os.stat(path)
        same = seen is None or (
            (now.st_ino, now.st_size, now.st_mtime_ns)
            == (seen.st_ino, seen.st_size, seen.st_mtime_ns)
        )
        if same:
            os.unlink(path)
        return same
    except OSError:
        return False


def _report(handler: _BadEntryHandler | None, path: Path, reason: str) -> None:
    if handler is not None:
        handler(path, reason)
    else:
        message = f"{path}: feature cache entry {reason}"
        warnings.warn(message, FeatureCacheWarning, stacklevel=3)


def _load_arrays(path: Path) -> dict[str, NDArray[np.generic]]:
    """Every array of the entry, read without pickle; any failure is a :class:`_BadEntry`."""
    try:
        data = np.load(path, allow_pickle=False)
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise _BadEntry("is not an .npz archive")
        with data:
            return {name: np.asarray(data[name]) for name in data.files}
    except _BadEntry:
        raise
    except Exception as exc:  # zip, zlib and npy readers raise many types on damaged files
        text = " ".join(str(exc).split())[:160]
        raise _BadEntry(f"is unreadable ({type(exc).__name__}: {text})") from None


def _checked(
    arrays: Mapping[str, NDArray[np.generic]], groupings: Sequence[str], n: int, width: int
) -> CachedFeatures:
    expected = {"readable", "seconds", "failures"}
    expected.update(f"{kind}/{g}" for g in groupings for kind in ("features", "status"))
    missing, extra = sorted(expected - set(arrays)), sorted(set(arrays) - expected)
    if missing or extra:
        raise _BadEntry(f"has other arrays (missing {missing}, unexpected {extra})")
    readable: NDArray[np.bool_] = _array(arrays, "readable", "b", (n,)).astype(bool, copy=False)
    features = {g: _array(arrays, f"features/{g}", "f", (n, width)) for g in groupings}
    status = {g: _array(arrays, f"status/{g}", "U", (n,)) for g in groupings}
    for g, values in status.items():
        odd = sorted(set(np.unique(values).tolist()) - _STATUSES)
        if odd:
            raise _BadEntry(f"status/{g} holds unknown values {odd[:3]}")
        if not np.array_equal(values == "unreadable", ~readable):
            raise _BadEntry(f"status/{g} does not match 'readable'")
    seconds = float(_array(arrays, "seconds", "f", ()))
    if not (math.isnan(seconds) or 0 <= seconds < math.inf):
        raise _BadEntry(f"seconds per frame is {seconds}")
    failures = _failures(_array(arrays, "failures", "U", None))
    if len(failures) != int(np.count_nonzero(~readable)):
        raise _BadEntry(f"lists {len(failures)} failures for {np.count_nonzero(~readable)} frames")
    return CachedFeatures(features, status, readable, failures, seconds)  # type: ignore[arg-type]


def _array(
    arrays: Mapping[str, NDArray[np.generic]],
    name: str,
    kind: str,
    shape: tuple[int, ...] | None,
) -> NDArray[np.generic]:
    """``arrays[name]`` if its dtype kind is ``kind`` and its shape ``shape`` (``None``: 1-D)."""
    a = arrays[name]
    good_shape = a.ndim == 1 if shape is None else a.shape == shape
    if a.dtype.kind != kind or not good_shape:
        want = "1-D" if shape is None else str(shape)
        raise _BadEntry(f"array {name!r} is {a.dtype} {a.shape}, expected kind {kind!r} {want}")
    return a


def _failures(texts: NDArray[np.generic]) -> list[Failure]:
    out = []
    for text in texts.tolist():
        try:
            item = json.loads(text)
        except (ValueError, RecursionError):
            raise _BadEntry("a failure record is not JSON") from None
        if (
            not isinstance(item, dict)
            or set(item) != {"file", "error"}
            or not all(isinstance(v, str) for v in item.values())
        ):
            raise _BadEntry("a failure record is not {'file': str, 'error': str}")
        out.append(Failure(item["file"], item["error"]))
    return out
