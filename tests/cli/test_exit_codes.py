"""A named input path that is missing, of the wrong kind or unreadable: exit 2, one ``error:`` line.

Every command that takes an input path or a dataset spec is given a path that does not
exist, a folder where a file is needed (or a file where a folder is), a FIFO and a
dangling symbolic link. Each answer is exit status 2 with exactly one ``error:`` line on
stderr naming the path, before any work (nothing is written). Tests run as root, where
``chmod 000`` does not stop a read: the FIFO and the dangling link stand in for it, and the
``chmod`` case runs only for other users.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import pytest
from tests.cli.test_cli_commands import app, road, runner

from qdcnn.data.images import write_image

Args = Callable[[str, Path], list[str]]

#: Each command's arguments with the bad path put in, and what the path should be.
COMMANDS: dict[str, tuple[Args, str]] = {
    "detect-shadows": (lambda p, o: ["detect-shadows", p, "--out", str(o)], "file"),
    "detect-shadows --model": (
        lambda p, o: ["detect-shadows", str(o.parent / "img"), "--out", str(o), "--model", p],
        "file",
    ),
    "score-shadows --pred": (
        lambda p, o: ["score-shadows", "--pred", p, "--gt", str(o.parent / "img")],
        "folder",
    ),
    "score-shadows --gt": (
        lambda p, o: ["score-shadows", "--pred", str(o.parent / "img"), "--gt", p],
        "folder",
    ),
    "train-shadows": (lambda p, o: ["train-shadows", "--data", p, "--out", str(o)], "folder"),
    "evaluate": (lambda p, o: ["evaluate", "--data", f"udacity:{p}"], "file"),
    "evaluate carla": (lambda p, o: ["evaluate", "--data", f"carla:{p}"], "folder"),
    "evaluate --weights": (
        lambda p, o: ["evaluate", "--data", "synthetic:track1:10", "--weights", p],
        "file",
    ),
    "train-direction": (
        lambda p, o: ["train-direction", "--data", f"udacity:{p}", "--out", str(o)],
        "file",
    ),
    "train-direction --weights": (
        lambda p, o: [
            "train-direction", "--data", "synthetic:track1:10", "--out", str(o), "--weights", p,
        ],
        "file",
    ),
    "detect-lanes": (lambda p, o: ["detect-lanes", p, "--out", str(o)], "file"),
    "detect-lanes --model": (
        lambda p, o: ["detect-lanes", str(o.parent / "img"), "--out", str(o), "--model", p],
        "file",
    ),
    "noise-sweep": (lambda p, o: ["noise-sweep", "--data", f"udacity:{p}"], "file"),
    "circuit --model": (lambda p, o: ["circuit", "head", "--model", p], "file"),
    "run": (lambda p, o: ["run", p, "--out", str(o)], "file"),
    "run --model": (
        lambda p, o: ["run", "synthetic:track1:10", "--out", str(o), "--model", p],
        "file",
    ),
    "reproduce --data": (
        lambda p, o: ["reproduce", "--data", f"track1=udacity:{p}", "--out", str(o)],
        "file",
    ),
    "reproduce --shadow-set": (
        lambda p, o: ["reproduce", "--shadow-set", p, "--out", str(o)],
        "folder",
    ),
}


def _bad_path(kind: str, wanted: str, root: Path) -> Path:
    """A path of ``kind`` under ``root``: unusable where a ``wanted`` (file or folder) is needed."""
    if kind == "missing":
        return root / "nowhere.png"
    if kind == "wrong kind":
        if wanted == "file":
            (root / "a-folder.png").mkdir()
            return root / "a-folder.png"
        (root / "a-file.png").write_bytes(b"not a folder")
        return root / "a-file.png"
    if kind == "fifo":
        os.mkfifo(root / "pipe.png")
        return root / "pipe.png"
    if kind == "dangling link":
        (root / "link.png").symlink_to(root / "gone.png")
        return root / "link.png"
    raise AssertionError(kind)


def _assert_refused(args: list[str], bad: Path, out: Path) -> None:
    res = runner.invoke(app, args)
    errors = [line for line in res.stderr.splitlines() if line.startswith("error:")]
    assert res.exit_code == 2, res.output
    assert len(errors) == 1, res.stderr
    assert str(bad) in errors[0]
    assert not out.exists() or not any(out.iterdir())  # refused before any work


@pytest.mark.parametrize("kind", ["missing", "wrong kind", "fifo", "dangling link"])
@pytest.mark.parametrize("command", list(COMMANDS))
def test_an_unusable_input_path_is_exit_2_with_one_error_line(
    command: str, kind: str, tmp_path: Path
) -> None:
    args_for, wanted = COMMANDS[command]
    write_image(tmp_path / "img" / "a.png", road())
    bad = _bad_path(kind, wanted, tmp_path)
    out = tmp_path / "out"
    _assert_refused(args_for(str(bad), out), bad, out)


@pytest.mark.skipif(os.geteuid() == 0, reason="root reads files whatever their mode")
@pytest.mark.parametrize("command", ["detect-shadows", "detect-lanes", "evaluate --weights"])
def test_an_unreadable_file_is_exit_2(command: str, tmp_path: Path) -> None:
    locked = tmp_path / "locked.png"
    write_image(locked, road())
    locked.chmod(0)
    args_for, _ = COMMANDS[command]
    out = tmp_path / "out"
    _assert_refused(args_for(str(locked), out), locked, out)


def test_a_missing_path_among_good_ones_stops_the_batch_before_any_work(tmp_path: Path) -> None:
    write_image(tmp_path / "img" / "a.png", road())
    missing = tmp_path / "nowhere.png"
    out = tmp_path / "masks"
    args = ["detect-shadows", str(tmp_path / "img"), str(missing), "--out", str(out), "--exact"]
    _assert_refused(args, missing, out)
