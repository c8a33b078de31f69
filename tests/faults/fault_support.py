"""Shared pieces of the fault suite: tiny inputs, every command that writes, and fault tools.

The fault suite (``tests/faults``) runs every command that writes against a file system
that refuses (read-only or full ``tmpfs`` mounts; skipped where mounting is not permitted),
outputs that are links, regular files or devices, ``kill -9`` at seeded points followed by
a re-run, two commands writing into one folder at once, and tampered model files. Every
case asserts the exit status, exactly one ``error:`` line and no traceback on stderr, and
that finished outputs did not change.

The inputs are tiny (a 3-frame synthetic drive, a 6-scene shadow set, a 100-frame
synthetic spec) so the whole suite runs in a few minutes on two loaded cores.
"""

from __future__ import annotations

import csv
import errno
import io
import json
import os
import re
import shutil
import signal
import stat
import subprocess
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from fnmatch import fnmatch
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner, Result

from qdcnn.cli import app

runner = CliRunner()

#: Hidden temporary names the writers use (``.<name>.<12 hex>.tmp[.suffix]``).
TEMPORARY = re.compile(r"^\..+\.[0-9a-f]{12}\.tmp(\.[A-Za-z0-9]+)?$")
#: Files of an output folder that are bookkeeping, not outputs (the lock holds a pid).
BOOKKEEPING = {".qdcnn.lock"}


# ---------------------------------------------------------------------------- inputs
@dataclass(frozen=True)
class Inputs:
    """Tiny inputs shared by the fault tests (made once per session)."""

    recording: Path  # a udacity recording of 3 synthetic frames
    shadow_set: Path  # DIR/images and DIR/masks, 6 synthetic scenes
    direction_model: Path  # image-split-uu trained on synthetic:track2:100
    shadow_model: Path  # train-shadows on the shadow set

    @property
    def images(self) -> Path:
        return self.recording / "IMG"


_INPUTS: dict[str, Inputs] = {}


def build_inputs(tmp_path_factory: pytest.TempPathFactory) -> Inputs:
    """The session's :class:`Inputs`, made by the commands themselves on first use."""
    if "inputs" not in _INPUTS:
        root = tmp_path_factory.mktemp("fault-inputs")
        invoke_ok(["synth", "--preset", "track2", "--n", "6", "--out", str(root / "drive")])
        inputs = Inputs(
            recording=root / "drive" / "udacity",
            shadow_set=root / "drive" / "shadows",
            direction_model=root / "direction.safetensors",
            shadow_model=root / "shadow.json",
        )
        invoke_ok([*DIRECTION_TRAINING, "--out", str(inputs.direction_model)])
        shadows = ["train-shadows", "--shadow-set", str(inputs.shadow_set)]
        invoke_ok([*shadows, "--out", str(inputs.shadow_model)])
        _INPUTS["inputs"] = inputs
    return _INPUTS["inputs"]


DIRECTION_DATA = "synthetic:track2:100"  # the smallest synthetic spec with turns
DIRECTION_TRAINING = ["train-direction", "--data", DIRECTION_DATA, "--inner-folds", "0"]


# ---------------------------------------------------------------------------- commands
@dataclass(frozen=True)
class Command:
    """A command that writes, with tiny inputs.

    ``output`` says what it writes: ``"folder"`` (a locked output folder), ``"file"`` (one
    file; ``noise-sweep --plot`` also writes ``NAME_shadow.EXT`` beside it) or ``"cache"``
    (only ``$QDCNN_CACHE``). ``rewrite`` are the options that make a second run write its
    outputs again over finished ones; ``empties`` says they remove the old outputs first.
    """

    name: str
    argv: Callable[[Inputs, Path], list[str]]
    output: str
    rewrite: tuple[str, ...] = ()
    empties: bool = False

    def args(self, inputs: Inputs, out: Path) -> list[str]:
        return self.argv(inputs, out)


def _plain(*args: str) -> Callable[[Inputs, Path], list[str]]:
    return lambda i, o: [*args, str(o)]


