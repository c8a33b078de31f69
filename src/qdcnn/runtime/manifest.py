"""The output folder's layout and its manifest of finished work, which a re-run skips.

Everything a run writes goes through :class:`qdcnn.outputs.OutputFolder`: files are
written atomically, then recorded in the folder's manifest with the input's identity and
a hash of every setting that changes the outputs. A re-run with the same arguments skips
the work whose record is complete and redoes the missing or stale rest, so a run killed at
any point and started again ends with the same files as an uninterrupted one.

Two kinds of record:

:class:`InputLedger`
    One input of :func:`qdcnn.runtime.engine.run_inputs`: an entry per finished chunk
    (``<name>/chunk-NNNNN``, its files under ``<name>/.chunks/``) and one for the final
    files (``<name>/final``).
:class:`ResumableBatch`
    ``detect-shadows`` and ``detect-lanes``: one entry per input image (``force`` redoes
    all).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from qdcnn._closing import ClosesOnExit
from qdcnn.outputs import ManifestEntry, OutputFolder, OutputRecord, config_hash, file_identity

__all__ = [
    "CHUNK_DIR",
    "FRAMES_CSV",
    "OVERLAY",
    "SUMMARY",
    "TIMINGS_CSV",
    "InputLedger",
    "ResumableBatch",
    "chunk_files",
]

FRAMES_CSV, TIMINGS_CSV, OVERLAY, SUMMARY = (
    "frames.csv",
    "timings.csv",
    "overlay.mp4",
    "summary.json",
)
#: Per input, the folder of finished chunks' files until the final files are assembled.
CHUNK_DIR = ".chunks"


def chunk_files(name: str, chunk: int) -> tuple[str, str, str]:
    """Rows, timings and overlay segment of chunk ``chunk`` of input ``name``."""
    base = f"{name}/{CHUNK_DIR}/{chunk:05d}"
    return f"{base}.rows.csv", f"{base}.timings.csv", f"{base}.mp4"


@dataclass(frozen=True)
class InputLedger:
    """One input's entries in the manifest: each finished chunk, and the final files.

    ``identity`` names the input's contents (a changed input makes every entry stale) and
    ``config`` hashes the settings that change its outputs.
    """

    name: str
    identity: dict[str, Any]
    config: str

    def chunk_key(self, chunk: int) -> str:
        return f"{self.name}/chunk-{chunk:05d}"

    @property
    def final_key(self) -> str:
        return f"{self.name}/final"

    def chunk_identity(self, start: int, stop: int) -> dict[str, Any]:
        return {**self.identity, "start": start, "stop": stop}

    def chunk_is_complete(self, folder: OutputFolder, chunk: int, start: int, stop: int) -> bool:
        """Whether chunk ``chunk`` (frames ``start`` to ``stop - 1``) is recorded and intact."""
        status = folder.manifest.status(
            self.chunk_key(chunk), self.chunk_identity(start, stop), self.config
        )
        return status == "complete"

    def chunk_entry(self, folder: OutputFolder, chunk: int) -> ManifestEntry | None:
        return folder.manifest.get(self.chunk_key(chunk))

    def record_chunk(
        self,
        folder: OutputFolder,
        chunk: int,
        span: tuple[int, int],
        outputs: Mapping[str, OutputRecord],
        summary: Mapping[str, Any],
    ) -> None:
        """Record chunk ``chunk`` (frames ``span[0]`` to ``span[1] - 1``) as finished."""
        identity = self.chunk_identity(*span)
        folder.manifest.record(self.chunk_key(chunk), identity, self.config, outputs, summary)

    def finished(self, folder: OutputFolder) -> dict[str, Any] | None:
        """The saved result of the final files when they are recorded and intact."""
        if folder.manifest.status(self.final_key, self.identity, self.config) != "complete":
            return None
        entry = folder.manifest.get(self.final_key)
        assert entry is not None
        return entry.result

    def record_final(
        self, folder: OutputFolder, outputs: Mapping[str, OutputRecord], saved: Mapping[str, Any]
    ) -> None:
        folder.manifest.record(self.final_key, self.identity, self.config, outputs, saved)

    def forget_chunk(self, folder: OutputFolder, chunk: int) -> None:
        """Drop chunk ``chunk``'s entry and its files."""
        folder.manifest.forget(self.chunk_key(chunk))
        for rel in chunk_files(self.name, chunk):
            folder.remove(rel)


class ResumableBatch(ClosesOnExit):
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

    def close(self) -> None:
        """Release the output folder (its lock)."""
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
