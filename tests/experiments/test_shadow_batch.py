"""detect-shadows: shot sampling follows each image's content, not its list position."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from qdcnn.cli import app
from qdcnn.data.images import write_image

runner = CliRunner()


def scene(i: int) -> np.ndarray:
    rng = np.random.default_rng(i)
    img = np.clip(rng.normal(150, 30, (96, 128, 3)), 0, 255).astype(np.uint8)
    img[20:70, 10 + i : 80 + i] //= 2
    return img


def detect(folder: Path, out: Path, seed: int = 3) -> None:
    args = ["detect-shadows", str(folder), "--out", str(out), "--shots", "8"]
    res = runner.invoke(app, [*args, "--seed", str(seed)])
    assert res.exit_code == 0, res.stderr


def masks(out: Path, names: list[str]) -> dict[str, bytes]:
    return {n: (out / f"{n}_mask.png").read_bytes() for n in names}


def test_fresh_resumed_and_extended_runs_give_the_same_masks(tmp_path: Path) -> None:
    folder = tmp_path / "in"
    for name, i in (("m", 1), ("n", 2), ("p", 3)):
        write_image(folder / f"{name}.png", scene(i))
    common = ["m", "n", "p"]
    resumed = tmp_path / "resumed"
    detect(folder, tmp_path / "first")
    detect(folder, resumed)
    write_image(folder / "a.png", scene(4))  # sorts first: every position moves
    detect(folder, resumed)  # resumes m, n, p; detects a
    detect(folder, tmp_path / "fresh")
    first = masks(tmp_path / "first", common)
    assert masks(resumed, common) == first
    assert masks(tmp_path / "fresh", common) == first
    assert masks(resumed, ["a"]) == masks(tmp_path / "fresh", ["a"])


def test_a_renamed_copy_gets_the_same_mask_and_shots_do_vary(tmp_path: Path) -> None:
    folder = tmp_path / "in"
    write_image(folder / "b.png", scene(1))
    shutil.copy(folder / "b.png", folder / "z.png")
    write_image(folder / "c.png", scene(5))
    detect(folder, tmp_path / "out")
    got = masks(tmp_path / "out", ["b", "z"])
    assert got["b"] == got["z"]
    detect(folder, tmp_path / "other", seed=4)
    assert masks(tmp_path / "other", ["b"])["b"] != got["b"]  # sampling does matter
