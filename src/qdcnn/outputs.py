"""Crash-safe output folders: one writer at a time, atomic files, and a manifest of finished work.

An :class:`OutputFolder` is opened by one run at a time: it holds an exclusive
``fcntl.flock`` on ``DIR/.qdcnn.lock`` (released by the kernel when the process ends,
``kill -9`` included). A second run into the same folder waits up to ``wait`` seconds and
then refuses with a one-line :class:`OutputLockedError` naming the folder.

Every file is written as :mod:`qdcnn._fileio` does (a hidden temporary name in the target's
folder, flushed to disk, then renamed), but relative to the folder's open descriptor and with
``O_NOFOLLOW`` at every step, so neither a symbolic link at the target nor one in place of a
sub-folder is ever followed. Temporary files left by a killed run are removed when the folder
is next opened (the lock says no one else is writing).

The :class:`Manifest` keeps one small JSON file per finished entry under
``DIR/.qdcnn-manifest/``, written atomically after the entry's outputs, so a crash can never
corrupt a finished entry: an entry is either complete (its file parses, its input identity
and config hash match, its outputs exist with the recorded sizes) or it is redone. An
unreadable entry file (which atomic writes never produce) counts as missing.

Examples
--------
>>> import tempfile
>>> with tempfile.TemporaryDirectory() as d, OutputFolder(d) as out:
...     record = out.write_text("a/b.txt", "hello\\n")
...     _ = out.manifest.record("a", {"input": 1}, "cfg", {"a/b.txt": record}, {"n": 1})
...     out.manifest.status("a", {"input": 1}, "cfg")
'complete'
"""

from __future__ import annotations

import errno
import fcntl
import hashlib
import json
import os
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from qdcnn import __version__
from qdcnn._closing import ClosesOnExit
from qdcnn._fileio import TEMPORARY_NAME, os_reason, temporary_sibling
from qdcnn.errors import InputError, OutputError, ParameterError

LOCK_NAME = ".qdcnn.lock"
_MANIFEST_DIR = ".qdcnn-manifest"
_DIR_FLAGS = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0) | getattr(os, "O_NOFOLLOW", 0)
Status = Literal["complete", "missing", "stale"]


class OutputLockedError(OutputError):
    """Another process holds the output folder's lock."""


@dataclass(frozen=True)
class OutputRecord:
    """A finished output file: size and SHA-256 of its bytes."""

    size: int
    sha256: str

    @classmethod
    def of(cls, data: bytes) -> OutputRecord:
        return cls(len(data), hashlib.sha256(data).hexdigest())

    def to_dict(self) -> dict[str, Any]:
        return {"size": self.size, "sha256": self.sha256}


@dataclass(frozen=True)
class ManifestEntry:
    """What a finished entry was made from and what it wrote.

    Attributes
    ----------
    key : str
        Deterministic name of the entry (for example ``"drive/chunk-00003"``).
    input : dict
        Identity of the input (:func:`file_identity` or any plain-JSON mapping).
    config_hash : str
        :func:`config_hash` of every setting that changes the outputs.
    outputs : dict of str to OutputRecord
        Files written, relative to the folder.
    result : dict
        A plain-JSON summary of the result.
    """

    key: str
    input: dict[str, Any]
    config_hash: str
    outputs: dict[str, OutputRecord] = field(default_factory=dict)
    result: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {
            "key": self.key,
            "input": self.input,
            "config_hash": self.config_hash,
            "outputs": {k: v.to_dict() for k, v in self.outputs.items()},
            "result": self.result,
            "qdcnn_version": __version__,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ManifestEntry:
        outputs = {
            str(k): OutputRecord(int(v["size"]), str(v["sha256"]))
            for k, v in dict(data["outputs"]).items()
        }
        return cls(
            str(data["key"]),
            dict(data["input"]),
            str(data["config_hash"]),
            outputs,
            dict(data.get("result", {})),
        )


def config_hash(config: Mapping[str, Any]) -> str:
    """A short stable hash of plain settings (sorted-key JSON; paths and tuples allowed)."""
    text = json.dumps(config, sort_keys=True, separators=(",", ":"), default=_plain)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:24]