COMMANDS: list[Command] = [
    Command(
        "synth",
        _plain("synth", "--preset", "track2", "--n", "3", "--out"),
        "folder",
        ("--force",),
        empties=True,
    ),
    Command(
        "detect-shadows",
        lambda i, o: ["detect-shadows", str(i.images), "--out", str(o)],
        "folder",
        ("--force",),
    ),
    Command(
        "train-shadows",
        lambda i, o: ["train-shadows", "--shadow-set", str(i.shadow_set), "--out", str(o)],
        "file",
    ),
    Command(
        "detect-lanes",
        lambda i, o: [
            "detect-lanes",
            str(i.images),
            "--out",
            str(o),
            "--model",
            str(i.direction_model),
        ],
        "folder",
        ("--force",),
    ),
    Command("train-direction", lambda i, o: [*DIRECTION_TRAINING, "--out", str(o)], "file"),
    Command(
        "run",
        lambda i, o: [
            "run",
            str(i.images),
            "--out",
            str(o),
            "--no-video",
            "--chunk",
            "2",
            "--model",
            str(i.direction_model),
        ],
        "folder",
        ("--force",),
    ),
    Command(
        "evaluate",
        lambda i, o: [
            "evaluate",
            "--data",
            DIRECTION_DATA,
            "--method",
            "image-split-uu",
            "--folds",
            "2",
            "--inner-folds",
            "0",
            "--json",
        ],
        "cache",
    ),
    Command(
        "score",
        lambda i, o: [
            "score",
            "--data",
            f"udacity:{i.recording}",
            "--model",
            str(i.direction_model),
            "--resamples",
            "50",
            "--json",
        ],
        "cache",
    ),
    Command(
        "reproduce",
        _plain("reproduce", "--quick", "--no-cnn", "--synthetic-frames", "20", "--out"),
        "folder",
        ("--force",),
        empties=True,
    ),
    Command(
        "noise-sweep --plot",
        lambda i, o: [
            "noise-sweep",
            "--shadow-set",
            str(i.shadow_set),
            "--method",
            "uu-shadow",
            "--channels",
            "depolarizing",
            "--p",
            "0",
            "--plot",
            str(o),
        ],
        "file",
    ),
    Command(
        "circuit --qasm",
        _plain("circuit", "vqc", "--x", "0.3,1.2", "--weights", "0.1,0.2,0.3,0.4", "--qasm"),
        "file",
    ),
]
BY_NAME = {c.name: c for c in COMMANDS}
#: ``demo`` is ``reproduce --quick`` on larger built-in drives: only where it stops at once.
DEMO = Command("demo", _plain("demo", "--out"), "folder", ("--force",), empties=True)
FILE_NAMES = {
    "train-shadows": "model.json",
    "train-direction": "model.safetensors",
    "noise-sweep --plot": "ber.png",
    "circuit --qasm": "vqc.qasm",
}


def output_path(command: Command, folder: Path) -> Path:
    """Where ``command`` writes inside ``folder`` (a file name or a sub-folder)."""
    return folder / FILE_NAMES.get(command.name, "out")


# ---------------------------------------------------------------------------- running
#: The sections ``reproduce`` and ``demo`` compute here: fast ones that succeed on 20 frames
#: and write a figure each (all eleven take a minute; the report's own writes are the same).
REPRODUCE_SECTIONS = ("table-iv", "fig-2", "fig-3")


@contextmanager
def few_reproduce_sections() -> Iterator[None]:
    """``reproduce`` and ``demo`` compute only :data:`REPRODUCE_SECTIONS` in this block."""
    from qdcnn.experiments.reproduce import runner as reproduce_runner

    saved = reproduce_runner.SECTIONS, reproduce_runner.PAGE_ORDER
    keep = tuple(d for d in saved[0] if d.id in REPRODUCE_SECTIONS)
    reproduce_runner.SECTIONS = keep
    reproduce_runner.PAGE_ORDER = tuple(i for i in saved[1] if i in REPRODUCE_SECTIONS)
    try:
        yield
    finally:
        reproduce_runner.SECTIONS, reproduce_runner.PAGE_ORDER = saved


