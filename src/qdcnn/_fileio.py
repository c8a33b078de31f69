"""Crash-safe file writes: a unique temporary name in the target's folder, then a rename.

A reader never sees a half-written file: the bytes go to ``.<name>.<random>.tmp``
beside the target, are flushed to disk, and :func:`os.replace` puts them in place
in one step. A target that is a symbolic link is refused, so a pre-made link is
never followed and its target never overwritten. Every :class:`OSError` becomes a
one-line :class:`~qdcnn.errors.OutputError` naming the path and the system's reason
(read-only file system, no space left on device, permission denied, ...), and the
clean-up of the temporary file never raises over it.
"""

from __future__ import annotations

import fcntl
import os
import re
import secrets
import stat
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO, TextIO

from qdcnn.errors import InputError, OutputError

if TYPE_CHECKING:
    from numpy.typing import NDArray


def temporary_sibling(path: Path) -> Path:
    """A fresh, unique temporary name in ``path``'s folder (hidden, ``.tmp`` suffix)."""
    return path.with_name(f".{path.name}.{secrets.token_hex(6)}.tmp")


def os_reason(exc: OSError) -> str:
    """The system's reason for ``exc`` in lower case ("read-only file system")."""
    reason = exc.strerror or str(exc) or type(exc).__name__
    return reason[:1].lower() + reason[1:]


_KINDS = {
    stat.S_IFDIR: "is a directory, not a file to write",
    stat.S_IFLNK: "is a symbolic link; qdcnn never writes through one",
    stat.S_IFCHR: "is a character device, not a regular file; qdcnn never writes to one",
    stat.S_IFBLK: "is a block device, not a regular file; qdcnn never writes to one",
    stat.S_IFIFO: "is a named pipe, not a regular file; qdcnn never writes to one",
    stat.S_IFSOCK: "is a socket, not a regular file; qdcnn never writes to one",
}


def refuse_non_regular(path: Path) -> None:
    """Raise :class:`OutputError` when ``path`` exists and is not a regular file.

    A symbolic link is refused whatever it points to (it is never followed); a device
    such as ``/dev/null`` is refused because a rename would replace the device itself.
    """
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    except OSError as exc:
        raise OutputError(path, f"cannot write: {os_reason(exc)}") from None
    kind = stat.S_IFMT(mode)
    if kind != stat.S_IFREG:
        raise OutputError(path, _KINDS.get(kind, "is not a regular file"))


