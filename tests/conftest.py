"""Shared fixtures: seeded generators and the location of the real recordings."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path

import numpy as np
import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"

#: Multiplies the example counts of the fuzz suite (tests/fuzz): QDCNN_FUZZ_SCALE=20 for a long run.
FUZZ_SCALE = float(os.environ.get("QDCNN_FUZZ_SCALE", "1"))

try:
    from hypothesis import HealthCheck, settings
except ImportError:  # a dev dependency: only the fuzz tests need it, and they skip without it
    pass
else:
    # Fixed seed (derandomize), no example database, and a deadline per example; each fuzz
    # test sets its own max_examples from FUZZ_SCALE.
    settings.register_profile(
        "qdcnn-fuzz",
        derandomize=True,
        database=None,
        deadline=timedelta(seconds=20),
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
        print_blob=True,
    )


@pytest.fixture(scope="session", autouse=True)
def _session_cache(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    """Feature and model caches in a folder of this session, never the user's ~/.cache."""
    old = os.environ.get("QDCNN_CACHE")
    os.environ["QDCNN_CACHE"] = str(tmp_path_factory.mktemp("qdcnn-cache"))
    yield
    if old is None:
        os.environ.pop("QDCNN_CACHE", None)
    else:
        os.environ["QDCNN_CACHE"] = old


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


def shared_recording(name: str) -> Path:
    """Path of a recording in ``../shared/data``; skips the test when it is absent."""
    path = SHARED_DATA / name
    if not (path / "driving_log.csv").is_file():
        pytest.skip(f"real recording {name} not available at {path}")
    return path


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