def invoke(args: list[str], *, cache: Path | None = None) -> Result:
    """Run ``qdcnn ARGS`` in this process (``cache``: its ``$QDCNN_CACHE``)."""
    old = os.environ.get("QDCNN_CACHE")
    if cache is not None:
        os.environ["QDCNN_CACHE"] = str(cache)
    try:
        with few_reproduce_sections():
            return runner.invoke(app, args)
    finally:
        if old is not None:
            os.environ["QDCNN_CACHE"] = old


def invoke_ok(args: list[str], *, cache: Path | None = None) -> Result:
    res = invoke(args, cache=cache)
    assert res.exit_code == 0, (args, res.output)
    return res


def error_lines(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("error:")]


def assert_one_error(res: Result, exit_code: int = 2, *names: str) -> str:
    """``res`` exited with ``exit_code``, no traceback, exactly one ``error:`` line naming
    every one of ``names``; returns that line."""
    assert "Traceback" not in res.output, res.output
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)
    assert res.exit_code == exit_code, res.output
    lines = error_lines(res.stderr)
    assert len(lines) == 1, res.stderr
    assert all(str(name) in lines[0] for name in names), (names, lines[0])
    return lines[0]


def fork_command(args: list[str], *, cache: Path) -> int:
    """Start ``qdcnn ARGS`` in a forked copy of this process (its imports done, so the work
    starts at once); returns its pid. Its exit status is the command's."""
    pid = os.fork()
    if pid == 0:  # the child: run the command, never return into pytest
        code = 70
        try:
            code = invoke(args, cache=cache).exit_code
        finally:
            os._exit(code)
    return pid


def kill_forked(args: list[str], *, cache: Path, after: float) -> bool:
    """:func:`fork_command` and SIGKILL it ``after`` seconds; False when it ended first."""
    pid = fork_command(args, cache=cache)
    deadline = time.monotonic() + after
    while time.monotonic() < deadline:
        if os.waitpid(pid, os.WNOHANG) != (0, 0):
            return False
        time.sleep(0.005)
    os.kill(pid, signal.SIGKILL)
    os.waitpid(pid, 0)
    return True


def kill_when(
    proc: subprocess.Popen[bytes], ready: Callable[[], bool], timeout: float = 300
) -> bool:
    """SIGKILL ``proc`` once ``ready()``; False when it ended first."""
    t0 = time.monotonic()
    while proc.poll() is None and time.monotonic() - t0 < timeout:
        if ready():
            os.kill(proc.pid, signal.SIGKILL)
            proc.communicate()
            return True
        time.sleep(0.01)
    proc.communicate()
    return False


#: Keys of JSON results that hold measured times (they differ between any two runs).
_TIMING_KEY = re.compile(r"second|(^|_)ms(_|$)|time|per_s|fps|created", re.IGNORECASE)


def is_timing(key: str) -> bool:
    """Whether a field or array named ``key`` holds measured times or dates."""
    return bool(_TIMING_KEY.search(key))


def timeless(value: object) -> object:
    """``value`` (parsed JSON) without the fields that hold measured times or dates."""
    if isinstance(value, dict):
        return {k: timeless(v) for k, v in value.items() if not _TIMING_KEY.search(str(k))}
    if isinstance(value, list):
        return [timeless(v) for v in value]
    return value


def json_results(stdout: str) -> list[object]:
    """The JSON lines of ``stdout``, :func:`timeless`."""
    return [timeless(json.loads(line)) for line in stdout.splitlines() if line.strip()]


# ---------------------------------------------------------------------------- folders
def snapshot(root: Path) -> dict[str, bytes]:
    """Every regular file under ``root`` (or ``root`` itself) and its bytes; links as
    ``b"-> target"``; the lock file left out."""
    if root.is_file() or root.is_symlink():
        return {root.name: _content(root)}
    out = {}
    for path in sorted(root.rglob("*")):
        if path.name not in BOOKKEEPING and (path.is_symlink() or path.is_file()):
            out[str(path.relative_to(root))] = _content(path)
    return out


