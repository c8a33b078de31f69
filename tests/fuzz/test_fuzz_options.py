"""Fuzzing every numeric option of every command: exit 0, 1 or 2, one error line, no traceback.

Each example gives one option of one command an odd value (negative, zero, huge, NaN,
infinite, text, an exponent, empty) on inputs small enough that a value the command
accepts still finishes at once. The property: the command ends by itself with exit status
0, 1 or 2; it never raises anything but its own exit; on status 2 stderr holds exactly one
``error:`` line (a note about the default model may precede it) and no traceback.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fuzz_support import fuzz_settings, hang_guard
from typer.testing import CliRunner

from qdcnn.cli import app
from qdcnn.data.images import write_image

hypothesis = pytest.importorskip("hypothesis")
st = hypothesis.strategies

#: Odd values for numeric options; valid-but-huge sizes are left out on purpose (they would
#: run for hours), every other class of value is in.
ODD = [
    "-1", "0", "1", "2", "-0", "0.5", "-0.5", "1.5", "1e21", "-1e21", "1e308", "nan", "inf",
    "-inf", "NaN", "", " ", "abc", "0x10", "1,2", "١", "2**40", "10000000000000", "9" * 40,
    "+1", "1e-320", "-10_000",
]  # fmt: skip


def _images(folder: Path) -> Path:
    rng = np.random.default_rng(0)
    for i in range(2):
        write_image(folder / f"f{i}.png", rng.integers(0, 255, (40, 80, 3), dtype=np.uint8))
    return folder


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    root = tmp_path_factory.mktemp("fuzz")
    images = _images(root / "images")
    out = root / "out"
    return {"images": str(images), "out": str(out), "root": str(root)}


#: command -> (base arguments, the numeric options to fuzz)
COMMANDS: dict[str, tuple[list[str], list[str]]] = {
    "detect-shadows": (
        ["detect-shadows", "{images}", "--out", "{out}/m", "--method", "ibt"],
        ["--shots", "--threshold", "--centroid", "--calibration-classes", "--seed", "--wait"],
    ),
    "detect-shadows-uu": (
        ["detect-shadows", "{images}", "--out", "{out}/u"],
        ["--shots", "--threshold", "--centroid", "--calibration-classes", "--seed"],
    ),
    "synth": (
        ["synth", "--out", "{out}/s", "--force", "--n", "2", "--width", "32", "--height", "16"],
        ["--n", "--seed", "--width", "--height"],
    ),
    "evaluate": (
        ["evaluate", "--data", "synthetic:track1:10", "--method", "image-split-uu"],
        [
            "--folds",
            "--gap",
            "--inner-folds",
            "--seed",
            "--epochs",
            "--threads",
            "--label-threshold",
            "--context",
        ],
    ),
    "noise-sweep": (
        ["noise-sweep", "--method", "uu-shadow", "--channels", "bit-flip", "--p", "0"],
        [
            "--shots",
            "--readout",
            "--folds",
            "--gap",
            "--inner-folds",
            "--shadow-frames",
            "--seed",
            "--p",
        ],
    ),
    "circuit": (
        ["circuit", "uu", "--theta-c", "1", "--theta-x", "0.5"],
        ["--theta-c", "--theta-x", "--shots", "--seed", "--feature-map-reps"],
    ),
    "circuit-head": (
        ["circuit", "head", "--qubits", "1", "--layers", "1", "--weights", "0,0,0"],
        ["--qubits", "--layers", "--shots", "--seed"],
    ),
    "bench": (["bench", "shadows", "--aer-blocks", "0", "--no-lbp"], ["--frames", "--repeats"]),
    "run": (
        ["run", "{images}", "--out", "{out}/r", "--no-video"],
        ["--smooth", "--chunk", "--seed", "--wait"],
    ),
    "train-shadows": (
        ["train-shadows", "--shadow-set", "{root}/nowhere", "--out", "{out}/m.json"],
        ["--centroids", "--seed"],
    ),
}
#: Commands whose accepted values run real work (training, rendering): only refused values.
SLOW = ("bench", "run", "evaluate", "noise-sweep")


def _plausible(value: str) -> bool:
    try:
        v = float(value.replace("_", ""))
    except ValueError:
        return False
    return 0 <= v <= 1e6


CASES = [(name, option) for name, (_, options) in COMMANDS.items() for option in options]
runner = CliRunner()


def _args(name: str, option: str, value: str, work: dict[str, str]) -> list[str]:
    base, _ = COMMANDS[name]
    args = [a.format(**work) for a in base]
    if option in args:  # replace the base value
        i = args.index(option)
        return [*args[: i + 1], value, *args[i + 2 :]]
    return [*args, option, value]


@pytest.mark.parametrize(("name", "option"), CASES)
def test_odd_option_values_end_with_a_status_and_one_line(
    name: str, option: str, work: dict[str, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))

    @fuzz_settings(len(ODD))
    @hypothesis.given(st.sampled_from(ODD))
    def check(value: str) -> None:
        args = _args(name, option, value, work)
        if name in SLOW and _plausible(value):
            return  # a value the command may accept runs it (its own tests cover that)
        with hang_guard(120):
            res = runner.invoke(app, args)
        assert res.exit_code in (0, 1, 2), (args, res.exit_code, res.output)
        assert res.exception is None or isinstance(res.exception, SystemExit), (args, res.exception)
        assert "Traceback" not in res.stderr, (args, res.stderr)
        if res.exit_code == 2:
            errors = [line for line in res.stderr.splitlines() if line.startswith("error:")]
            assert len(errors) == 1, (args, res.stderr)
        if "--json" in args and res.exit_code == 0:
            for line in res.stdout.splitlines():
                json.loads(line)

    check()
