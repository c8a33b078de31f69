"""What differs on the base install (no extras): the commands that need an extra say which,
in one line with exit status 2, and the base commands run end to end.

CI's base job runs only the tests marked ``base`` (``pytest -m base``); this module is the
core of it. On the full install the missing-extra cases skip (the extra is there) and the
base commands run as well.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from qdcnn._optional import has_module

pytestmark = pytest.mark.base


def _qdcnn(*args: str, env_cache: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "qdcnn", *args],
        capture_output=True,
        text=True,
        timeout=600,
        env={"QDCNN_CACHE": str(env_cache), "PATH": "/usr/bin:/bin"},
    )


NEEDS_EXTRA = [
    (
        "torch",
        "dnn",
        ["evaluate", "--data", "synthetic:track2:200", "--method", "dnn-pilotnet", "--folds", "2"],
    ),
    ("dask", "dask", ["run", "synthetic:track1:20", "--out", "OUT", "--scheduler", "local:2"]),
    (
        "qiskit_aer",
        "quantum",
        ["circuit", "uu", "--theta-c", "1", "--theta-x", "0.5", "--backend", "aer"],
    ),
]


@pytest.mark.parametrize(("module", "extra", "args"), NEEDS_EXTRA, ids=[e[1] for e in NEEDS_EXTRA])
def test_a_command_that_needs_a_missing_extra_names_it(
    module: str, extra: str, args: list[str], tmp_path: Path
) -> None:
    if has_module(module):
        pytest.skip(f"{module} is installed")
    args = [str(tmp_path / "out") if a == "OUT" else a for a in args]
    res = _qdcnn(*args, env_cache=tmp_path / "cache")
    assert res.returncode == 2, res.stderr
    errors = [line for line in res.stderr.splitlines() if line.startswith("error:")]
    assert len(errors) == 1 and f"pip install 'qdcnn[{extra}]'" in errors[0], res.stderr
    assert "Traceback" not in res.stderr


def test_the_base_commands_run_end_to_end(tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    synth = _qdcnn(
        "synth", "--preset", "track2", "--n", "12", "--seed", "3", "--out", str(tmp_path / "s"),
        env_cache=cache,
    )
    assert synth.returncode == 0, synth.stderr
    shadows = _qdcnn(
        "detect-shadows", str(tmp_path / "s" / "shadows" / "images"), "--method", "uu",
        "--out", str(tmp_path / "masks"), "--json", env_cache=cache,
    )
    assert shadows.returncode == 0, shadows.stderr
    assert json.loads(shadows.stdout.splitlines()[-1])["n_images"] == 12
    evaluate = _qdcnn(
        "evaluate", "--data", "synthetic:track2:120", "--method", "image-split-uu",
        "--folds", "2", "--json", env_cache=cache,
    )
    assert evaluate.returncode == 0, evaluate.stderr
    assert 0.0 <= json.loads(evaluate.stdout.splitlines()[0])["accuracy"] <= 1.0
