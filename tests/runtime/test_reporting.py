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


class Recorded:
    """Lines every 10 seconds of a fake clock, kept in ``lines``; no heartbeat thread (the
    script calls ``beat`` itself)."""

    def __init__(self) -> None:
        self.clock = FakeClock()
        self.lines: list[str] = []

    def play(self, total: int, description: str, script: str) -> list[str]:
        """Run ``script`` inside the progress: ``+N`` moves the clock N seconds, ``advance``,
        ``beat``, ``pause``, ``resume`` call those; ``raise`` raises RuntimeError."""
        progress = ProgressLines(
            total, description, self.lines.append, interval=10, clock=self.clock, heartbeat=False
        )
        with progress:
            for word in script.split():
                if word.startswith("+"):
                    self.clock.now += float(word)
                elif word == "raise":
                    raise RuntimeError("boom")
                else:
                    getattr(progress, word)()
        return self.lines


def test_steps_print_at_most_one_line_per_interval() -> None:
    assert Recorded().play(25, "lane features (x)", "+1 advance " * 25) == [
        "progress: lane features (x): 0/25, 0.0 s",
        "progress: lane features (x): 10/25, 10.0 s",
        "progress: lane features (x): 20/25, 20.0 s",
        "progress: lane features (x): 25/25, done in 25.0 s",
    ]


def test_the_heartbeat_repeats_the_last_state_only_once_an_interval_has_passed() -> None:
    # too early at 9 s; at 10 s a line, and none again until 10 s later
    lines = Recorded().play(3, "fit", "advance +9 beat +1 beat beat +10 beat")
    assert lines[1:] == [
        "progress: fit: 1/3, 10.0 s",
        "progress: fit: 1/3, 20.0 s",
        "progress: fit: 1/3, done in 20.0 s",
    ]


def test_a_paused_outer_piece_of_work_keeps_quiet_until_resumed() -> None:
    # resumed: the next line an interval from then
    lines = Recorded().play(2, "outer", "pause +30 beat resume beat +10 beat")
    assert lines == [
        "progress: outer: 0/2, 0.0 s",
        "progress: outer: 0/2, 40.0 s",
        "progress: outer: 0/2, done in 40.0 s",
    ]


def test_work_that_raises_ends_with_stopped_after() -> None:
    log = Recorded()
    with pytest.raises(RuntimeError):
        log.play(4, "sweep", "advance +2.5 raise")
    assert log.lines[-1] == "progress: sweep: 1/4, stopped after 2.5 s"


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
