"""Fixtures of the runtime tests."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator

import pytest


@pytest.fixture
def busy_cpu() -> Iterator[None]:
    """A process spinning on one core beside the test, as on a loaded CI machine (Dask's
    workers then register, start and answer late)."""
    spinner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        yield
    finally:
        spinner.kill()
        spinner.wait()
