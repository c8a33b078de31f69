"""``import qdcnn.cli``, every ``--help`` and an option error load none of the heavy libraries.

The commands import their runners when they run, so ``qdcnn --help`` stays fast (see
benchmarks/bench_startup.py for the measured times). Each check runs in a fresh interpreter,
since this test process has long since imported everything.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

pytestmark = pytest.mark.base  # the base install's CLI must start fast too

#: Libraries only a running command may load (scikit-image would bring SciPy).
HEAVY = (
    "sklearn",
    "scipy",
    "torch",
    "qiskit",
    "qiskit_aer",
    "matplotlib",
    "dask",
    "distributed",
    "av",
    "pennylane",
    "skimage",
)
#: Not heavy extras, but each costs a tenth of a second or more, and the CLI needs neither.
ARRAYS = ("numpy", "cv2")

#: Every command's --help (bench's subcommands too) and one option error, in one interpreter.
EVERY_HELP = """
import contextlib, io, sys
from typer.main import get_command
from qdcnn.cli import app, main

group = get_command(app)
argvs = [["--help"], [], ["evaluate", "--bogus"], ["bench"]]
argvs += [[name, "--help"] for name in group.commands]
argvs += [["bench", name, "--help"] for name in group.commands["bench"].commands]
for argv in argvs:
    sys.argv = ["qdcnn", *argv]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        try:
            main()
        except SystemExit:
            pass
"""


def loaded_after(code: str, names: tuple[str, ...]) -> list[str]:
    """Which of ``names`` are in ``sys.modules`` after ``code`` runs in a new interpreter."""
    report = f"\nimport json, sys\nprint(json.dumps([m for m in {names!r} if m in sys.modules]))"
    done = subprocess.run(
        [sys.executable, "-c", code + report], capture_output=True, text=True, check=True
    )
    return list(json.loads(done.stdout.splitlines()[-1]))


def test_importing_the_cli_loads_no_heavy_library() -> None:
    assert loaded_after("import qdcnn.cli", HEAVY) == []


def test_importing_the_cli_loads_neither_numpy_nor_opencv() -> None:
    assert loaded_after("import qdcnn.cli", ARRAYS) == []


def test_help_and_option_errors_load_no_heavy_library() -> None:
    assert loaded_after(EVERY_HELP, HEAVY + ARRAYS) == []


def test_the_help_check_reaches_every_command() -> None:
    code = EVERY_HELP + "\nprint(len(argvs))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert int(done.stdout.split()[-1]) >= 4 + 13 + 2