def make_folder(folder: Path) -> None:
    """Create ``folder`` and its parents (existing is fine); one-line :class:`OutputError`
    naming it and the reason when that is impossible (a file in the way, read-only, ...)."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise OutputError(folder, "cannot create folder: not a directory") from None
    except OSError as exc:
        raise OutputError(folder, f"cannot create folder: {os_reason(exc)}") from None


def discard(path: Path) -> None:
    """Remove ``path`` if it can be; never raises (clean-up after an error)."""
    try:
        path.unlink(missing_ok=True)
    except OSError:
        pass


#: Names :func:`temporary_sibling` makes (with an optional kept suffix).
TEMPORARY_NAME = re.compile(r"^\..+\.[0-9a-f]{12}\.tmp(\.[A-Za-z0-9]+)?$")


def _write_and_replace(tmp: Path, data: bytes | Callable[[BinaryIO], object], target: Path) -> None:
    """Write ``tmp`` (``data``, or what ``data(file)`` writes) and rename it onto ``target``.

    The writer holds a shared ``flock`` on the folder from before ``tmp`` exists until the
    rename, so :func:`remove_dead_temporaries` (which needs the folder's exclusive lock)
    never takes a live writer's file for a dead one's.
    """
    folder = _lock_folder(target.parent, fcntl.LOCK_SH)
    try:
        flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
        with os.fdopen(os.open(tmp, flags, 0o644), "wb") as fh:
            if isinstance(data, bytes):
                fh.write(data)
            else:
                data(fh)
            fh.flush()
            os.fsync(fh.fileno())
            os.replace(tmp, target)
    finally:
        _unlock_folder(folder)


def _lock_folder(folder: Path, how: int) -> int | None:
    """An ``flock`` of kind ``how`` on ``folder`` (its open descriptor), or ``None`` when the
    folder cannot be opened or, with ``LOCK_NB``, is locked by another process."""
    try:
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return None
    try:
        fcntl.flock(fd, how)
    except OSError:
        os.close(fd)
        return None
    return fd


def _unlock_folder(fd: int | None) -> None:
    if fd is not None:
        os.close(fd)  # closing the descriptor drops its flock


def remove_dead_temporaries(folder: Path) -> list[Path]:
    """Remove the temporary files in ``folder`` left by writers that died (``kill -9``).

    For shared folders written without an output-folder lock (the caches). Every writer
    holds a shared lock on the folder while its temporary file exists (the kernel drops it
    when the writer dies), so when this takes the folder's exclusive lock every temporary
    file there is a dead writer's. While any writer is active it removes nothing (the next
    call will). Never raises; returns what it removed.
    """
    removed: list[Path] = []
    lock = _lock_folder(folder, fcntl.LOCK_EX | fcntl.LOCK_NB)
    if lock is None:
        return removed
    try:
        names = [n for n in os.listdir(folder) if TEMPORARY_NAME.match(n)]
        for name in names:
            try:
                (folder / name).unlink()
                removed.append(folder / name)
            except OSError:
                pass  # already gone
    except OSError:
        pass
    finally:
        _unlock_folder(lock)
    return removed


def _sync_folder(folder: Path) -> None:
    """Flush a rename in ``folder`` to disk where the system allows it (best effort)."""
    try:
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def atomic_write_npy(path: str | os.PathLike[str], array: NDArray[Any]) -> Path:
    """Write ``array`` as a ``.npy`` file (NumPy's format, no pickle) to ``path`` atomically,
    streamed from the array (no copy of its bytes in memory); read it back with
    ``np.load(path, mmap_mode="r", allow_pickle=False)``. Errors as :func:`atomic_write_bytes`.
    """
    import numpy as np  # not at import: the CLI starts without NumPy

    arr = np.asarray(array)
    if arr.dtype.hasobject:
        raise TypeError("atomic_write_npy writes plain arrays only (no Python objects)")
    return atomic_write_bytes(
        path, lambda fh: np.lib.format.write_array(fh, arr, allow_pickle=False)
    )


def atomic_write_bytes(
    path: str | os.PathLike[str], data: bytes | Callable[[BinaryIO], object]
) -> Path:
    """Write ``data`` to ``path`` atomically; the folder is created if needed.

    ``data`` is the bytes, or a function that writes them to the open binary file.

    The bytes go to a fresh temporary name beside ``path``, are flushed to disk and
    renamed over ``path``. A ``path`` that is a symbolic link is refused, never followed.

    Raises
    ------
    OutputError
        ``path`` is a folder, a symbolic link or a device, or the folder cannot be created or the
        file cannot be written (one line naming the path and the system's reason).
    """
    target = Path(path)
    refuse_non_regular(target)
    make_folder(target.parent)
    tmp = temporary_sibling(target)
    try:
        _write_and_replace(tmp, data, target)
    except OSError as exc:
        discard(tmp)
        raise OutputError(target, f"cannot write: {os_reason(exc)}") from None
    _sync_folder(target.parent)
    return target


class AtomicTextFile:
    """A text file written piece by piece under another name, moved into place by :meth:`commit`.

    Parameters
    ----------
    path : path-like
        The finished file (its folder is created; a link or device there is refused).
    partial : path-like, optional
        Where the text goes until :meth:`commit` (default: a fresh hidden temporary name
        beside ``path``); it is opened without following a link.
    errors : str
        The encoder's error handler (``"surrogateescape"`` keeps undecodable file names).

    Every :class:`OSError` becomes a one-line :class:`OutputError` naming ``path``.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        partial: str | os.PathLike[str] | None = None,
        errors: str = "strict",
    ) -> None:
        self.path = Path(path)
        refuse_non_regular(self.path)
        make_folder(self.path.parent)
        self.partial = Path(partial) if partial is not None else temporary_sibling(self.path)
        flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0)
        try:
            fd = os.open(self.partial, flags, 0o644)
        except OSError as exc:
            raise OutputError(self.path, f"cannot write: {os_reason(exc)}") from None
        self._fh: TextIO | None = os.fdopen(fd, "w", encoding="utf-8", newline="", errors=errors)

    def write(self, text: str) -> int:
        """Append ``text`` (the ``write`` of a file object, so :func:`csv.writer` takes it)."""
        assert self._fh is not None, "written after commit or abort"
        try:
            return self._fh.write(text)
        except OSError as exc:
            raise OutputError(self.path, f"cannot write: {os_reason(exc)}") from None

    def flush(self) -> None:
        if self._fh is not None:
            try:
                self._fh.flush()
            except OSError as exc:
                raise OutputError(self.path, f"cannot write: {os_reason(exc)}") from None

    def commit(self) -> Path:
        """Flush to disk and rename onto ``path``; returns ``path``."""
        if self._fh is None:
            return self.path
        try:
            self._fh.flush()
            os.fsync(self._fh.fileno())
            self._fh.close()
            self._fh = None
            refuse_non_regular(self.path)
            os.replace(self.partial, self.path)
        except (OSError, InputError) as exc:
            self.abort()
            if isinstance(exc, InputError):
                raise
            raise OutputError(self.path, f"cannot write: {os_reason(exc)}") from None
        _sync_folder(self.path.parent)
        return self.path

    def close(self) -> None:
        """Stop writing and leave ``partial`` where it is (never raises)."""
        if self._fh is not None:
            try:
                self._fh.close()
            except OSError:
                pass
            self._fh = None

    def abort(self) -> None:
        """Stop writing and remove ``partial`` (never raises)."""
        self.close()
        discard(self.partial)


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """:func:`atomic_write_bytes` of ``text`` encoded as UTF-8."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def write_cache_entry(path: Path, data: bytes) -> InputError | None:
    """Write a cache entry atomically, first removing dead writers' temporaries in its folder.

    A cache only saves time, so a write that fails is returned, not raised: the caller
    reports it or goes on without the entry.
    """
    remove_dead_temporaries(path.parent)  # of runs killed while writing
    try:
        atomic_write_bytes(path, data)
    except InputError as exc:
        return exc
    return None


def unique_stems(paths: list[Path]) -> dict[Path, str]:
    """An output stem per input path, unique within ``paths``.

    A file's stem is used as it is when no other input shares it; inputs that share a
    stem (``a/x.png`` and ``b/x.png``, or ``x.png`` and ``x.jpg``) get
    ``<stem>-<first 8 hex digits of the SHA-256 of the input's absolute path>``, so their
    outputs never overwrite each other and the name is the same on every run.

    Examples
    --------
    >>> names = unique_stems([Path("a/x.png"), Path("b/x.png"), Path("y.png")])
    >>> names[Path("y.png")], names[Path("a/x.png")] != names[Path("b/x.png")]
    ('y', True)
    """
    import hashlib
    from collections import Counter

    counts = Counter(p.stem for p in paths)
    out: dict[Path, str] = {}
    for p in paths:
        if counts[p.stem] == 1:
            out[p] = p.stem
        else:
            digest = hashlib.sha256(os.fsencode(os.path.abspath(p))).hexdigest()[:8]
            out[p] = f"{p.stem}-{digest}"
    return out
