"""Two commands writing into one output folder at once: one is refused, the other finishes.

The first command runs in a forked copy of the test process; once it holds the folder's
lock (its pid is in ``.qdcnn.lock``) it is stopped with SIGSTOP, so the second one meets
the lock whatever the machine's load. The second exits 2 with one ``error:`` line naming
the folder and writes nothing; the first, continued, exits 0 with outputs equal to an
undisturbed run's. Two commands sharing one feature cache both finish with equal results.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest
from fault_support import (
    BY_NAME,
    COMMANDS,
    Inputs,
    assert_one_error,
    assert_whole,
    build_inputs,
    fork_command,
    invoke,
    invoke_ok,
    json_results,
    outputs_of,
    snapshot,
)

FOLDERS = [c for c in COMMANDS if c.output == "folder"]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Inputs:
    return build_inputs(tmp_path_factory)


def _stop_once_locked(pid: int, out: Path, timeout: float = 300) -> None:
    """SIGSTOP ``pid`` as soon as ``out/.qdcnn.lock`` holds its pid (it holds the lock)."""
    lock, deadline = out / ".qdcnn.lock", time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            if lock.read_text().strip() == str(pid):
                os.kill(pid, signal.SIGSTOP)
                return
        except OSError:
            pass
        assert os.waitpid(pid, os.WNOHANG) == (0, 0), "the first command ended before the test"
        time.sleep(0.001)
    raise AssertionError("the first command never took the lock")


def _exit_code(pid: int) -> int:
    os.kill(pid, signal.SIGCONT)
    _, status = os.waitpid(pid, 0)
    return os.waitstatus_to_exitcode(status)


SECOND = [*(c.name for c in FOLDERS), "detect-lanes into detect-shadows' folder"]


@pytest.mark.parametrize("second", SECOND)
def test_a_second_command_into_a_locked_folder_is_refused(
    second: str, inputs: Inputs, tmp_path: Path
) -> None:
    first = BY_NAME["detect-shadows"] if second.startswith("detect-lanes into") else None
    other = BY_NAME["detect-lanes"] if first else BY_NAME[second]
    first = first or other
    invoke_ok(first.args(inputs, tmp_path / "ref"), cache=tmp_path / "cache")
    reference = outputs_of(first, tmp_path / "ref", tmp_path)
    out = tmp_path / "out"
    pid = fork_command(first.args(inputs, out), cache=tmp_path / "cache")
    try:
        _stop_once_locked(pid, out)
        before = snapshot(out)
        res = invoke(other.args(inputs, out), cache=tmp_path / "cache")
        line = assert_one_error(res, 2, out)
        assert "another qdcnn run is writing to this folder" in line and res.stdout == ""
        assert snapshot(out) == before  # the refused command wrote nothing
    finally:
        code = _exit_code(pid)
    assert code == 0
    got = outputs_of(first, out, tmp_path)
    assert set(got) == set(reference)
    assert_whole(first, got, reference)


def test_two_commands_sharing_a_cache_both_finish(inputs: Inputs, tmp_path: Path) -> None:
    evaluate, cache = BY_NAME["evaluate"], tmp_path / "cache"
    expected = invoke_ok(evaluate.args(inputs, tmp_path), cache=tmp_path / "ref-cache")
    pid = fork_command(evaluate.args(inputs, tmp_path), cache=cache)
    res = invoke_ok(evaluate.args(inputs, tmp_path), cache=cache)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    assert json_results(res.stdout) == json_results(expected.stdout)
    again = invoke_ok(evaluate.args(inputs, tmp_path), cache=cache)  # from the shared cache
    assert json_results(again.stdout) == json_results(expected.stdout)
