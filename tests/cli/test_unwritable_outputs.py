"""Outputs that cannot be written: exit 2 and one ``error:`` line, never a traceback (issue 23).

Each command that writes is pointed at a read-only file system (a ``tmpfs`` mounted
read-only; skipped where ``mount`` is not permitted), at a path below a regular file, and
at a character device (a null device made with ``mknod`` in the test's folder; skipped
where that is not permitted; the real ``/dev/null`` is not used, since a writer that
renamed over it would replace the machine's device). ``circuit --qasm`` and
``noise-sweep --plot`` onto a symbolic link are refused and the link's target is unchanged.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from tests.cli.test_cli_commands import app, runner
from tests.faults.fault_support import make_null_device, mounted_tmpfs

from qdcnn.data.images import write_image, write_mask
from qdcnn.experiments.noise import synthetic_shadow_set

Args = Callable[[Path, Path], list[str]]


def _shadow_set(root: Path) -> Path:
    images, masks = synthetic_shadow_set(4, seed=2)
    for i, (im, m) in enumerate(zip(images, masks, strict=True)):
        write_image(root / "images" / f"s{i}.png", im)
        write_mask(root / "masks" / f"s{i}.png", m)
    return root


#: (arguments given the work folder and the output path, output is a folder)
COMMANDS: dict[str, tuple[Args, bool]] = {
    "synth": (lambda w, o: ["synth", "--n", "2", "--out", str(o)], True),
    "train-shadows": (
        lambda w, o: ["train-shadows", "--shadow-set", str(_shadow_set(w / "s")), "--out", str(o)],
        False,
    ),
    "train-direction": (
        lambda w, o: ["train-direction", "--data", "synthetic:track2:100", "--out", str(o)],
        False,
    ),
    "reproduce --quick --no-cnn": (
        lambda w, o: ["reproduce", "--quick", "--no-cnn", "--out", str(o)],
        True,
    ),
}


@pytest.fixture
def read_only_dir(tmp_path: Path) -> Iterator[Path]:
    """An empty folder on a read-only ``tmpfs`` (skips when mounting is not permitted)."""
    with mounted_tmpfs(tmp_path / "ro", "ro") as mount_point:
        yield mount_point


@pytest.fixture
def null_device(tmp_path: Path) -> Path:
    """A character device like ``/dev/null`` in the test's folder (skips without mknod)."""
    return make_null_device(tmp_path / "null")


def _assert_one_error(args: list[str], *names: str) -> str:
    res = runner.invoke(app, args)
    lines = [line for line in res.stderr.splitlines() if not line.startswith("progress:")]
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output
    assert len(lines) == 1 and lines[0].startswith("error:"), res.stderr
    assert all(name in lines[0] for name in names), lines[0]
    return lines[0]


@pytest.mark.parametrize("command", COMMANDS)
def test_a_read_only_file_system_is_one_error_line(
    command: str, tmp_path: Path, read_only_dir: Path
) -> None:
    make_args, is_folder = COMMANDS[command]
    out = read_only_dir / ("out" if is_folder else "model.json")
    line = _assert_one_error(make_args(tmp_path, out), str(read_only_dir))
    assert "read-only file system" in line.lower()
    assert not any(read_only_dir.iterdir())


@pytest.mark.parametrize("command", COMMANDS)
def test_an_output_below_a_regular_file_is_one_error_line(command: str, tmp_path: Path) -> None:
    make_args, is_folder = COMMANDS[command]
    blocker = tmp_path / "a-file"
    blocker.write_text("keep")
    out = blocker if is_folder else blocker / "model.json"
    _assert_one_error(make_args(tmp_path, out), str(blocker))
    assert blocker.read_text() == "keep"


@pytest.mark.parametrize("command", COMMANDS)
def test_an_output_on_a_device_is_one_error_line(
    command: str, tmp_path: Path, null_device: Path
) -> None:
    make_args, _is_folder = COMMANDS[command]
    _assert_one_error(make_args(tmp_path, null_device), str(null_device))
    assert stat.S_ISCHR(os.lstat(null_device).st_mode)  # still the device


def _victim_and_link(tmp_path: Path, name: str) -> tuple[Path, Path]:
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    link = tmp_path / name
    link.symlink_to(victim)
    return victim, link


def test_circuit_qasm_onto_a_link_is_refused(tmp_path: Path) -> None:
    pytest.importorskip("qiskit_qasm3_import")
    victim, link = _victim_and_link(tmp_path, "vqc.qasm")
    args = ["circuit", "vqc", "--x", "0.3,1.2", "--weights", "0.1,0.2,0.3,0.4", "--qasm", str(link)]
    line = _assert_one_error(args, str(link))
    assert "is a symbolic link; qdcnn never writes through one" in line
    assert victim.read_text() == "keep me" and link.is_symlink()


def test_noise_sweep_plot_onto_a_link_is_refused(tmp_path: Path) -> None:
    victim, link = _victim_and_link(tmp_path, "ber.png")
    root = _shadow_set(tmp_path / "set")
    args = ["noise-sweep", "--shadow-set", str(root), "--method", "uu-shadow"]
    args += ["--channels", "depolarizing", "--p", "0", "--plot", str(link)]
    res = runner.invoke(app, args)
    errors = [line for line in res.stderr.splitlines() if line.startswith("error:")]
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output
    assert len(errors) == 1 and "is a symbolic link; qdcnn never writes through one" in errors[0]
    assert victim.read_text() == "keep me" and link.is_symlink()
