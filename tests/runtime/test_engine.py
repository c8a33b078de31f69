"""The chunked video runner: outputs, smoothing, resuming after kill -9, bad input, Dask."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from video_fakes import BatchHalvesProcessor, HalvesProcessor, ListSource, clip_frame, write_clip

from qdcnn.data.images import write_image
from qdcnn.data.video import VideoReader
from qdcnn.errors import InputError, ParameterError
from qdcnn.outputs import OutputFolder, OutputLockedError
from qdcnn.runtime.chunks import majority_vote
from qdcnn.runtime.engine import Progress, RunOptions, run_inputs
from qdcnn.runtime.manifest import FRAMES_CSV

pytest.importorskip("av")

SRC = Path(__file__).resolve().parents[2] / "src"
HERE = Path(__file__).resolve().parent
N, CHUNK, SMOOTH = 50, 8, 3
OPTIONS = RunOptions(chunk_frames=CHUNK, smooth=SMOOTH)


@pytest.fixture(scope="module")
def clip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_clip(tmp_path_factory.mktemp("clips") / "drive.mp4", N)


@pytest.fixture(scope="module")
def reference(clip: Path, tmp_path_factory: pytest.TempPathFactory) -> bytes:
    """frames.csv of one uninterrupted run."""
    out = tmp_path_factory.mktemp("reference")
    result = run_inputs([clip], HalvesProcessor(), out, options=OPTIONS)
    assert result.ok
    return (out / "drive" / FRAMES_CSV).read_bytes()


def _rows(data: bytes) -> list[dict[str, str]]:
    return list(csv.DictReader(data.decode().splitlines()))


def test_a_run_writes_rows_in_frame_order_an_overlay_and_a_summary(
    clip: Path, reference: bytes, tmp_path: Path
) -> None:
    seen: list[Progress] = []
    result = run_inputs([clip], HalvesProcessor(), tmp_path, options=OPTIONS, progress=seen.append)
    folder = tmp_path / "drive"
    assert (folder / FRAMES_CSV).read_bytes() == reference
    rows = _rows(reference)
    assert list(rows[0]) == [
        "frame", "timestamp", "direction", "direction_raw", "p_left", "p_straight", "p_right",
        "shadow_fraction", "lane_status", "status", "note",
    ]  # fmt: skip
    assert [int(r["frame"]) for r in rows] == list(range(N))
    assert np.allclose([float(r["timestamp"]) for r in rows], np.arange(N) / 10.0)
    sums = [sum(float(r[f"p_{c}"]) for c in ("left", "straight", "right")) for r in rows]
    assert np.allclose(sums, 1.0, atol=1e-5)
    timings = list(csv.DictReader((folder / "timings.csv").read_text().splitlines()))
    assert [int(t["frame"]) for t in timings] == list(range(N))
    assert all(float(t["process_ms"]) >= 0 and float(t["overlay_ms"]) > 0 for t in timings)
    with VideoReader(folder / "overlay.mp4") as overlay:
        assert len(overlay) == N and overlay.info.width == 64
        assert np.allclose([f.timestamp for f in overlay], np.arange(N) / 10.0, atol=1e-4)
    summary = json.loads((tmp_path / "summary.json").read_text())
    entry = summary["inputs"][0]
    assert summary["ok"] and summary["frames"] == N and summary["timing"] == "measured"
    assert summary["processor"] == HalvesProcessor().settings()  # what decided, on record
    assert entry["frames"] == N and entry["chunks"] == 7 and entry["decoder"] == "pyav"
    assert entry["frames_per_second"] > 0 and entry["first_bad_frame"] is None
    assert sum(entry["directions"].values()) == N
    assert result.to_dict()["inputs"][0]["frames"] == N
    assert seen[-1] == Progress("drive", N, N)
    assert [p.done for p in seen] == sorted(p.done for p in seen)
    assert not (folder / ".chunks").exists()


def test_decisions_do_not_depend_on_chunking_and_smoothing_is_a_trailing_vote(
    clip: Path, reference: bytes, tmp_path: Path
) -> None:
    run_inputs([clip], HalvesProcessor(), tmp_path / "one", options=RunOptions(smooth=SMOOTH))
    assert (tmp_path / "one" / "drive" / FRAMES_CSV).read_bytes() == reference
    rows = _rows(reference)
    raw = [r["direction_raw"] for r in rows]
    assert len(set(raw)) >= 2
    for i, r in enumerate(rows):
        assert r["direction"] == majority_vote(raw[max(0, i - SMOOTH + 1) : i + 1])
    assert sum(r["direction"] != r["direction_raw"] for r in rows) > 0  # the vote acted
    run_inputs([clip], HalvesProcessor(), tmp_path / "raw", options=RunOptions(chunk_frames=5))
    plain = _rows((tmp_path / "raw" / "drive" / FRAMES_CSV).read_bytes())
    assert list(plain[0]) == list(rows[0])  # the same columns with and without --smooth
    assert [r["direction"] for r in plain] == raw == [r["direction_raw"] for r in plain]


def test_a_re_run_skips_finished_work_and_redoes_missing_or_stale_work(
    clip: Path, reference: bytes, tmp_path: Path
) -> None:
    run_inputs([clip], HalvesProcessor(), tmp_path, options=OPTIONS)
    again = run_inputs([clip], HalvesProcessor(), tmp_path, options=OPTIONS).inputs[0]
    assert (again.frames_processed, again.chunks_skipped, again.frames) == (0, 7, N)
    (tmp_path / "drive" / "overlay.mp4").unlink()
    redone = run_inputs([clip], HalvesProcessor(), tmp_path, options=OPTIONS).inputs[0]
    assert redone.frames_processed == N and (tmp_path / "drive" / "overlay.mp4").exists()
    changed = run_inputs([clip], HalvesProcessor(version=2), tmp_path, options=OPTIONS)
    assert changed.inputs[0].frames_processed == N  # another processor setting: stale
    force = RunOptions(chunk_frames=CHUNK, smooth=SMOOTH, force=True)
    forced = run_inputs([clip], HalvesProcessor(version=2), tmp_path, options=force)
    assert forced.inputs[0].frames_processed == N
    assert (tmp_path / "drive" / FRAMES_CSV).read_bytes() == reference
    os.utime(clip)  # the input changed (modification time): everything is redone
    touched = run_inputs([clip], HalvesProcessor(version=2), tmp_path, options=OPTIONS)
    assert touched.inputs[0].frames_processed == N


KILLED_RUN = textwrap.dedent(
    """
    import os, signal, sys
    sys.path[:0] = [{src!r}, {here!r}]
    from video_fakes import HalvesProcessor
    from qdcnn.runtime.engine import RunOptions, run_inputs

    mode, n = sys.argv[1], int(sys.argv[2])
    calls = [0]
    if mode in ("replace", "fsync"):
        real = getattr(os, mode)

        def dying(*args, **kwargs):
            calls[0] += 1
            if calls[0] == n:
                os.kill(os.getpid(), signal.SIGKILL)
            return real(*args, **kwargs)

        setattr(os, mode, dying)

    def progress(p):
        print(p.done, flush=True)

    options = RunOptions(chunk_frames={chunk}, smooth={smooth})
    run_inputs([{clip!r}], HalvesProcessor(), {out!r}, options=options, progress=progress)
    print("finished", calls[0], flush=True)
    """
)


def _killed_run(clip: Path, out: Path, mode: str, n: int) -> subprocess.CompletedProcess[str]:
    code = KILLED_RUN.format(
        src=str(SRC), here=str(HERE), chunk=CHUNK, smooth=SMOOTH, clip=str(clip), out=str(out)
    )
    return subprocess.run(
        [sys.executable, "-c", code, mode, str(n)], capture_output=True, text=True, timeout=120
    )


def _check_nothing_truncated(out: Path, reference: bytes) -> None:
    """Every file under its final name is complete (atomic writes), whatever was killed."""
    for path in out.rglob("*"):
        if not path.is_file() or path.name.startswith("."):
            continue
        if path.name == FRAMES_CSV:
            assert path.read_bytes() == reference
        elif path.name == "overlay.mp4":
            with VideoReader(path) as overlay:
                assert len(overlay) == N and not overlay.info.truncated
        elif path.suffix == ".json":
            json.loads(path.read_text())
        elif path.suffix == ".csv":
            assert path.read_text().endswith("\n")


def _resume_and_compare(clip: Path, out: Path, reference: bytes) -> None:
    result = run_inputs([clip], HalvesProcessor(), out, options=OPTIONS)
    assert result.ok and (out / "drive" / FRAMES_CSV).read_bytes() == reference
    with VideoReader(out / "drive" / "overlay.mp4") as overlay:
        assert len(overlay) == N
    leftovers = [p for p in out.rglob("*") if ".tmp" in p.name or p.name == ".chunks"]
    assert leftovers == []


def test_kill_9_at_every_kind_of_point_then_resume_gives_identical_output(
    clip: Path, reference: bytes, tmp_path: Path
) -> None:
    full = _killed_run(clip, tmp_path / "count", "replace", 10**9)
    assert full.returncode == 0, full.stderr
    renames = int(full.stdout.split()[-1])  # atomic renames of one whole run
    assert renames >= 7 * 4 + 4
    points = sorted({1, 3, renames // 2, renames - 2, renames - 1, renames})
    for k in points:
        out = tmp_path / f"replace{k}"
        proc = _killed_run(clip, out, "replace", k)
        assert proc.returncode == -9, (k, proc.stderr[-2000:])
        _check_nothing_truncated(out, reference)
        _resume_and_compare(clip, out, reference)
    out = tmp_path / "fsync"  # killed inside a write: data on disk, not yet renamed
    assert _killed_run(clip, out, "fsync", 5).returncode == -9  # 3rd file, before its rename
    assert any(".tmp" in p.name for p in out.rglob("*"))
    _check_nothing_truncated(out, reference)
    _resume_and_compare(clip, out, reference)


def test_kill_9_from_outside_mid_chunk_twice_then_resume(
    clip: Path, reference: bytes, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    code = KILLED_RUN.format(
        src=str(SRC), here=str(HERE), chunk=CHUNK, smooth=SMOOTH, clip=str(clip), out=str(out)
    )
    for stop_after in (13, 37):  # frames done when the kill is sent (mid-chunk both times)
        proc = subprocess.Popen(
            [sys.executable, "-c", code, "none", "0"], stdout=subprocess.PIPE, text=True
        )
        assert proc.stdout is not None
        for line in proc.stdout:
            if line.strip().isdigit() and int(line) >= stop_after:
                proc.kill()  # SIGKILL to this one process
                break
        proc.wait(timeout=60)
        assert proc.returncode == -9
        _check_nothing_truncated(out, reference)
    resumed = run_inputs([clip], HalvesProcessor(), out, options=OPTIONS).inputs[0]
    assert 0 < resumed.chunks_skipped < 7 and resumed.frames_processed < N
    assert (out / "drive" / FRAMES_CSV).read_bytes() == reference


def test_corrupt_video_keeps_every_frame_row_and_reports_the_first_bad_one(
    clip: Path, tmp_path: Path
) -> None:
    data = bytearray(clip.read_bytes())
    k = len(data) // 2
    data[k : k + 1500] = bytes(1500)
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(bytes(data))
    result = run_inputs([bad, clip], HalvesProcessor(), tmp_path / "out", options=OPTIONS)
    broken, fine = result.inputs
    assert fine.ok and not broken.ok and not result.ok
    assert broken.first_bad_frame is not None and 0 < broken.first_bad_frame < N
    rows = _rows((tmp_path / "out" / "bad" / FRAMES_CSV).read_bytes())
    assert [int(r["frame"]) for r in rows] == list(range(N))
    errors = [int(r["frame"]) for r in rows if r["lane_status"] == "error"]
    assert errors and errors[0] == broken.first_bad_frame
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["n_failed"] == 1 and summary["inputs"][0]["first_bad_frame"] == errors[0]


def test_bad_inputs_are_reported_and_the_others_processed(clip: Path, tmp_path: Path) -> None:
    empty = tmp_path / "empty.mp4"
    empty.write_bytes(b"")
    folder = tmp_path / "frames"
    for i in range(5):
        write_image(folder / f"f{i:02d}.png", np.full((48, 64, 3), 40 * i, np.uint8))
    (folder / "f02.png").write_bytes(b"not a png")
    result = run_inputs(
        [empty, folder, clip, ListSource(9)],
        HalvesProcessor(fail_at=(4,)),
        tmp_path / "out",
        options=OPTIONS,
    )
    by_name = {r.name: r for r in result.inputs}
    assert by_name["empty"].error == f"{empty}: empty file (0 bytes)"
    images = by_name["frames"]
    assert images.frames == 5 and [b[0] for b in images.bad_frames] == [2, 4]
    rows = _rows((tmp_path / "out" / "frames" / FRAMES_CSV).read_bytes())
    assert [r["timestamp"] for r in rows] == [""] * 5  # image folders have no timestamps
    assert [r["lane_status"] for r in rows].count("error") == 2
    memory = _rows((tmp_path / "out" / "memory" / FRAMES_CSV).read_bytes())
    assert np.allclose([float(r["timestamp"]) for r in memory], np.arange(9) * 0.05)
    assert by_name["drive"].bad_frames == [(4, "frame 4: cannot be processed")]
    with pytest.raises(InputError, match="file not found"):
        run_inputs([tmp_path / "nope.mp4"], HalvesProcessor(), tmp_path / "o2")
    with pytest.raises(InputError, match="not a video file or folder"):
        run_inputs([tmp_path / "out" / "summary.json"], HalvesProcessor(), tmp_path / "o3")
    with pytest.raises(ParameterError, match="processor='int' is invalid"):
        run_inputs([clip], 3, tmp_path / "o4")  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="smooth=0 is invalid"):
        RunOptions(smooth=0)


def test_bad_files_and_rows_are_frames_with_a_status_and_never_renumbered(tmp_path: Path) -> None:
    from qdcnn.data.frames import load_frameset

    folder = tmp_path / "frames"
    for i in range(6):
        write_image(folder / f"f{i:02d}.png", np.full((48, 64, 3), 40 * i, np.uint8))
    (folder / "f01.png").unlink()
    (folder / "f01.png").symlink_to(tmp_path / "gone.png")  # a dangling link
    (folder / "f02.png").write_bytes(b"")
    (folder / "f03.png").write_bytes(b"not a png")
    rec = tmp_path / "rec"
    for i in range(4):
        write_image(rec / "IMG" / f"c{i}.png", clip_frame(i))
    steering = ["0.1", "abc", "", "0.2"]
    lines = [f"IMG/c{i}.png, , , {s}, 0, 0, 1" for i, s in enumerate(steering)]
    (rec / "driving_log.csv").write_text("\n".join(lines) + "\n")
    recording = load_frameset(f"udacity:{rec}").in_recording_order()
    processor = HalvesProcessor(fail_at=(5,))
    out = tmp_path / "out"
    result = run_inputs([folder, recording], processor, out, options=OPTIONS)
    images = _rows((out / "frames" / FRAMES_CSV).read_bytes())
    assert [int(r["frame"]) for r in images] == list(range(6))  # the folder's order, all kept
    assert [r["status"] for r in images] == [
        "ok",
        "unreadable",
        "unreadable",
        "unreadable",
        "ok",
        "failed",
    ]
    assert "f01.png: file not found (a broken symbolic link)" in images[1]["note"]
    assert "f02.png: empty file (0 bytes)" in images[2]["note"]
    assert images[0]["note"] == "" and images[5]["note"] == "frame 5: cannot be processed"
    rows = _rows((out / "rec" / FRAMES_CSV).read_bytes())
    assert [r["status"] for r in rows] == ["ok", "bad-row", "bad-row", "ok"]
    assert rows[1]["note"].endswith("driving_log.csv:row 2: steering 'abc' is not a number")
    assert rows[1]["direction"] == "" and rows[3]["direction"] != ""
    by_name = {r.name: r for r in result.inputs}
    assert [i for i, _ in by_name["frames"].bad_frames] == [1, 2, 3, 5]
    assert [i for i, _ in by_name["rec"].bad_frames] == [1, 2] and not result.ok
    again = run_inputs([folder, recording], processor, out, options=OPTIONS)
    assert [r.bad_frames for r in again.inputs] == [r.bad_frames for r in result.inputs]
    assert all(r.chunks_skipped == r.chunks for r in again.inputs)


def test_odd_sized_video_gets_a_padded_overlay(tmp_path: Path) -> None:
    av = pytest.importorskip("av")
    path = tmp_path / "odd.mkv"
    with av.open(str(path), "w") as c:
        s = c.add_stream("ffv1", rate=10)
        s.width, s.height, s.pix_fmt = 33, 21, "bgr0"
        for i in range(12):
            img = np.ascontiguousarray(np.resize(np.arange(256, dtype=np.uint8), (21, 33, 3)))
            frame = av.VideoFrame.from_ndarray(img, format="rgb24").reformat(format="bgr0")
            frame.pts = i
            for p in s.encode(frame):
                c.mux(p)
        for p in s.encode():
            c.mux(p)
    result = run_inputs([path], HalvesProcessor(), tmp_path / "out", options=OPTIONS)
    assert result.ok and result.inputs[0].frames == 12
    assert result.inputs[0].to_dict()["video"]["overlay_padded_to"] == [34, 22]
    with VideoReader(tmp_path / "out" / "odd" / "overlay.mp4") as overlay:
        assert (overlay.info.width, overlay.info.height, len(overlay)) == (34, 22, 12)


def test_two_runs_into_one_folder_do_not_mix(clip: Path, tmp_path: Path) -> None:
    holder = subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(f"""
            import sys, time
            sys.path.insert(0, {str(SRC)!r})
            from qdcnn.outputs import OutputFolder
            with OutputFolder({str(tmp_path)!r}):
                print("locked", flush=True)
                time.sleep(30)
        """)],
        stdout=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "locked"
        with pytest.raises(OutputLockedError, match="another qdcnn run is writing"):
            run_inputs([clip], HalvesProcessor(), tmp_path, options=OPTIONS)
        assert not (tmp_path / "drive").exists()
    finally:
        holder.kill()
        holder.wait()
    with OutputFolder(tmp_path):
        pass


def test_a_batch_processor_gets_batches_and_gives_the_same_rows(
    clip: Path, reference: bytes, tmp_path: Path
) -> None:
    batched = BatchHalvesProcessor(fail_at=(9,))
    result = run_inputs([clip], batched, tmp_path / "b", options=OPTIONS)
    single = run_inputs([clip], HalvesProcessor(fail_at=(9,)), tmp_path / "s", options=OPTIONS)
    assert max(batched.batches) > 1 and sum(batched.batches) >= N
    assert (
        result.inputs[0].bad_frames
        == single.inputs[0].bad_frames
        == [(9, "frame 9: cannot be processed")]
    )
    a = (tmp_path / "b" / "drive" / FRAMES_CSV).read_bytes()
    assert a == (tmp_path / "s" / "drive" / FRAMES_CSV).read_bytes()


def test_the_lane_pipeline_processor_gives_each_frame_its_own_result(tmp_path: Path) -> None:
    from qdcnn.data.synthetic import iter_drive
    from qdcnn.data.writers import write_video
    from qdcnn.direction.processor import LaneDirectionProcessor

    processor = LaneDirectionProcessor.train("image-split-uu", data="synthetic:track1:80")
    path = write_video(iter_drive("track2", 20, seed=3), tmp_path / "drive.mp4")
    result = run_inputs([path], processor, tmp_path / "out", options=RunOptions(chunk_frames=8))
    assert result.ok and result.inputs[0].frames == 20
    rows = _rows((tmp_path / "out" / "drive" / FRAMES_CSV).read_bytes())
    with VideoReader(path) as reader:
        frames = list(reader)
    for row, frame in zip(rows, frames, strict=True):
        alone = processor.process(frame.image, frame.index)
        assert row["direction"] == alone.direction and row["lane_status"] == alone.lane_status
        assert float(row["shadow_fraction"]) == pytest.approx(alone.shadow_fraction, abs=1e-6)
        assert alone.probabilities is not None
        assert float(row["p_left"]) == pytest.approx(alone.probabilities[0], abs=1e-6)
    assert {r["lane_status"] for r in rows} <= {"ok", "one-line", "no-lines"}
    assert 0 < np.mean([float(r["shadow_fraction"]) for r in rows]) < 1
    drawn = processor.draw(frames[0].image, processor.process(frames[0].image, 0), "left")
    assert drawn.shape == frames[0].image.shape and not np.array_equal(drawn, frames[0].image)
    assert processor.settings() == LaneDirectionProcessor(processor.model).settings()


@pytest.mark.slow
@pytest.mark.usefixtures("busy_cpu")
def test_local_cluster_with_a_killed_worker_gives_identical_output(
    clip: Path, reference: bytes, tmp_path: Path
) -> None:
    pytest.importorskip("distributed")
    from qdcnn.runtime.scheduler import Executor

    alone = tmp_path / "alone"
    run_inputs([clip], HalvesProcessor(), alone, options=OPTIONS)
    with Executor("local:2", timeout=60) as ex:
        # the first task's first frame (its worker may hold the only computed copy of the
        # shared processor and sources), mid-run, and in the last chunks
        for kill_at in (0, 21, 45):
            marker = tmp_path / f"killed-at-{kill_at}.txt"
            processor = HalvesProcessor(kill_at=kill_at, marker=str(marker))
            out, seen = tmp_path / f"out-{kill_at}", list[Progress]()
            result = run_inputs(
                [clip], processor, out, options=OPTIONS, executor=ex, progress=seen.append
            )
            assert marker.exists() and result.ok, kill_at  # a worker died; the job finished
            for name in (FRAMES_CSV, "overlay.mp4"):
                assert (out / "drive" / name).read_bytes() == (alone / "drive" / name).read_bytes()
            assert (out / "drive" / FRAMES_CSV).read_bytes() == reference
            assert result.executor["kind"] == "local" and result.executor["workers"] == 2
            assert seen[-1] == Progress("drive", N, N)


def test_without_pyav_opencv_decodes_encodes_and_joins(
    clip: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import qdcnn._optional
    import qdcnn.data.video

    for module in (qdcnn._optional, qdcnn.data.video):
        monkeypatch.setattr(module, "has_module", lambda name: name != "av")
    result = run_inputs([clip], HalvesProcessor(), tmp_path, options=OPTIONS)
    entry = result.inputs[0]
    assert result.ok and entry.decoder == "opencv" and entry.frames == N
    rows = _rows((tmp_path / "drive" / FRAMES_CSV).read_bytes())
    assert [int(r["frame"]) for r in rows] == list(range(N))
    with VideoReader(tmp_path / "drive" / "overlay.mp4", decoder="opencv") as overlay:
        assert len(overlay) == N and overlay.info.codec.lower() in ("mp4v", "fmp4")
