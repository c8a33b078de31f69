"""The killed-worker test of the video runner, many times in a row beside a busy process.

Each round runs ``test_local_cluster_with_a_killed_worker_gives_identical_output`` of
``tests/runtime/test_engine.py`` (a ``local:2`` Dask cluster; a worker killed early,
mid-run and late; output byte-identical to an in-process run) in a fresh pytest process,
while a process of this script spins on one core (the test starts another beside its
cluster). Prints each round's result and **measured** wall time, then how many passed.
Not part of the test suite (issue 21).

Usage::

    python benchmarks/killed_worker_loop.py [--rounds 20]
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TEST = (
    "tests/runtime/test_engine.py::test_local_cluster_with_a_killed_worker_gives_identical_output"
)


def spin() -> None:
    while True:
        pass


def one_round() -> tuple[bool, float, str]:
    """Whether the test passed, its wall time (s) and the tail of its output."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", TEST]
    t0 = time.perf_counter()
    proc = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True)
    return proc.returncode == 0, time.perf_counter() - t0, proc.stdout[-2000:]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rounds", type=int, default=20)
    args = parser.parse_args()
    busy = multiprocessing.Process(target=spin, daemon=True)
    busy.start()
    passed = 0
    try:
        for k in range(1, args.rounds + 1):
            ok, seconds, tail = one_round()
            passed += ok
            verdict, load = "pass" if ok else "FAIL", os.getloadavg()[0]
            print(f"round {k:2d}: {verdict} {seconds:6.1f} s (load {load:.1f})", flush=True)
            if not ok:
                print(tail, flush=True)
    finally:
        busy.kill()
        busy.join()
    print(f"{passed}/{args.rounds} passed", flush=True)


if __name__ == "__main__":
    main()