def _plain(value: Any) -> Any:
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, tuple | set | frozenset):
        return list(value)
    if hasattr(value, "item"):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def file_identity(path: str | os.PathLike[str], *, content_hash: bool = False) -> dict[str, Any]:
    """Identity of an input file: resolved path, size, modification time (and SHA-256).

    Raises
    ------
    InputError
        The file cannot be examined.
    """
    p = Path(path)
    try:
        st = p.stat()
    except OSError as exc:
        if isinstance(exc, FileNotFoundError) and p.is_symlink():
            raise InputError(p, "cannot read: a broken symbolic link") from None
        raise InputError(p, f"cannot read: {os_reason(exc)}") from None
    out: dict[str, Any] = {"path": str(p.resolve()), "size": st.st_size, "mtime_ns": st.st_mtime_ns}
    if content_hash:
        h = hashlib.sha256()
        with open(p, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
        out["sha256"] = h.hexdigest()
    return out


def _split(relpath: str | os.PathLike[str]) -> list[str]:
    rel = os.fspath(relpath)
    parts = rel.replace("\\", "/").split("/")
    if os.path.isabs(rel) or not rel or any(p in ("", ".", "..") for p in parts):
        raise ParameterError("path", rel, "a relative path inside the output folder, without ..")
    return parts


def refuse_output_in_inputs(
    out: str | os.PathLike[str], inputs: Iterable[str | os.PathLike[str]]
) -> None:
    """Refuse an output folder that is one of the input folders or lies inside one.

    A run's masks, overlays or rows written there would be read as inputs by the next run
    over the same folders. Only inputs that are folders count (a video file's folder may
    hold the outputs); links are resolved first.

    Raises
    ------
    InputError
        Naming the output folder and the input folder it is in.
    """
    target = Path(out).resolve()
    for item in inputs:
        folder = Path(item)
        if not folder.is_dir():
            continue
        where = folder.resolve()
        if target == where or target.is_relative_to(where):
            what = "is the input folder" if target == where else "lies inside the input folder"
            raise InputError(
                out,
                f"{what} {folder}: the outputs would be read as inputs on the next run "
                "(choose an output folder outside the inputs)",
            )


class OutputFolder(ClosesOnExit):
    """An output folder opened for writing by this process alone.

    Parameters
    ----------
    root : path-like
        The folder (created if needed). It may itself be a symbolic link chosen by the
        user; nothing below it is ever reached through one.
    wait : float
        Seconds to wait for another run's lock before refusing (0: refuse at once).

    Raises
    ------
    OutputLockedError
        Another process is writing to the folder.
    OutputError
        The folder cannot be created or written.
    """

    def __init__(self, root: str | os.PathLike[str], *, wait: float = 0.0) -> None:
        if not isinstance(wait, int | float) or isinstance(wait, bool) or wait < 0:
            raise ParameterError("wait", wait, "a number of seconds >= 0")
        self.root = Path(root)
        self.wait = float(wait)
        self._dir_fd: int | None = None
        self._lock_fd: int | None = None
        self.manifest = Manifest(self)

    # ------------------------------------------------------------------ open and lock
    def open(self) -> OutputFolder:
        try:
            self.root.mkdir(parents=True, exist_ok=True)
            self._dir_fd = os.open(self.root, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
        except OSError as exc:
            raise OutputError(
                self.root, f"cannot create or open the output folder: {os_reason(exc)}"
            ) from None
        try:
            self._lock_fd = os.open(
                LOCK_NAME,
                os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0),
                0o644,
                dir_fd=self._dir_fd,
            )
        except OSError as exc:
            self.close()
            raise OutputError(
                self.root, f"output folder is not writable: {os_reason(exc)}"
            ) from None
        self._acquire()
        try:
            os.ftruncate(self._lock_fd, 0)
            os.write(self._lock_fd, f"{os.getpid()}\n".encode())
        except OSError:
            pass  # the pid is for people looking at the folder; the lock is what counts
        self.remove_stale_temporaries()
        return self

    def _acquire(self) -> None:
        assert self._lock_fd is not None
        deadline = time.monotonic() + self.wait
        while True:
            try:
                fcntl.flock(self._lock_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                return
            except OSError as exc:
                if exc.errno not in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                    self.close()
                    raise OutputError(self.root, f"cannot lock: {os_reason(exc)}") from None
            if time.monotonic() >= deadline:
                self.close()
                waited = f" (waited {self.wait:g} s)" if self.wait else ""
                raise OutputLockedError(
                    self.root,
                    f"another qdcnn run is writing to this folder ({LOCK_NAME} is locked)"
                    f"{waited}; wait for it to finish or choose another output folder",
                )
            time.sleep(min(0.05, max(deadline - time.monotonic(), 0.0)))

    def close(self) -> None:
        for name in ("_lock_fd", "_dir_fd"):
            fd = getattr(self, name)
            if fd is not None:
                os.close(fd)  # closing the descriptor releases the flock
                setattr(self, name, None)

    def __enter__(self) -> OutputFolder:
        return self.open()

    @property
    def is_open(self) -> bool:
        return self._lock_fd is not None

    def _fd(self) -> int:
        if self._dir_fd is None or self._lock_fd is None:
            raise ParameterError("OutputFolder", str(self.root), "opened (use it in a with block)")
        return self._dir_fd

    # ------------------------------------------------------------------ safe paths
    def _parent_fd(self, parts: list[str], *, create: bool) -> int:
        """An open descriptor of the folder holding ``parts[-1]``; no link is followed."""
        fd = os.dup(self._fd())
        try:
            for i, part in enumerate(parts[:-1]):
                if create:
                    try:
                        os.mkdir(part, 0o755, dir_fd=fd)
                    except FileExistsError:
                        pass
                try:
                    child = os.open(part, _DIR_FLAGS, dir_fd=fd)
                except OSError as exc:
                    shown = self.root.joinpath(*parts[: i + 1])
                    if exc.errno in (errno.ELOOP, errno.ENOTDIR) and os.path.islink(shown):
                        raise OutputError(
                            shown, "is a symbolic link; qdcnn never writes through one"
                        ) from None
                    raise OutputError(shown, f"cannot open folder: {os_reason(exc)}") from None
                os.close(fd)
                fd = child
        except BaseException:
            os.close(fd)
            raise
        return fd

    def path(self, relpath: str | os.PathLike[str]) -> Path:
        """The absolute path of ``relpath`` in the folder (checked, not created)."""
        return self.root.joinpath(*_split(relpath))

    def write_bytes(self, relpath: str | os.PathLike[str], data: bytes) -> OutputRecord:
        """Write ``data`` to ``relpath`` atomically; returns its size and SHA-256."""
        parts = _split(relpath)
        target = self.root.joinpath(*parts)
        fd = self._parent_fd(parts, create=True)
        tmp = temporary_sibling(Path(parts[-1])).name
        try:
            out = os.open(
                tmp,
                os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0),
                0o644,
                dir_fd=fd,
            )
            try:
                view = memoryview(data)
                while view:
                    view = view[os.write(out, view) :]
                os.fsync(out)
            finally:
                os.close(out)
            os.replace(tmp, parts[-1], src_dir_fd=fd, dst_dir_fd=fd)
            os.fsync(fd)
        except OSError as exc:
            try:
                os.unlink(tmp, dir_fd=fd)
            except OSError:
                pass
            raise OutputError(target, f"cannot write: {os_reason(exc)}") from None
        finally:
            os.close(fd)
        return OutputRecord.of(data)

    def write_file(
        self, relpath: str | os.PathLike[str], write: Callable[[Path], object]
    ) -> OutputRecord:
        """Let ``write(path)`` create a file (for libraries that write by path, such as
        FFmpeg), then move it to ``relpath`` atomically; returns its size and SHA-256.

        ``path`` is a fresh temporary name in the target's folder, reached through the
        folder's open descriptor (``/proc/self/fd``) where the system has one, so no link
        is followed on the way; its suffix is the target's.
        """
        parts = _split(relpath)
        target = self.root.joinpath(*parts)
        fd = self._parent_fd(parts, create=True)
        tmp = temporary_sibling(Path(parts[-1])).name + Path(parts[-1]).suffix
        via_fd = Path(f"/proc/self/fd/{fd}")
        base = via_fd if via_fd.is_dir() else target.parent
        try:
            write(base / tmp)
            st = os.stat(tmp, dir_fd=fd, follow_symlinks=False)
            if (st.st_mode & 0o170000) != 0o100000:
                raise OutputError(target, "the writer did not produce a regular file")
            h = hashlib.sha256()
            f = os.open(tmp, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0), dir_fd=fd)
            try:
                with os.fdopen(f, "rb") as fh:
                    for block in iter(lambda: fh.read(1 << 20), b""):
                        h.update(block)
                    os.fsync(fh.fileno())
            except OSError:
                raise
            os.replace(tmp, parts[-1], src_dir_fd=fd, dst_dir_fd=fd)
            os.fsync(fd)
        except BaseException as exc:
            try:
                os.unlink(tmp, dir_fd=fd)
            except OSError:
                pass
            if isinstance(exc, OSError):
                raise OutputError(target, f"cannot write: {os_reason(exc)}") from None
            raise
        finally:
            os.close(fd)
        return OutputRecord(st.st_size, h.hexdigest())

    def remove_folder(self, relpath: str | os.PathLike[str]) -> None:
        """Remove an empty sub-folder (anything else is left alone)."""
        parts = _split(relpath)
        try:
            fd = self._parent_fd(parts, create=False)
        except InputError:
            return
        try:
            os.rmdir(parts[-1], dir_fd=fd)
        except OSError:
            pass
        finally:
            os.close(fd)

    def write_text(self, relpath: str | os.PathLike[str], text: str) -> OutputRecord:
        """:meth:`write_bytes` of ``text`` as UTF-8."""
        return self.write_bytes(relpath, text.encode("utf-8"))

    def read_bytes(self, relpath: str | os.PathLike[str]) -> bytes | None:
        """The bytes of a regular file in the folder, or ``None`` (missing, link, folder)."""
        parts = _split(relpath)
        try:
            fd = self._parent_fd(parts, create=False)
        except InputError:
            return None
        try:
            f = os.open(parts[-1], os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0), dir_fd=fd)
        except OSError:
            return None
        finally:
            os.close(fd)
        try:
            with os.fdopen(f, "rb") as fh:
                return fh.read()
        except OSError:
            return None

    def size_of(self, relpath: str | os.PathLike[str]) -> int | None:
        """Size of a regular file in the folder (``None``: missing, a link or not a file)."""
        parts = _split(relpath)
        try:
            fd = self._parent_fd(parts, create=False)
        except InputError:
            return None
        try:
            st = os.stat(parts[-1], dir_fd=fd, follow_symlinks=False)
        except OSError:
            return None
        finally:
            os.close(fd)
        return st.st_size if (st.st_mode & 0o170000) == 0o100000 else None

    def remove(self, relpath: str | os.PathLike[str]) -> None:
        """Delete a file (a link is removed, never its target); missing is fine."""
        parts = _split(relpath)
        try:
            fd = self._parent_fd(parts, create=False)
        except InputError:
            return
        try:
            os.unlink(parts[-1], dir_fd=fd)
        except FileNotFoundError:
            pass
        except OSError as exc:
            reason = f"cannot remove: {os_reason(exc)}"
            raise OutputError(self.root.joinpath(*parts), reason) from None
        finally:
            os.close(fd)

    def remove_stale_temporaries(self) -> list[Path]:
        """Delete temporary files of killed runs (hidden ``*.tmp`` names); returns them."""
        self._fd()
        removed = []
        for folder, dirs, files in os.walk(self.root, followlinks=False):
            dirs[:] = [d for d in dirs if not os.path.islink(os.path.join(folder, d))]
            for name in files:
                if TEMPORARY_NAME.match(name):
                    path = Path(folder) / name
                    try:
                        path.unlink()
                        removed.append(path)
                    except OSError:
                        pass
        return removed


