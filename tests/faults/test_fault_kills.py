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

import fcntl
import os
import time
import zlib
from pathlib import Path

import numpy as np
import pytest
from fault_support import (
    BY_NAME,
    COMMANDS,
    Command,
    Inputs,
    assert_whole,
    build_inputs,
    invoke_ok,
    json_results,
    kill_forked,
    output_path,
    outputs_of,
    temporaries,
)

KILLS = 2


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Inputs:
    return build_inputs(tmp_path_factory)


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
    reference = outputs_of(command, ref_out, ref_cache)
    assert reference

    out, cache = output_path(command, tmp_path / "run"), tmp_path / "cache"
    for i, share in enumerate(rng.uniform(0.2, 1.0, KILLS)):
        args = command.args(inputs, out) if i == 0 else _rerun_args(command, inputs, out)
        kill_forked(args, cache=cache, after=share * duration)
        assert_whole(command, outputs_of(command, out, cache), reference)
    final = invoke_ok(_rerun_args(command, inputs, out), cache=cache)
    assert not temporaries(out.parent) and not temporaries(cache)
    got = outputs_of(command, out, cache)
    assert set(got) == set(reference)
    assert_whole(command, got, reference)
    if command.output == "cache":
        assert json_results(final.stdout) == json_results(reference_run.stdout)


def test_a_dead_writers_cache_temporary_is_removed_and_a_live_ones_kept(
    inputs: Inputs, tmp_path: Path
) -> None:
    """The caches have no output-folder lock: a writer holds a shared flock on the folder
    while its temporary file exists, so temporaries are removed only when no writer is live."""
    cache = tmp_path / "cache"
    cache.mkdir()
    dead = cache / ".features-0.npz.0123456789ab.tmp"
    live = cache / ".features-1.npz.ba9876543210.tmp"
    dead.write_bytes(b"half an entr")
    live.write_bytes(b"being written")
    held = os.open(cache, os.O_RDONLY)
    try:
        fcntl.flock(held, fcntl.LOCK_SH)  # as a running writer holds it
        invoke_ok(BY_NAME["score"].args(inputs, tmp_path), cache=cache)
        assert dead.exists() and live.read_bytes() == b"being written"
    finally:
        os.close(held)  # the writer ends: both files are now a dead writer's
    for entry in cache.glob("features-*.npz"):
        entry.unlink()  # so the next run writes an entry again, which removes dead temporaries
    invoke_ok(BY_NAME["score"].args(inputs, tmp_path), cache=cache)
    assert not dead.exists() and not live.exists()
