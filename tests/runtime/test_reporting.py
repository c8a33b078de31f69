"""Plain progress lines: at the start, at most one per interval, a heartbeat, at the end."""

from __future__ import annotations

import time

import pytest

from qdcnn.runtime.reporting import PROGRESS_INTERVAL, ProgressLines, progress_interval


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_steps_print_at_most_one_line_per_interval() -> None:
    clock, lines = FakeClock(), []
    with ProgressLines(
        25, "lane features (x)", lines.append, interval=10, clock=clock, heartbeat=False
    ) as p:
        for _ in range(25):
            clock.now += 1.0
            p.advance()
    assert lines == [
        "progress: lane features (x): 0/25, 0.0 s",
        "progress: lane features (x): 10/25, 10.0 s",
        "progress: lane features (x): 20/25, 20.0 s",
        "progress: lane features (x): 25/25, done in 25.0 s",
    ]


def test_the_heartbeat_repeats_the_last_state_only_once_an_interval_has_passed() -> None:
    clock, lines = FakeClock(), []
    with ProgressLines(3, "fit", lines.append, interval=10, clock=clock, heartbeat=False) as p:
        p.advance()
        clock.now += 9.0
        p.beat()  # too early: nothing
        clock.now += 1.0
        p.beat()
        p.beat()  # nothing new to wait for yet
        clock.now += 10.0
        p.beat()
    assert lines[1:] == [
        "progress: fit: 1/3, 10.0 s",
        "progress: fit: 1/3, 20.0 s",
        "progress: fit: 1/3, done in 20.0 s",
    ]


def test_a_paused_outer_piece_of_work_keeps_quiet_until_resumed() -> None:
    clock, lines = FakeClock(), []
    with ProgressLines(2, "outer", lines.append, interval=10, clock=clock, heartbeat=False) as p:
        p.pause()
        clock.now += 30.0
        p.beat()
        p.resume()
        p.beat()  # resumed: the next line an interval from now
        clock.now += 10.0
        p.beat()
    assert lines == [
        "progress: outer: 0/2, 0.0 s",
        "progress: outer: 0/2, 40.0 s",
        "progress: outer: 0/2, done in 40.0 s",
    ]


def test_work_that_raises_ends_with_stopped_after() -> None:
    clock, lines = FakeClock(), []
    with pytest.raises(RuntimeError):
        with ProgressLines(4, "sweep", lines.append, clock=clock, heartbeat=False) as p:
            p.advance()
            clock.now += 2.5
            raise RuntimeError("boom")
    assert lines[-1] == "progress: sweep: 1/4, stopped after 2.5 s"


def test_the_heartbeat_thread_prints_while_a_step_never_advances() -> None:
    lines: list[str] = []
    with ProgressLines(1, "one long fit", lines.append, interval=0.01):
        deadline = time.monotonic() + 30
        while len(lines) < 4 and time.monotonic() < deadline:
            time.sleep(0.01)
    assert len(lines) >= 5  # the start, at least three heartbeats, the end
    assert all(line.startswith("progress: one long fit: 0/1, ") for line in lines[:-1])
    assert lines[-1].startswith("progress: one long fit: 0/1, done in ")


@pytest.mark.parametrize(
    ("value", "seconds"),
    [
        ("", PROGRESS_INTERVAL),
        ("0.5", 0.5),
        ("0", PROGRESS_INTERVAL),
        ("x", PROGRESS_INTERVAL),
        ("inf", PROGRESS_INTERVAL),
        ("nan", PROGRESS_INTERVAL),
    ],
)
def test_the_interval_comes_from_the_environment(value: str, seconds: float, monkeypatch) -> None:
    monkeypatch.setenv("QDCNN_PROGRESS_INTERVAL", value)
    assert progress_interval() == seconds