class Manifest:
    """Finished entries of an :class:`OutputFolder`, one JSON file each."""

    def __init__(self, folder: OutputFolder) -> None:
        self.folder = folder

    @staticmethod
    def entry_name(key: str) -> str:
        return f"{_MANIFEST_DIR}/{hashlib.sha256(key.encode()).hexdigest()[:32]}.json"

    def get(self, key: str) -> ManifestEntry | None:
        """The entry of ``key``, or ``None`` when absent or unreadable."""
        data = self.folder.read_bytes(self.entry_name(key))
        if data is None:
            return None
        try:
            entry = ManifestEntry.from_dict(json.loads(data.decode("utf-8")))
        except (ValueError, KeyError, TypeError, AttributeError):
            return None
        return entry if entry.key == key else None

    def status(
        self,
        key: str,
        input_identity: Mapping[str, Any],
        config: str,
        *,
        verify: Literal["size", "hash"] = "size",
    ) -> Status:
        """``"complete"``, ``"missing"`` (no entry or an output gone) or ``"stale"``
        (another input or config, or an output of another size or, with ``verify="hash"``,
        other contents)."""
        entry = self.get(key)
        if entry is None:
            return "missing"
        if entry.input != dict(_json_round_trip(input_identity)) or entry.config_hash != config:
            return "stale"
        for rel, record in entry.outputs.items():
            size = self.folder.size_of(rel)
            if size is None:
                return "missing"
            if size != record.size:
                return "stale"
            if verify == "hash":
                data = self.folder.read_bytes(rel)
                if data is None or OutputRecord.of(data) != record:
                    return "stale"
        return "complete"

    def record(
        self,
        key: str,
        input_identity: Mapping[str, Any],
        config: str,
        outputs: Mapping[str, OutputRecord],
        result: Mapping[str, Any] | None = None,
    ) -> ManifestEntry:
        """Mark ``key`` finished (call after its outputs are written)."""
        entry = ManifestEntry(
            key,
            dict(_json_round_trip(input_identity)),
            config,
            dict(outputs),
            dict(_json_round_trip(result or {})),
        )
        text = json.dumps(entry.to_dict(), sort_keys=True, indent=1, default=_plain)
        self.folder.write_text(self.entry_name(key), text + "\n")
        return entry

    def forget(self, key: str) -> None:
        """Remove the entry of ``key`` (its outputs stay)."""
        self.folder.remove(self.entry_name(key))


def _json_round_trip(value: Mapping[str, Any]) -> dict[str, Any]:
    """``value`` as it reads back from JSON (tuples become lists), for comparisons."""
    return dict(json.loads(json.dumps(value, sort_keys=True, default=_plain)))
