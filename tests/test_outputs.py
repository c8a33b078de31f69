"""Crash-safe output folders: the lock, writes that never follow links, the manifest."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from qdcnn.errors import InputError, ParameterError
from qdcnn.outputs import (
    LOCK_NAME,
    Manifest,
    OutputFolder,
    OutputLockedError,
    OutputRecord,
    config_hash,
    file_identity,
)

SRC = Path(__file__).resolve().parents[1] / "src"

HOLDER = textwrap.dedent(
    """
    import sys, time
    sys.path.insert(0, {src!r})
    from qdcnn.outputs import OutputFolder
    with OutputFolder({root!r}) as folder:
        folder.write_text("held.txt", "held\\n")
        print("locked", flush=True)
        time.sleep(float(sys.argv[1]))
    print("released", flush=True)
    """
)


def _hold(root: Path, seconds: float) -> subprocess.Popen[str]:
    """Another process holding the folder's lock; returns once it holds it."""
    code = HOLDER.format(src=str(SRC), root=str(root))
    proc = subprocess.Popen(
        [sys.executable, "-c", code, str(seconds)], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None and proc.stdout.readline().strip() == "locked"
    return proc


def test_a_second_process_is_refused_at_once_naming_the_folder(tmp_path: Path) -> None:
    proc = _hold(tmp_path / "out", 30)
    try:
        t0 = time.monotonic()
        with pytest.raises(OutputLockedError) as info:
            OutputFolder(tmp_path / "out").open()
        assert time.monotonic() - t0 < 1.0
        message = str(info.value)
        assert message.startswith(f"{tmp_path / 'out'}: another qdcnn run is writing")
        assert "\n" not in message and LOCK_NAME in message
    finally:
        proc.kill()
        proc.wait()


def test_a_waiting_run_gets_the_folder_when_the_other_finishes(tmp_path: Path) -> None:
    proc = _hold(tmp_path / "out", 0.8)
    t0 = time.monotonic()
    with OutputFolder(tmp_path / "out", wait=20) as folder:
        waited = time.monotonic() - t0
        assert folder.read_bytes("held.txt") == b"held\n"
    proc.wait()
    assert 0.3 < waited < 15


def test_waiting_has_a_limit_and_kill_9_releases_the_lock(tmp_path: Path) -> None:
    proc = _hold(tmp_path / "out", 60)
    try:
        t0 = time.monotonic()
        with pytest.raises(OutputLockedError, match=r"\(waited 0.5 s\)"):
            OutputFolder(tmp_path / "out", wait=0.5).open()
        assert 0.4 < time.monotonic() - t0 < 3
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        with OutputFolder(tmp_path / "out") as folder:  # the kernel dropped the dead lock
            assert folder.is_open
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_files_are_written_atomically_and_temporaries_of_dead_runs_removed(
    tmp_path: Path,
) -> None:
    stale = tmp_path / "sub" / ".frames.csv.0123456789ab.tmp"
    stale.parent.mkdir(parents=True)
    stale.write_text("half a file")
    keep = tmp_path / "sub" / ".hidden-but-mine"
    keep.write_text("x")
    with OutputFolder(tmp_path) as folder:
        assert not stale.exists() and keep.exists()
        record = folder.write_text("sub/deeper/a.txt", "hello\n")
        assert record == OutputRecord.of(b"hello\n")
        assert (tmp_path / "sub" / "deeper" / "a.txt").read_text() == "hello\n"
        assert folder.size_of("sub/deeper/a.txt") == 6
        record = folder.write_file("v/x.bin", lambda p: p.write_bytes(b"\0" * 10))
        assert record.size == 10 and folder.read_bytes("v/x.bin") == b"\0" * 10
        assert sorted(p.name for p in (tmp_path / "v").iterdir()) == ["x.bin"]
        folder.remove("sub/deeper/a.txt")
        folder.remove("sub/deeper/a.txt")  # missing is fine
        assert folder.read_bytes("sub/deeper/a.txt") is None
        with pytest.raises(ParameterError, match="a relative path inside the output folder"):
            folder.write_text("../escape.txt", "no")
        with pytest.raises(ParameterError):
            folder.write_text("/etc/passwd", "no")
    assert not (tmp_path.parent / "escape.txt").exists()


def test_links_are_never_followed(tmp_path: Path) -> None:
    outside = tmp_path / "outside"
    outside.mkdir()
    victim = outside / "victim.txt"
    victim.write_text("precious")
    root = tmp_path / "out"
    root.mkdir()
    (root / "linked").symlink_to(outside, target_is_directory=True)
    (root / "file.txt").symlink_to(victim)
    with OutputFolder(root) as folder:
        with pytest.raises(InputError, match=r"linked: is a symbolic link; qdcnn never writes"):
            folder.write_text("linked/victim.txt", "overwritten")
        folder.write_text("file.txt", "replaced the link\n")  # the link itself is replaced
        assert folder.read_bytes("linked/victim.txt") is None
        assert folder.size_of("linked/victim.txt") is None
    assert victim.read_text() == "precious"
    assert not (root / "file.txt").is_symlink()
    assert (root / "file.txt").read_text() == "replaced the link\n"


def test_an_unusable_folder_gets_one_line_errors(tmp_path: Path) -> None:
    (tmp_path / "a-file").write_text("x")
    with pytest.raises(InputError, match="cannot create or open the output folder"):
        OutputFolder(tmp_path / "a-file" / "out").open()
    with pytest.raises(ParameterError, match="wait=-1 is invalid"):
        OutputFolder(tmp_path, wait=-1)
    folder = OutputFolder(tmp_path)
    with pytest.raises(ParameterError, match="opened"):
        folder.write_text("a.txt", "not locked yet")


def _record(folder: OutputFolder, key: str, text: str, cfg: str = "cfg1") -> None:
    out = {f"{key}.txt": folder.write_text(f"{key}.txt", text)}
    folder.manifest.record(key, {"input": key}, cfg, out, {"rows": len(text)})


def test_manifest_says_complete_missing_or_stale(tmp_path: Path) -> None:
    with OutputFolder(tmp_path) as folder:
        m = folder.manifest
        assert m.status("a", {"input": "a"}, "cfg1") == "missing"
        _record(folder, "a", "alpha\n")
        assert m.status("a", {"input": "a"}, "cfg1") == "complete"
        assert m.get("a") is not None and m.get("a").result == {"rows": 6}  # type: ignore[union-attr]
        assert m.status("a", {"input": "a"}, "cfg2") == "stale"  # other settings
        assert m.status("a", {"input": "b"}, "cfg1") == "stale"  # other input
        (tmp_path / "a.txt").write_text("alpha, longer\n")
        assert m.status("a", {"input": "a"}, "cfg1") == "stale"  # output changed size
        (tmp_path / "a.txt").write_text("ALPHA\n")
        assert m.status("a", {"input": "a"}, "cfg1") == "complete"
        assert m.status("a", {"input": "a"}, "cfg1", verify="hash") == "stale"
        (tmp_path / "a.txt").unlink()
        assert m.status("a", {"input": "a"}, "cfg1") == "missing"
        m.forget("a")
        assert m.get("a") is None


def test_a_torn_or_foreign_manifest_entry_counts_as_missing(tmp_path: Path) -> None:
    with OutputFolder(tmp_path) as folder:
        _record(folder, "a", "alpha\n")
        entry = tmp_path / Manifest.entry_name("a")
        full = entry.read_bytes()
        entry.write_bytes(full[: len(full) // 2])  # what a non-atomic write could leave
        assert folder.manifest.status("a", {"input": "a"}, "cfg1") == "missing"
        entry.write_bytes(full.replace(b'"key": "a"', b'"key": "b"'))
        assert folder.manifest.get("a") is None


def test_identity_and_config_hash_are_stable(tmp_path: Path) -> None:
    f = tmp_path / "in.bin"
    f.write_bytes(b"12345")
    a = file_identity(f, content_hash=True)
    assert a["size"] == 5 and a["path"] == str(f.resolve()) and len(a["sha256"]) == 64
    assert config_hash({"b": (1, 2), "a": Path("x")}) == config_hash({"a": "x", "b": [1, 2]})
    assert config_hash({"a": 1}) != config_hash({"a": 2})
    with pytest.raises(InputError, match="cannot read"):
        file_identity(tmp_path / "missing")


def test_an_output_folder_in_an_input_folder_is_refused(tmp_path: Path) -> None:
    from qdcnn.outputs import refuse_output_in_inputs

    frames = tmp_path / "frames"
    frames.mkdir()
    video = tmp_path / "drive.mp4"
    video.write_bytes(b"x")
    with pytest.raises(InputError, match="is the input folder"):
        refuse_output_in_inputs(frames, [video, frames])
    with pytest.raises(InputError, match="lies inside the input folder"):
        refuse_output_in_inputs(frames / "out" / "deeper", [frames])
    link = tmp_path / "link"
    link.symlink_to(frames)
    with pytest.raises(InputError, match="is the input folder"):
        refuse_output_in_inputs(link, [frames])
    refuse_output_in_inputs(tmp_path / "out", [frames, video])  # beside: fine
    refuse_output_in_inputs(tmp_path, [video])  # a video's folder may hold the outputs


def test_a_dangling_link_is_named_a_broken_symbolic_link(tmp_path: Path) -> None:
    link = tmp_path / "frame.png"
    link.symlink_to(tmp_path / "gone.png")
    with pytest.raises(InputError, match=r"frame\.png: cannot read: a broken symbolic link"):
        file_identity(link)
