"""The output folder's manifest: a run's per-input ledger and the per-file batches."""

from __future__ import annotations

from pathlib import Path

from qdcnn.outputs import OutputFolder
from qdcnn.runtime.manifest import InputLedger, ResumableBatch, chunk_files


def test_a_ledger_records_chunks_and_final_files_and_forgets_chunks(tmp_path: Path) -> None:
    ledger = InputLedger("drive", {"kind": "video", "size": 3}, "config")
    rows, timings, video = chunk_files("drive", 2)
    assert (rows, timings, video) == (
        "drive/.chunks/00002.rows.csv",
        "drive/.chunks/00002.timings.csv",
        "drive/.chunks/00002.mp4",
    )
    with OutputFolder(tmp_path) as folder:
        assert not ledger.chunk_is_complete(folder, 2, 16, 24)
        outputs = {rows: folder.write_text(rows, "16,left\n")}
        ledger.record_chunk(folder, 2, (16, 24), outputs, {"frames": 8})
        assert ledger.chunk_is_complete(folder, 2, 16, 24)
        assert not ledger.chunk_is_complete(folder, 2, 16, 23)  # another span: stale
        other = InputLedger("drive", ledger.identity, "another config")
        assert not other.chunk_is_complete(folder, 2, 16, 24)
        entry = ledger.chunk_entry(folder, 2)
        assert entry is not None and entry.result == {"frames": 8}
        assert ledger.finished(folder) is None
        final = {"drive/frames.csv": folder.write_text("drive/frames.csv", "frame\n")}
        ledger.record_final(folder, final, {"frames": 8})
        assert ledger.finished(folder) == {"frames": 8}
        (tmp_path / "drive" / "frames.csv").write_text("frame,more\n")
        assert ledger.finished(folder) is None  # a final file of another size: stale
        ledger.forget_chunk(folder, 2)
        assert ledger.chunk_entry(folder, 2) is None and not (tmp_path / rows).exists()


def test_a_resumable_batch_skips_recorded_items_unless_stale_or_forced(tmp_path: Path) -> None:
    source, out = tmp_path / "in.png", tmp_path / "out"
    source.write_bytes(b"image")
    with ResumableBatch(out, {"threshold": 1}) as batch:
        assert batch.finished("in", source) is None
        paths = batch.record("in", source, {"in.mask.png": b"mask"}, {"score": 1})
        assert Path(paths["in.mask.png"]).read_bytes() == b"mask"
    with ResumableBatch(out, {"threshold": 1}) as batch:
        assert batch.finished("in", source) == {"score": 1} and batch.skipped == 1
    with ResumableBatch(out, {"threshold": 2}) as batch:
        assert batch.finished("in", source) is None  # another setting
    with ResumableBatch(out, {"threshold": 1}, force=True) as batch:
        assert batch.finished("in", source) is None
