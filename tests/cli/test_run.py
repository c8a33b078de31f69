"""qdcnn run and synth --video: a real video file end to end, resumable, with one-line errors."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from qdcnn.cli import app

pytest.importorskip("av")
runner = CliRunner()


def json_lines(text: str) -> list[dict]:
    return [json.loads(line) for line in text.splitlines() if line.strip()]


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("synth")
    res = runner.invoke(
        app,
        [
            "synth",
            "--preset",
            "track2",
            "--n",
            "24",
            "--video",
            "--layout",
            "udacity",
            "--out",
            str(out),
        ],
    )
    assert res.exit_code == 0, res.stderr
    return out / "video" / "track2.mp4"


def test_run_a_video_then_resume_without_redoing_work(drive: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = ["run", str(drive), "--out", str(out), "--chunk", "10", "--smooth", "3", "--json"]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.stderr
    first, summary = json_lines(res.stdout)
    assert first["frames"] == 24 and first["frames_per_second"] > 0 and first["seconds"] > 0
    assert summary["summary"] and summary["frames"] == 24
    assert summary["processor"]["method"] in summary["model"]  # the record names what decided
    assert json.loads((out / "summary.json").read_text())["processor"] == summary["processor"]
    frames_csv = (out / "track2" / "frames.csv").read_bytes()
    assert frames_csv.count(b"\n") == 25 and (out / "track2" / "overlay.mp4").stat().st_size > 0
    again = runner.invoke(app, args)
    assert again.exit_code == 0, again.stderr
    resumed = json_lines(again.stdout)[0]
    assert resumed["chunks_skipped"] == 3 and resumed["frames_processed"] == 0
    assert (out / "track2" / "frames.csv").read_bytes() == frames_csv


def test_run_a_dataset_spec_without_video(tmp_path: Path) -> None:
    res = runner.invoke(
        app, ["run", "synthetic:track1:12", "--out", str(tmp_path), "--no-video", "--json"]
    )
    assert res.exit_code == 0, res.stderr
    assert json_lines(res.stdout)[0]["frames"] == 12
    assert not (tmp_path / "synthetic-track1" / "overlay.mp4").exists()


def test_frames_csv_has_the_same_columns_with_and_without_smooth(tmp_path: Path) -> None:
    headers = []
    for smooth in ("1", "3"):
        out = tmp_path / smooth
        args = ["run", "synthetic:track1:10", "--out", str(out), "--no-video", "--smooth", smooth]
        assert runner.invoke(app, args).exit_code == 0
        rows = (out / "synthetic-track1" / "frames.csv").read_text().splitlines()
        headers.append(rows[0])
        if smooth == "1":  # no vote: the raw decision is the decision
            raw = [r.split(",")[2:4] for r in rows[1:]]
            assert all(direction == direction_raw for direction, direction_raw in raw)
    assert headers[0] == headers[1] and "direction,direction_raw" in headers[0]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["nowhere.mp4"], "nowhere.mp4: file not found"),
        (["synthetic:mars"], "data='synthetic:mars' is invalid"),
        (["x.mp4", "--smooth", "0"], "smooth=0 is invalid"),
        (["x.mp4", "--method", "best"], "method='best' is invalid"),
    ],
)
def test_bad_inputs_are_one_line_errors(args: list[str], message: str, tmp_path: Path) -> None:
    res = runner.invoke(app, ["run", *args, "--out", str(tmp_path / "o")])
    assert res.exit_code == 2, res.output
    assert message in res.stderr and len(res.stderr.strip().splitlines()) <= 2


def test_a_scheduler_that_does_not_answer_fails_fast(drive: Path, tmp_path: Path) -> None:
    pytest.importorskip("distributed")
    t0 = time.perf_counter()
    res = runner.invoke(
        app, ["run", str(drive), "--out", str(tmp_path), "--scheduler", "tcp://127.0.0.1:9"]
    )
    assert res.exit_code == 2 and "127.0.0.1:9" in res.stderr
    assert time.perf_counter() - t0 < 60


def test_failed_inputs_get_an_error_line_and_the_others_finish(drive: Path, tmp_path: Path) -> None:
    broken = tmp_path / "broken.mp4"
    broken.write_bytes(drive.read_bytes()[:2000])
    out = tmp_path / "run"
    res = runner.invoke(app, ["run", str(drive), str(broken), "--out", str(out), "--no-video"])
    assert res.exit_code == 1, res.output
    errors = [line for line in res.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and "broken.mp4: not a readable video" in errors[0]
    assert (out / "track2" / "frames.csv").read_bytes().count(b"\n") == 25


def test_bad_rows_and_files_of_a_recording_are_frames_with_one_error_line_each(
    tmp_path: Path,
) -> None:
    rec = tmp_path / "rec"
    res = runner.invoke(app, ["synth", "--n", "8", "--layout", "udacity", "--out", str(rec)])
    assert res.exit_code == 0, res.output
    log = rec / "driving_log.csv"
    lines = log.read_text().splitlines()
    for k, steering in ((2, "abc"), (4, "")):
        fields = lines[k].split(",")
        fields[3] = steering
        lines[k] = ",".join(fields)
    log.write_text("\n".join(lines) + "\n")
    empty = lines[6].split(",")[0].strip()
    Path(empty).write_bytes(b"")
    out = tmp_path / "run"
    args = ["run", f"udacity:{rec}", "--out", str(out), "--no-video", "--quiet"]
    res = runner.invoke(app, args)
    assert res.exit_code == 1, res.output
    frames = (out / "rec" / "frames.csv").read_bytes()
    rows = frames.decode().splitlines()[1:]
    assert [int(r.split(",")[0]) for r in rows] == list(range(8))  # the recording's rows
    status = [r.split(",")[-2] for r in rows]
    assert status == ["ok", "ok", "bad-row", "ok", "bad-row", "ok", "unreadable", "ok"]
    errors = res.stderr.splitlines()
    assert len(errors) == 3 and all(e.startswith("error: ") for e in errors), res.stderr
    assert "frame 2: " in errors[0] and "driving_log.csv:row 3: steering 'abc'" in errors[0]
    assert "frame 4: " in errors[1] and "driving_log.csv:row 5: steering ''" in errors[1]
    assert "frame 6: " in errors[2] and "empty file (0 bytes)" in errors[2]
    again = runner.invoke(app, args)  # resumed: the same rows, lines and exit status
    assert again.exit_code == 1 and again.stderr == res.stderr
    assert (out / "rec" / "frames.csv").read_bytes() == frames
    fresh = runner.invoke(app, [*args[:3], str(tmp_path / "fresh"), *args[4:]])
    assert (
        fresh.exit_code == 1 and (tmp_path / "fresh" / "rec" / "frames.csv").read_bytes() == frames
    )
