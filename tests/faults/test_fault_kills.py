"""``kill -9`` at seeded points of every command that writes, then a re-run.

Each command runs once to the end (the reference). Then it is started again into a fresh
output in a forked copy of the test process (imports done, so the work starts at once),
killed with SIGKILL after a seeded share (0.2 to 1) of the reference's duration, started
again over what the killed run left and killed again, and finally run to the end. After
every kill each file the run left is whole: it equals the reference's file byte for byte,
or (files that hold measured times, cache entries whose zip headers hold dates) equals it
apart from those. The final outputs equal the reference's in the same way, and no temporary
file remains. The commands that resume (detect-shadows, detect-lanes, run) are re-run as
they are; synth and reproduce with ``--force`` (what a non-empty folder needs); commands
that write one file or the cache with the same arguments. Output paths inside files are
compared relative to the output. (tests/test_crash_safety.py kills real ``python -m qdcnn``
processes at points chosen by the files they have written.)
"""

from __future__ import annotations

import csv
import fcntl
import io
import json
import time
import zlib
from fnmatch import fnmatch
from pathlib import Path

import numpy as np
import pytest
from fault_support import (
    BY_NAME,
    COMMANDS,
    Command,
    Inputs,
    build_inputs,
    invoke_ok,
    is_timing,
    json_results,
    kill_forked,
    output_path,
    snapshot,
    temporaries,
    timeless,
)

#: Files whose contents hold measured times (compared apart from them).
TIMED = {
    "run": ("summary.json", "*/timings.csv", ".qdcnn-manifest/*"),
    "reproduce": ("index.html", "report.json", "sections/*.json"),
}
KILLS = 2


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Inputs:
    return build_inputs(tmp_path_factory)


def _outputs(command: Command, out: Path, cache: Path) -> dict[str, bytes]:
    """What ``command`` left (the cache for a cache command), with ``out`` written ``<out>``."""
    root = cache if command.output == "cache" else out
    if not root.exists():
        return {}
    found = snapshot(root)
    return {rel: data.replace(str(root).encode(), b"<out>") for rel, data in found.items()}


def _same(command: Command, rel: str, got: bytes, want: bytes) -> bool:
    if got == want:
        return True
    if rel.endswith(".json"):
        if timeless(json.loads(got)) == timeless(json.loads(want)):
            return True
    if rel.endswith(".npz"):  # a zip holds its members' dates: compare the arrays
        return _same_arrays(got, want)
    if not any(fnmatch(rel, pattern) for pattern in TIMED.get(command.name, ())):
        return False
    return _whole(rel, got, want)


def _same_arrays(got: bytes, want: bytes) -> bool:
    with np.load(io.BytesIO(got)) as a, np.load(io.BytesIO(want)) as b:
        kept = [k for k in a if not is_timing(k)]
        return set(a) == set(b) and all(np.array_equal(a[k], b[k]) for k in kept)


def _whole(rel: str, got: bytes, want: bytes) -> bool:
    """``got`` is a complete file of ``want``'s kind (times may differ)."""
    if rel.endswith(".json"):
        return set(json.loads(got)) == set(json.loads(want))
    if rel.endswith(".csv"):
        rows = [list(csv.reader(io.StringIO(d.decode()))) for d in (got, want)]
        return [r[0] for r in rows[0]] == [r[0] for r in rows[1]]
    return got.rstrip().endswith(b"</html>")


def _assert_whole(command: Command, left: dict[str, bytes], reference: dict[str, bytes]) -> None:
    """Every file a killed run left that the reference also has is whole."""
    for rel, data in left.items():
        if rel in reference:
            assert _same(command, rel, data, reference[rel]), rel


def _rerun_args(command: Command, inputs: Inputs, out: Path) -> list[str]:
    extra = command.rewrite if command.empties else ()
    return [*command.args(inputs, out), *extra]


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: c.name)
def test_killed_then_rerun_equals_an_uninterrupted_run(
    command: Command, inputs: Inputs, tmp_path: Path
) -> None:
    rng = np.random.default_rng(zlib.crc32(command.name.encode()))
    ref_out, ref_cache = output_path(command, tmp_path / "ref"), tmp_path / "ref-cache"
    t0 = time.monotonic()
    reference_run = invoke_ok(command.args(inputs, ref_out), cache=ref_cache)
    duration = time.monotonic() - t0
    reference = _outputs(command, ref_out, ref_cache)
    assert reference

    out, cache = output_path(command, tmp_path / "run"), tmp_path / "cache"
    for i, share in enumerate(rng.uniform(0.2, 1.0, KILLS)):
        args = command.args(inputs, out) if i == 0 else _rerun_args(command, inputs, out)
        kill_forked(args, cache=cache, after=share * duration)
        _assert_whole(command, _outputs(command, out, cache), reference)
    final = invoke_ok(_rerun_args(command, inputs, out), cache=cache)
    assert not temporaries(out.parent) and not temporaries(cache)
    got = _outputs(command, out, cache)
    assert set(got) == set(reference)
    _assert_whole(command, got, reference)
    if command.output == "cache":
        assert json_results(final.stdout) == json_results(reference_run.stdout)


def test_a_dead_writers_cache_temporary_is_removed_and_a_live_ones_kept(
    inputs: Inputs, tmp_path: Path
) -> None:
    """The caches have no folder lock: a temporary file counts as dead when its flock is free."""
    cache = tmp_path / "cache"
    cache.mkdir()
    dead = cache / ".features-0.npz.0123456789ab.tmp"
    live = cache / ".features-1.npz.ba9876543210.tmp"
    dead.write_bytes(b"half an entr")
    live.write_bytes(b"being written")
    with open(live, "rb") as held:
        fcntl.flock(held.fileno(), fcntl.LOCK_EX)  # as a running writer holds it
        invoke_ok(BY_NAME["score"].args(inputs, tmp_path), cache=cache)
        assert not dead.exists() and live.read_bytes() == b"being written"
