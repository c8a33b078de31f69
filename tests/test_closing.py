"""The with-block mixins: what leaving the block calls."""

from __future__ import annotations

import pytest

from qdcnn._closing import ClosesOnExit, FinishesOnExit


class _Resource(ClosesOnExit):
    def __init__(self) -> None:
        self.calls: list[str] = []

    def close(self) -> None:
        self.calls.append("close")


class _Output(FinishesOnExit):
    def __init__(self) -> None:
        self.calls: list[str] = []

    def close(self) -> str:
        self.calls.append("close")
        return "done"

    def abort(self) -> None:
        self.calls.append("abort")


def test_closes_on_exit_closes_after_success_and_after_an_error() -> None:
    with _Resource() as ok:
        pass
    assert ok.calls == ["close"]
    failed = _Resource()
    with pytest.raises(RuntimeError), failed as entered:
        assert entered is failed
        raise RuntimeError("boom")
    assert failed.calls == ["close"]


def test_finishes_on_exit_closes_after_success_and_aborts_after_an_error() -> None:
    with _Output() as ok:
        pass
    assert ok.calls == ["close"]
    failed = _Output()
    with pytest.raises(RuntimeError), failed:
        raise RuntimeError("boom")
    assert failed.calls == ["abort"]
