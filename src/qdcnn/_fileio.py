"""Crash-safe file writes: a unique temporary name in the target's folder, then a rename.

A reader never sees a half-written file: the bytes go to ``.<name>.<random>.tmp``
beside the target, are flushed to disk, and :func:`os.replace` puts them in place
in one step. A rename replaces a symbolic link at the target path itself, so a
pre-made link is never followed and its target never overwritten.
"""

from __future__ import annotations

import os
import secrets
from pathlib import Path

from qdcnn.errors import InputError


def temporary_sibling(path: Path) -> Path:
    """A fresh, unique temporary name in ``path``'s folder (hidden, ``.tmp`` suffix)."""
    return path.with_name(f".{path.name}.{secrets.token_hex(6)}.tmp")


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; the folder is created if needed.

    Raises
    ------
    InputError
        The folder cannot be created or the file cannot be written (naming ``path``).
    """
    target = Path(path)
    if target.is_dir() and not target.is_symlink():
        raise InputError(target, "is a directory, not a file to write")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(target.parent, f"cannot create folder: {exc.strerror or exc}") from None
    tmp = temporary_sibling(target)
    try:
        fd = os.open(
            tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o644
        )
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise InputError(target, f"cannot write: {exc.strerror or exc}") from None
    return target


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """:func:`atomic_write_bytes` of ``text`` encoded as UTF-8."""
    return atomic_write_bytes(path, text.encode("utf-8"))


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