def _content(path: Path) -> bytes:
    return f"-> {os.readlink(path)}".encode() if path.is_symlink() else path.read_bytes()


def temporaries(root: Path) -> list[Path]:
    """Temporary files the writers left under ``root``."""
    return sorted(p for p in root.rglob(".*") if TEMPORARY.match(p.name))


# ---------------------------------------------------------------------------- faults
@contextmanager
def mounted_tmpfs(point: Path, options: str) -> Iterator[Path]:
    """A ``tmpfs`` mounted at ``point`` with ``options``; skips the test when not permitted."""
    point.mkdir(parents=True, exist_ok=True)
    if shutil.which("mount") is None:
        pytest.skip("no mount command")
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(point)],
        capture_output=True,
        check=False,
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {done.stderr.decode().strip()}")
    try:
        yield point
    finally:
        subprocess.run(["umount", "-l", str(point)], check=False)


def remount_read_only(point: Path) -> None:
    subprocess.run(["mount", "-o", "remount,ro", str(point)], check=True, capture_output=True)


def fill(folder: Path) -> Path:
    """Fill the file system of ``folder`` to the last byte; returns the filler file."""
    filler = folder / "filler"
    fd = os.open(filler, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    try:
        for size in (1 << 16, 1 << 12, 1 << 8, 1):
            try:
                while True:
                    os.write(fd, b"\0" * size)
            except OSError as exc:
                assert exc.errno == errno.ENOSPC, exc
    finally:
        os.close(fd)
    return filler


def make_null_device(path: Path) -> Path:
    """A character device like ``/dev/null`` at ``path`` (skips without mknod); the real
    ``/dev/null`` is not used, since a writer that renamed over it would replace it."""
    try:
        os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    except (OSError, AttributeError) as exc:
        pytest.skip(f"cannot make a device node: {exc}")
    return path


# ---------------------------------------------------------------------------- comparing
#: Files whose contents hold measured times (compared apart from them).
TIMED = {
    "run": ("summary.json", "*/timings.csv", ".qdcnn-manifest/*"),
    "reproduce": ("index.html", "report.json", "sections/*.json"),
}


def outputs_of(command: Command, out: Path, cache: Path) -> dict[str, bytes]:
    """What ``command`` left (the cache for a cache command), with ``out`` written ``<out>``."""
    root = cache if command.output == "cache" else out
    if not root.exists():
        return {}
    found = snapshot(root)
    return {rel: data.replace(str(root).encode(), b"<out>") for rel, data in found.items()}


def same_output(command: Command, rel: str, got: bytes, want: bytes) -> bool:
    if got == want:
        return True
    if rel.endswith(".json"):
        if timeless(json.loads(got)) == timeless(json.loads(want)):
            return True
    if rel.endswith(".npz"):  # a zip holds its members' dates: compare the arrays
        return same_arrays(got, want)
    if not any(fnmatch(rel, pattern) for pattern in TIMED.get(command.name, ())):
        return False
    return is_whole(rel, got, want)


def same_arrays(got: bytes, want: bytes) -> bool:
    with np.load(io.BytesIO(got)) as a, np.load(io.BytesIO(want)) as b:
        kept = [k for k in a if not is_timing(k)]
        return set(a) == set(b) and all(np.array_equal(a[k], b[k]) for k in kept)


def is_whole(rel: str, got: bytes, want: bytes) -> bool:
    """``got`` is a complete file of ``want``'s kind (times may differ)."""
    if rel.endswith(".json"):
        return set(json.loads(got)) == set(json.loads(want))
    if rel.endswith(".csv"):
        rows = [list(csv.reader(io.StringIO(d.decode()))) for d in (got, want)]
        return [r[0] for r in rows[0]] == [r[0] for r in rows[1]]
    return got.rstrip().endswith(b"</html>")


def assert_whole(command: Command, left: dict[str, bytes], reference: dict[str, bytes]) -> None:
    """Every file in ``left`` that ``reference`` also has equals it (or is whole, if timed)."""
    for rel, data in left.items():
        if rel in reference:
            assert same_output(command, rel, data, reference[rel]), rel
