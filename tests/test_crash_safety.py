"""kill -9 at several points of long commands: nothing truncated is left, a re-run completes.

Each test starts one ``python -m qdcnn`` process, waits until it has done some of its work
(files appear), kills that process (and only it) with SIGKILL, then checks that every
file it left can be read whole, that the feature cache reads back, and that running the
same command again finishes with the same outputs as a run that was never interrupted.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from tests.faults.fault_support import kill_when

from qdcnn.data.images import read_image, read_mask, write_image

pytestmark = pytest.mark.slow


def qdcnn(*args: str, env: dict[str, str]) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-m", "qdcnn", *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        env=env,
        start_new_session=True,
    )


def finish(*args: str, env: dict[str, str]) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "qdcnn", *args], capture_output=True, env=env, timeout=600
    )
    assert proc.returncode == 0, proc.stderr.decode()


@pytest.fixture
def env(tmp_path: Path) -> dict[str, str]:
    return {**os.environ, "QDCNN_CACHE": str(tmp_path / "cache")}


@pytest.fixture
def images(tmp_path: Path) -> Path:
    rng = np.random.default_rng(0)
    folder = tmp_path / "in"
    for i in range(24):
        img = np.clip(rng.normal(150, 5, (160, 320, 3)), 0, 255).astype(np.uint8)
        img[40:110, 60 + i : 150 + i] //= 2
        write_image(folder / f"f{i:02d}.png", img)
    return folder


def visible(folder: Path, pattern: str) -> list[Path]:
    return sorted(p for p in folder.glob(pattern) if not p.name.startswith("."))


@pytest.mark.parametrize("after", [1, 6, 15])
def test_detect_shadows_killed_then_resumed(
    after: int, images: Path, tmp_path: Path, env: dict[str, str]
) -> None:
    out, clean = tmp_path / "masks", tmp_path / "clean"
    args = ["detect-shadows", str(images), "--shots", "1024"]
    finish(*args, "--out", str(clean), env=env)
    proc = qdcnn(*args, "--out", str(out), env=env)
    kill_when(proc, lambda: len(visible(out, "*_mask.png")) >= after)
    for mask in visible(out, "*_mask.png"):
        assert read_mask(mask).shape == (160, 320)  # never half a file
    finish(*args, "--out", str(out), env=env)
    assert not list(out.glob(".*.tmp"))
    for mask in visible(clean, "*_mask.png"):
        assert (out / mask.name).read_bytes() == mask.read_bytes()


@pytest.mark.parametrize("after", [2, 12])
def test_detect_lanes_killed_then_resumed(
    after: int, images: Path, tmp_path: Path, env: dict[str, str]
) -> None:
    out, clean = tmp_path / "lanes", tmp_path / "clean"
    finish("detect-lanes", str(images), "--out", str(clean), env=env)
    proc = qdcnn("detect-lanes", str(images), "--out", str(out), env=env)
    kill_when(proc, lambda: len(visible(out, "*_lanes.png")) >= after)
    for overlay in visible(out, "*_lanes.png"):
        assert read_image(overlay).shape == (160, 320, 3)
    assert not (out / "predictions.csv").exists() or after > 24
    finish("detect-lanes", str(images), "--out", str(out), env=env)
    assert (out / "predictions.csv").read_bytes() == (clean / "predictions.csv").read_bytes()


def test_synth_killed_then_run_again(tmp_path: Path, env: dict[str, str]) -> None:
    out = tmp_path / "synth"
    args = ["synth", "--preset", "track2", "--n", "60", "--out", str(out)]
    proc = qdcnn(*args, env=env)
    kill_when(proc, lambda: len(visible(out / "udacity" / "IMG", "*.jpg")) >= 10)
    for frame in visible(out / "udacity" / "IMG", "*.jpg"):
        assert read_image(frame).shape == (160, 320, 3)
    assert not (out / "udacity" / "driving_log.csv").exists()  # the log appears when complete
    finish(*args, "--force", env=env)  # the killed run's frames are there: replace them
    assert not [p for p in out.rglob(".*.tmp*")]  # no temporary file is left behind
    from qdcnn.data.udacity import load_udacity

    assert len(load_udacity(out / "udacity")) == 60


def test_evaluate_killed_while_caching_features(tmp_path: Path, env: dict[str, str]) -> None:
    from qdcnn.direction import feature_cache

    args = ["evaluate", "--data", "synthetic:track2:400", "--method", "image-split-uu", "--json"]
    cache = Path(env["QDCNN_CACHE"])
    for delay in (1.0, 2.5):
        proc = qdcnn(*args, env=env)
        time.sleep(delay)
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
    finish(*args, env=env)
    entries = sorted(p for p in cache.rglob("*.npz") if not p.name.startswith("."))
    assert entries
    for path in entries:
        assert feature_cache.read_entry(path, ("image-split",), 400, 2) is not None
