"""Where tasks run: in this process, on a local Dask cluster, or on a scheduler address."""

from __future__ import annotations

import os
import signal
import socket
import sys
import time
from pathlib import Path

import pytest

from qdcnn.errors import InputError, MissingExtraError, ParameterError
from qdcnn.runtime.scheduler import Executor, TaskFailure, parse_scheduler


def square_or_fail(x: int, offset: int) -> int:
    if x == 3:
        raise InputError(f"item{x}", "cannot be squared")
    if x == 4:
        raise FileNotFoundError(2, "No such file or directory", f"item{x}.bin")
    return x * x + offset


def square_killing_once(x: int, marker: str) -> int:
    """Kills the worker running it the first time it sees x == 5."""
    if x == 5 and not os.path.exists(marker):
        Path(marker).write_text("killed\n")
        os.kill(os.getpid(), signal.SIGKILL)
    time.sleep(0.05)
    return x * x


def test_scheduler_specs_are_checked() -> None:
    assert parse_scheduler(None) == ("in-process", None)
    assert parse_scheduler("none") == ("in-process", None)
    assert parse_scheduler("local:3") == ("local", 3)
    assert parse_scheduler("local")[0] == "local"
    assert parse_scheduler("tcp://10.0.0.7:8786") == ("remote", "tcp://10.0.0.7:8786")
    for bad in ("local:0", "local:x", "tcp//host", "http://host:1", "", "cluster"):
        with pytest.raises(ParameterError, match=f"scheduler={bad!r} is invalid"):
            Executor(bad)


def test_in_process_runs_in_order_and_turns_qdcnn_and_os_errors_into_failures() -> None:
    with Executor() as ex:
        got = list(ex.map_unordered(square_or_fail, range(6), 10))
        assert ex.in_process and ex.workers == 1
    assert [t for t, _ in got] == list(range(6))
    assert [r for _, r in got if not isinstance(r, TaskFailure)] == [10, 11, 14, 35]
    failures = {t: r for t, r in got if isinstance(r, TaskFailure)}
    assert failures[3] == TaskFailure("item3: cannot be squared", "InputError")
    assert failures[4].error == "item4.bin: No such file or directory"
    assert ex.stats.tasks == 6 and ex.stats.failures == 2
    assert ex.stats.overhead_per_task is not None and ex.stats.overhead_per_task >= 0


def test_programming_errors_are_not_hidden() -> None:
    with Executor() as ex, pytest.raises(ZeroDivisionError):
        list(ex.map_unordered(lambda x: 1 // x, [1, 0]))


def test_without_the_extra_a_scheduler_names_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "distributed", None)  # import fails as if not installed
    with pytest.raises(MissingExtraError, match=r"pip install 'qdcnn\[dask\]'"):
        Executor("local:2")
    with pytest.raises(MissingExtraError, match="distributed"):
        Executor("tcp://127.0.0.1:8786")
    with Executor(None) as ex:  # in-process needs nothing
        assert [r for _, r in ex.map_unordered(square_or_fail, [2], 0)] == [4]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_an_address_where_no_scheduler_answers_fails_within_the_timeout() -> None:
    pytest.importorskip("distributed")
    address = f"tcp://127.0.0.1:{_free_port()}"
    t0 = time.monotonic()
    with pytest.raises(InputError) as info:
        Executor(address, timeout=1.5)
    assert time.monotonic() - t0 < 6
    assert str(info.value).startswith(f"{address}: no Dask scheduler answered within 1.5 s")


@pytest.mark.slow
@pytest.mark.usefixtures("busy_cpu")
def test_local_cluster_gives_the_in_process_results_even_when_a_worker_dies(
    tmp_path: Path,
) -> None:
    pytest.importorskip("distributed")
    marker = str(tmp_path / "killed.txt")
    with Executor() as ex:
        expected = sorted(ex.map_unordered(square_or_fail, range(8), 1), key=repr)
    with Executor("local:2", timeout=60) as ex:
        assert ex.workers == 2 and not ex.in_process
        got = sorted(ex.map_unordered(square_or_fail, range(8), 1), key=repr)
        assert got == expected
        survived = dict(ex.map_unordered(square_killing_once, range(12), marker))
        assert Path(marker).exists()  # a worker really was killed mid-job
        assert survived == {x: x * x for x in range(12)}
        overhead = ex.measure_overhead(50)
        assert 0 < overhead < 1.0
