"""What the A/B benchmarks share: two code paths timed in turns, and their command line.

``bench_road_fill.py`` and ``bench_calibration.py`` time a compiled kernel against its NumPy
path pass for pass, in the order kernel, NumPy, NumPy, kernel, ... (ABBA), so a drift of the
machine during the run weighs on both alike.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
from collections.abc import Callable, Sequence
from typing import Any


def turn_name(turn: int, names: Sequence[str]) -> str:
    """The path timed in ``turn`` (0, 1, 2, ...): ``names[0]``, ``names[1]``, ``names[1]``,
    ``names[0]``, then again."""
    first = turn % 2 if (turn // 2) % 2 == 0 else 1 - turn % 2
    return names[first]


def size_row(
    size: tuple[int, int], times: dict[str, list[float]], unit: str, digits: int, **extra: Any
) -> dict[str, Any]:
    """One frame size's row: the medians over the passes (under ``unit``), every pass
    (rounded to ``digits``) and the NumPy path's median over the kernel's."""
    medians = {name: statistics.median(t) for name, t in times.items()}
    return {
        "size": list(size),
        **extra,
        unit: medians,
        "passes": {name: [round(t, digits) for t in ts] for name, ts in times.items()},
        "numpy_over_kernel": medians["numpy"] / medians["kernel"],
    }


def measured(what: str, frames: int, one_core: bool, rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The benchmark's JSON: measured times, what was timed, on how many frames, the rows."""
    return {
        "kind": "measured",
        "what": what,
        "frames": frames,
        "one_core": one_core,
        "machine": {"python": platform.python_version()},
        "rows": rows,
    }


def parse_size(text: str) -> tuple[int, int]:
    """``"320x160"`` -> ``(320, 160)``."""
    w, _, h = text.partition("x")
    return int(w), int(h)


def main(
    doc: str | None,
    bench: Callable[[list[tuple[int, int]], int, int], dict[str, Any]],
    defaults: tuple[int, int, str],
    describe: Callable[[dict[str, Any]], str],
) -> None:
    """``--json`` / ``--passes`` / ``--frames`` / ``--sizes`` (``defaults``: passes, frames,
    sizes), then ``bench`` and either its JSON or one line per row (``describe``)."""
    passes, frames, sizes = defaults
    parser = argparse.ArgumentParser(description=doc.splitlines()[0] if doc else None)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--passes", type=int, default=passes)
    parser.add_argument("--frames", type=int, default=frames)
    parser.add_argument("--sizes", default=sizes)
    args = parser.parse_args()
    result = bench([parse_size(s) for s in args.sizes.split(",")], args.passes, args.frames)
    if args.json:
        print(json.dumps(result))
        return
    for row in result["rows"]:
        print(describe(row))
