"""Printed messages are escaped (square brackets in them survive); progress off a terminal
is plain lines on stderr, and ``--quiet`` drops progress and notes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from qdcnn.cli import app
from qdcnn.cli._common import err, report_error, report_note
from qdcnn.data.images import write_image


@pytest.mark.parametrize(
    "message",
    ["frame[left].png: empty file (0 bytes)", "needs torch: pip install 'qdcnn[dnn]'"],
)
def test_brackets_in_messages_are_printed_as_written(message: str) -> None:
    with err.capture() as capture:
        report_error(message)
        report_note(message)
    assert capture.get() == f"error: {message}\nnote: {message}\n"


def test_quiet_leaves_out_progress_and_notes_but_not_errors(monkeypatch) -> None:
    from qdcnn.batch import Failure
    from qdcnn.cli._common import CliReporter

    monkeypatch.setenv("QDCNN_PROGRESS_INTERVAL", "0.01")
    reporter = CliReporter(False, quiet=True)
    with err.capture() as capture:
        reporter.note("left out on purpose")
        with reporter.progress(3, "work") as advance:
            advance()
        reporter.failure(Failure("a.png", "a.png: empty file (0 bytes)"))
    assert capture.get() == "error: a.png: empty file (0 bytes)\n"


def test_off_a_terminal_progress_is_plain_lines_and_nested_work_prints_its_own(
    monkeypatch,
) -> None:
    from rich.console import Console

    from qdcnn.cli._common import CliReporter

    monkeypatch.setattr(Console, "is_terminal", property(lambda self: False))
    reporter = CliReporter(False)
    with err.capture() as capture:
        with reporter.progress(2, "sections") as section_done:
            with reporter.progress(5, "lane features [x]") as frame_done:
                for _ in range(5):
                    frame_done()
            section_done()
            section_done()
    lines = capture.get().splitlines()
    assert [line.rsplit(",", 1)[0] for line in lines] == [
        "progress: sections: 0/2",
        "progress: lane features [x]: 0/5",
        "progress: lane features [x]: 5/5",
        "progress: sections: 2/2",
    ]
    assert lines[2].endswith(" s") and "done in" in lines[2]


runner = CliRunner()


@pytest.mark.parametrize("quiet", [False, True])
def test_progress_lines_on_stderr_unless_quiet(quiet: bool, tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("QDCNN_PROGRESS_INTERVAL", "0.001")
    rng = np.random.default_rng(0)
    for name in ("a.png", "b.png"):
        write_image(tmp_path / name, rng.integers(0, 255, (64, 96, 3), dtype=np.uint8))
    args = ["detect-shadows", str(tmp_path / "a.png"), str(tmp_path / "b.png")]
    args += ["--out", str(tmp_path / "o"), "--exact"] + (["--quiet"] if quiet else [])
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.stderr
    progress = [line for line in res.stderr.splitlines() if line.startswith("progress: ")]
    if quiet:
        assert progress == []
    else:
        assert progress[0] == "progress: detect-shadows uu: 0/2, 0.0 s"
        assert progress[-1].startswith("progress: detect-shadows uu: 2/2, done in ")
    assert sorted(p.name for p in (tmp_path / "o").glob("*_mask.png")) == [
        "a_mask.png",
        "b_mask.png",
    ]


def test_a_damaged_feature_cache_entry_is_one_note_line(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    args = ["evaluate", "--data", "synthetic:track1:120", "--folds", "2", "--inner-folds", "0"]
    args += ["--method", "image-split-uu", "--quiet"]
    runner.invoke(app, args)
    entries = list((tmp_path / "cache").glob("features-*.npz"))
    assert entries
    for entry in entries:
        entry.write_bytes(b"junk")
    res = runner.invoke(app, args)
    notes = [line for line in res.stderr.splitlines() if "feature cache entry" in line]
    assert len(notes) == len(entries) and all(n.startswith("note: ") for n in notes), res.stderr
    assert "FeatureCacheWarning" not in res.stderr and ".py:" not in res.stderr


def test_another_package_s_warning_is_one_note_line_with_its_category() -> None:
    import warnings

    from qdcnn.cli._common import warnings_as_notes

    with err.capture() as capture, warnings_as_notes():
        warnings.warn("it converged slowly", RuntimeWarning, stacklevel=1)
    assert capture.get() == "note: RuntimeWarning: it converged slowly\n"
