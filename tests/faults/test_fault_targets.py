"""Outputs that are links, regular files, folders or devices, for every command that writes.

A file output (a model, a plot, a QASM file) that is a link (to a file, or dangling), a
folder or a device, or that lies below a regular file, is refused: exit 2, one ``error:``
line naming it, no traceback, and the link's target, the file or the device unchanged. An
output folder that is a regular file, a device or a dangling link is refused the same way.
Links planted in a finished output folder, at every file's name and in place of every
sub-folder, are never written through when the command writes the folder again: their
targets keep their bytes. The device is a null device made with ``mknod`` in the test's
folder (skipped where that is not permitted), never the machine's ``/dev/null``.
"""

from __future__ import annotations

import os
import shutil
import stat
from pathlib import Path

import pytest
from fault_support import (
    COMMANDS,
    DEMO,
    Command,
    Inputs,
    assert_one_error,
    build_inputs,
    error_lines,
    invoke,
    invoke_ok,
    make_null_device,
    output_path,
    snapshot,
    temporaries,
)

FILES = [c for c in COMMANDS if c.output == "file"]
FOLDERS = [*(c for c in COMMANDS if c.output == "folder"), DEMO]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Inputs:
    return build_inputs(tmp_path_factory)


def _victim(tmp_path: Path) -> Path:
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    return victim


@pytest.mark.parametrize("kind", ["link", "dangling link", "folder", "device", "below a file"])
@pytest.mark.parametrize("command", FILES, ids=lambda c: c.name)
def test_a_file_output_that_is_no_regular_file_is_refused(
    command: Command, kind: str, inputs: Inputs, tmp_path: Path
) -> None:
    victim = _victim(tmp_path)
    out = output_path(command, tmp_path / "outs")
    out.parent.mkdir()
    named = out
    if kind == "link":
        out.symlink_to(victim)
    elif kind == "dangling link":
        out.symlink_to(tmp_path / "nowhere")
    elif kind == "folder":
        out.mkdir()
    elif kind == "device":
        make_null_device(out)
    else:
        named = out.parent / "a-file"
        named.write_text("keep me")
        out = named / out.name
    before = snapshot(out.parent)
    line = assert_one_error(invoke(command.args(inputs, out)), 2, named)
    if "link" in kind:
        assert "is a symbolic link; qdcnn never writes through one" in line
    assert victim.read_text() == "keep me" and not (tmp_path / "nowhere").exists()
    assert snapshot(out.parent) == before and not temporaries(tmp_path)
    if kind == "device":
        assert stat.S_ISCHR(os.lstat(out).st_mode)


@pytest.mark.parametrize("kind", ["file", "device", "dangling link", "below a file"])
@pytest.mark.parametrize("command", FOLDERS, ids=lambda c: c.name)
def test_an_output_folder_that_is_no_folder_is_refused(
    command: Command, kind: str, inputs: Inputs, tmp_path: Path
) -> None:
    out = named = tmp_path / "out"
    if kind == "file":
        out.write_text("keep me")
    elif kind == "device":
        make_null_device(out)
    elif kind == "dangling link":
        out.symlink_to(tmp_path / "nowhere")
    else:
        named.write_text("keep me")
        out = named / "out"
    before = snapshot(tmp_path)
    res = invoke(command.args(inputs, out))
    assert_one_error(res, 2, named)
    assert res.stdout == ""
    assert snapshot(tmp_path) == before and not (tmp_path / "nowhere").exists()


def _plant_links(out: Path, victims: Path) -> None:
    """Replace every file of ``out`` by a link to a copy of it in ``victims``, then every
    sub-folder of ``out`` by a link to it, moved to ``victims``."""
    for path in [p for p in out.rglob("*") if p.is_file() and p.name != ".qdcnn.lock"]:
        copy = victims / "files" / path.relative_to(out)
        copy.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, copy)
        path.unlink()
        path.symlink_to(copy)
    (victims / "folders").mkdir()
    for path in [p for p in out.iterdir() if p.is_dir()]:
        moved = path.rename(victims / "folders" / path.name)
        path.symlink_to(moved, target_is_directory=True)


@pytest.mark.parametrize("command", [c for c in FOLDERS if c is not DEMO], ids=lambda c: c.name)
def test_links_planted_in_an_output_folder_are_never_written_through(
    command: Command, inputs: Inputs, tmp_path: Path
) -> None:
    out, victims = tmp_path / "out", tmp_path / "victims"
    invoke_ok(command.args(inputs, out))
    _plant_links(out, victims)
    planted = snapshot(victims)
    res = invoke([*command.args(inputs, out), *command.rewrite])
    assert "Traceback" not in res.output
    assert snapshot(victims) == planted  # no target was written, moved or removed
    assert not temporaries(tmp_path)
    if res.exit_code != 0:
        line = assert_one_error(res, 2, out)
        assert "is a symbolic link; qdcnn never writes through one" in line
    else:
        assert not error_lines(res.stderr)
