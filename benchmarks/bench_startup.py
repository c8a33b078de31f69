"""Start-up time of the command line: ``qdcnn --help`` and friends against ``python -c pass``.

Target (issue 18): ``qdcnn --help``, ``qdcnn COMMAND --help`` and an option error return
within 0.5 s. Each time is the **measured** wall-clock time of a fresh interpreter
(``subprocess.run`` from start to exit), the median of ``--runs`` runs (default 10). The
commands run in rounds, one of each per round, so a change of load on a shared machine
touches all of them alike; ``python -c pass`` in the same rounds is the floor any Python
command pays. ``qdcnn`` is run as ``python -m qdcnn`` with this interpreter (what the
``qdcnn`` script does, without the script's own ``python`` lookup). Beside the wall time,
the CPU time of each child (user + system, ``getrusage``) is reported: on a busy machine the
wall time includes waiting for a core, the CPU time does not.

Usage::

    python benchmarks/bench_startup.py [--json] [--runs 10]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from typing import Any

TARGET_SECONDS = 0.5
#: name -> (argv after the interpreter, the exit status it must give).
COMMANDS: dict[str, tuple[tuple[str, ...], int]] = {
    "python -c pass": (("-c", "pass"), 0),
    "qdcnn --help": (("-m", "qdcnn", "--help"), 0),
    "qdcnn evaluate --help": (("-m", "qdcnn", "evaluate", "--help"), 0),
    "qdcnn run --help": (("-m", "qdcnn", "run", "--help"), 0),
    "qdcnn evaluate --bogus": (("-m", "qdcnn", "evaluate", "--bogus"), 2),
}
FLOOR = "python -c pass"


def child_cpu_seconds() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed_run(argv: tuple[str, ...], status: int) -> tuple[float, float]:
    """Measured wall time and CPU time of one run of this interpreter with ``argv``."""
    cpu0 = child_cpu_seconds()
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, *argv], capture_output=True, check=False)
    seconds = time.perf_counter() - t0
    cpu = child_cpu_seconds() - cpu0
    if done.returncode != status:
        raise SystemExit(
            f"{' '.join(argv)}: exit status {done.returncode}, expected {status}\n"
            + done.stderr.decode(errors="replace")
        )
    return seconds, cpu


def measure(runs: int) -> dict[str, Any]:
    """Median and spread per command, in rounds of one run each."""
    times: dict[str, list[tuple[float, float]]] = {name: [] for name in COMMANDS}
    for argv, status in COMMANDS.values():  # one warm-up each: the file cache
        timed_run(argv, status)
    for _ in range(runs):
        for name, (argv, status) in COMMANDS.items():
            times[name].append(timed_run(argv, status))
    floor = statistics.median(wall for wall, _ in times[FLOOR])
    rows = []
    for name, runs_of_name in times.items():
        walls = [wall for wall, _ in runs_of_name]
        median = statistics.median(walls)
        rows.append(
            {
                "command": name,
                "median_seconds": median,
                "min_seconds": min(walls),
                "max_seconds": max(walls),
                "median_cpu_seconds": statistics.median(cpu for _, cpu in runs_of_name),
                "ratio_to_python": median / floor,
                "above_python_seconds": median - floor,
                "within_target": median <= TARGET_SECONDS,
            }
        )
    return {"runs": runs, "rows": rows}


def print_table(result: dict[str, Any]) -> None:
    machine = result["machine"]
    print(
        f"measured wall time, median of {result['runs']} runs; target {TARGET_SECONDS} s; "
        f"{machine['cpus']} CPUs, load average {machine['load_average_at_start'][0]:.2f} "
        f"-> {machine['load_average_at_end'][0]:.2f}"
    )
    print(
        f"{'command':<26} {'median s':>9} {'min s':>7} {'max s':>7} {'x python':>9} "
        f"{'+ s':>7} {'cpu s':>7}"
    )
    for row in result["rows"]:
        print(
            f"{row['command']:<26} {row['median_seconds']:9.3f} {row['min_seconds']:7.3f} "
            f"{row['max_seconds']:7.3f} {row['ratio_to_python']:9.1f} "
            f"{row['above_python_seconds']:7.3f} {row['median_cpu_seconds']:7.3f}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--runs", type=int, default=10, help="runs per command (median)")
    args = parser.parse_args()
    if args.runs < 1:
        parser.error("--runs must be at least 1")
    machine: dict[str, Any] = {
        "python": platform.python_version(),
        "cpus": os.cpu_count(),
        "load_average_at_start": os.getloadavg(),
    }
    result = {"kind": "measured", "target_seconds": TARGET_SECONDS, "machine": machine}
    result.update(measure(args.runs))
    machine["load_average_at_end"] = os.getloadavg()
    if args.json:
        print(json.dumps(result))
    else:
        print_table(result)


if __name__ == "__main__":
    main()
