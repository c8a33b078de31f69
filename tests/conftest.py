"""Shared fixtures: seeded generators and the location of the real recordings."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


def shared_recording(name: str) -> Path:
    """Path of a recording in ``../shared/data``; skips the test when it is absent."""
    path = SHARED_DATA / name
    if not (path / "driving_log.csv").is_file():
        pytest.skip(f"real recording {name} not available at {path}")
    return path
