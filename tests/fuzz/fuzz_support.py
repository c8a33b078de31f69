"""Shared pieces of the fuzz suite: the settings profile, example counts and a hang guard.

The profile ``qdcnn-fuzz`` is registered in ``tests/conftest.py`` (fixed seed, no
example database, 20 s deadline per example). ``QDCNN_FUZZ_SCALE`` multiplies every
test's example count; a long run::

    QDCNN_FUZZ_SCALE=20 python -m pytest -q tests/fuzz
"""

from __future__ import annotations

import signal
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

import pytest

hypothesis = pytest.importorskip("hypothesis")

from conftest import FUZZ_SCALE  # noqa: E402

#: Seconds after which one example counts as hung (the deadline only reports slow ones).
HANG_SECONDS = 60


def fuzz_settings(examples: int) -> hypothesis.settings:
    """The ``qdcnn-fuzz`` profile with ``examples`` (times ``QDCNN_FUZZ_SCALE``) examples."""
    count = max(1, round(examples * FUZZ_SCALE))
    return hypothesis.settings(hypothesis.settings.get_profile("qdcnn-fuzz"), max_examples=count)


class Hung(Exception):
    """An example ran past :data:`HANG_SECONDS`."""


@contextmanager
def hang_guard(seconds: int = HANG_SECONDS) -> Iterator[None]:
    """Raise :class:`Hung` in the main thread if the block runs longer than ``seconds``."""

    def expire(signum: int, frame: FrameType | None) -> None:
        raise Hung(f"no answer after {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
