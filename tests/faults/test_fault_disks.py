"""Read-only and full file systems under every command that writes (real ``tmpfs`` mounts).

A command's finished outputs on a ``tmpfs`` are written again (``--force`` where the
command resumes) after the file system was filled to the last byte, then after it was
remounted read-only: each time exit 2, one ``error:`` line with the system's reason and no
traceback, every finished file byte for byte as it was, and no temporary file left
(``synth --force`` and ``reproduce --force`` empty the folder first, so a full disk meets
them as a new folder). A new output folder on a read-only or a full file system is refused
with one line, leaving no temporary file. Commands that write only the feature cache finish
with the same results when the cache cannot be written. The tests skip where mounting is
not permitted (they need root or CAP_SYS_ADMIN).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest
from fault_support import (
    COMMANDS,
    DEMO,
    Command,
    Inputs,
    assert_one_error,
    build_inputs,
    fill,
    invoke,
    invoke_ok,
    json_results,
    mounted_tmpfs,
    output_path,
    remount_read_only,
    snapshot,
    temporaries,
)

WRITERS = [c for c in COMMANDS if c.output != "cache"]
CACHE_ONLY = [c for c in COMMANDS if c.output == "cache"]
FOLDERS = [*(c for c in COMMANDS if c.output == "folder"), DEMO]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Inputs:
    return build_inputs(tmp_path_factory)


@pytest.mark.parametrize("command", WRITERS, ids=lambda c: c.name)
def test_finished_outputs_survive_a_full_then_a_read_only_disk(
    command: Command, inputs: Inputs, tmp_path: Path
) -> None:
    with mounted_tmpfs(tmp_path / "disk", "size=16m") as disk:
        out = output_path(command, disk)
        invoke_ok(command.args(inputs, out))
        finished = snapshot(out)
        assert finished
        args = [*command.args(inputs, out), *command.rewrite]
        if not command.empties:  # these meet a full disk as a new folder: see below
            filler = fill(disk)
            line = assert_one_error(invoke(args), 2, disk)
            assert "no space left on device" in line
            assert snapshot(out) == finished and not temporaries(disk)
            filler.unlink()
        remount_read_only(disk)
        line = assert_one_error(invoke(args), 2, disk)
        assert "read-only file system" in line
        assert snapshot(out) == finished


@pytest.mark.parametrize("command", FOLDERS, ids=lambda c: c.name)
def test_a_new_output_folder_on_a_read_only_disk_is_refused(
    command: Command, inputs: Inputs, tmp_path: Path
) -> None:
    with mounted_tmpfs(tmp_path / "disk", "ro") as disk:
        res = invoke(command.args(inputs, disk / "out"))
        line = assert_one_error(res, 2, disk / "out")
        assert "read-only file system" in line and res.stdout == ""
        assert not any(disk.iterdir())


@pytest.mark.parametrize("command", FOLDERS, ids=lambda c: c.name)
def test_a_new_output_folder_on_a_full_disk_is_one_error(
    command: Command, inputs: Inputs, tmp_path: Path
) -> None:
    with mounted_tmpfs(tmp_path / "disk", "size=64k") as disk:
        fill(disk)
        line = assert_one_error(invoke(command.args(inputs, disk / "out")), 2, disk / "out")
        assert "no space left on device" in line
        assert not temporaries(disk)


@pytest.mark.parametrize("options", ["ro", "size=4k"])
@pytest.mark.parametrize("command", CACHE_ONLY, ids=lambda c: c.name)
def test_an_unwritable_cache_changes_no_result(
    command: Command, options: str, inputs: Inputs, tmp_path: Path
) -> None:
    args = command.args(inputs, tmp_path)
    expected = invoke_ok(args, cache=tmp_path / "cache")
    with mounted_tmpfs(tmp_path / "disk", options) as disk:
        if options != "ro":
            fill(disk)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            res = invoke(args, cache=disk / "cache")
        assert res.exit_code == 0 and "Traceback" not in res.output, res.output
        assert not [line for line in res.stderr.splitlines() if line.startswith("error:")]
        told = [res.stderr, *(str(w.message) for w in caught)]
        assert any(str(disk / "cache") in text for text in told)  # the cache is named
        assert json_results(res.stdout) == json_results(expected.stdout)
        assert not temporaries(disk)
