"""Resumable per-file batches: finished items are skipped on a re-run, never redone or lost.

``detect-shadows`` and ``detect-lanes`` write one or more files per input image. A
:class:`ResumableBatch` opens the output folder for one run at a time
(:class:`qdcnn.outputs.OutputFolder`: a second run waits or refuses), writes each item's
files atomically, then records the item in the folder's manifest with the input's
identity and a hash of every setting that changes the outputs. A re-run with the same
arguments skips the items whose record is complete and redoes the missing or stale ones
(``force`` redoes all), so a run killed at any point and started again ends with the same
files as an uninterrupted one.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from types import TracebackType
from typing import Any

from qdcnn.outputs import OutputFolder, config_hash, file_identity

__all__ = ["ResumableBatch"]


class ResumableBatch:
    """One run's view of an output folder and its manifest.

    Parameters
    ----------
    out : Path
        The output folder (created).
    settings : mapping
        Every setting that changes the outputs (hashed into each record).
    force : bool
        Redo items even when their record is complete.
    wait : float
        Seconds to wait for another run's lock before refusing.
    """

    def __init__(
        self, out: Path, settings: Mapping[str, Any], *, force: bool = False, wait: float = 0.0
    ) -> None:
        self.folder = OutputFolder(out, wait=wait)
        self.config = config_hash(settings)
        self.force = force
        self.skipped = 0

    def __enter__(self) -> ResumableBatch:
        self.folder.open()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.folder.close()

    def finished(self, key: str, source: Path) -> dict[str, Any] | None:
        """The recorded result of ``key`` when it is complete for this input and settings."""
        if self.force:
            return None
        identity = file_identity(source)
        if self.folder.manifest.status(key, identity, self.config) != "complete":
            return None
        entry = self.folder.manifest.get(key)
        if entry is None:
            return None
        self.skipped += 1
        return entry.result

    def record(
        self, key: str, source: Path, files: Mapping[str, bytes], result: Mapping[str, Any]
    ) -> dict[str, str]:
        """Write ``files`` (relative names to bytes) atomically, then record ``key`` as done.

        Returns the absolute path of each file written.
        """
        outputs = {rel: self.folder.write_bytes(rel, data) for rel, data in files.items()}
        self.folder.manifest.record(key, file_identity(source), self.config, outputs, result)
        return {rel: str(self.folder.path(rel)) for rel in files}
