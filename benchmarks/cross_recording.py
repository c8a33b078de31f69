"""Roads never seen: the leave-one-recording-out table over the shared recordings, timed.

Two ``qdcnn evaluate`` runs, each from an empty cache unless ``--cache`` is given (so the
time includes decoding, shadow removal and lane features):

1. ``--protocol leave-one-out`` over the three simulator recordings: each is the test set
   in turn, the model trained on the other two (lane methods with the inner contiguous
   search, gap 5). Labels: each recording's own unit and the unit's default threshold
   (0.05 of full lock for the simulator), the definition of the paper's Table I.
2. The real dashcam sample as a test set, trained on all three simulator recordings, with
   the threshold at the 33rd percentile of |smoothed steering| of the TRAINING frames
   (``@threshold=p33``): at the default threshold 889 of its 1,000 frames are "straight".
   Its steering is positive to the left (``left=positive``); the results kept from before
   5cc9212 took it the other way, so its left and right labels were swapped there.

Each run's JSON lines (predictions left out) and wall time go to ``--out``; ``--table``
prints README's Markdown tables from those files without recomputing anything::

    python benchmarks/cross_recording.py --data-root ../shared/data
    python benchmarks/cross_recording.py --table

With ``--cache DIR`` a stopped run resumes where it stopped (results are cached per
method, fold, seed and test recording); its wall time is then not a cold-start time, and
``timing.json`` says so.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from qdcnn.direction.scores import format_metric
from readme_tables import markdown_table

SIMULATOR = ["udacity-lake-track", "udacity-mountain-track", "udacity-dark-mountain-track"]
REAL = "real-dashcam-sample"
METHODS = [
    "image-split-uu",
    "kmeans-uu",
    "spectral-uu",
    "image-split-vqc",
    "kmeans-vqc",
    "spectral-vqc",
    "lines-logreg",
    "hog-logreg",
    "dnn-pilotnet",
]
BULKY = ("predictions", "test_labels")


def runs(root: Path) -> dict[str, list[str]]:
    """The evaluate arguments of each run, by name."""
    sims = [f"udacity:{root / name}" for name in SIMULATOR]
    loo = ["--protocol", "leave-one-out", *(a for s in sims for a in ("--data", s))]
    p33 = [f"{s}@threshold=p33" for s in sims]
    real = [*(a for s in p33 for a in ("--train", s))]
    real += ["--test", f"udacity:{root / REAL}@unit=rad,threshold=p33,left=positive"]
    return {"leave-one-out": loo, "real-sample": real}


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def lighten(item: dict[str, Any]) -> dict[str, Any]:
    """``item`` without its per-frame lists."""
    return {k: v for k, v in item.items() if k not in BULKY}


def run_one(
    name: str,
    args: list[str],
    out: Path,
    cache: Path,
    common: list[str],
    light: Callable[[dict[str, Any]], dict[str, Any]] = lighten,
) -> tuple[float, float]:
    """Run one evaluation, keep its JSON lines (lighter); its wall and CPU seconds.

    The CPU seconds (user + system of the evaluation and its workers) say what the run
    costs on a machine shared with other work, where the wall time says mostly how busy
    the machine was.
    """
    command = ["qdcnn", "evaluate", *args, *common, "--paired", "--json"]
    print(f"{name}: {' '.join(command)}", file=sys.stderr, flush=True)
    env = {**os.environ, "QDCNN_CACHE": str(cache)}
    start, cpu = time.perf_counter(), _children_cpu()
    done = subprocess.run(command, env=env, stdout=subprocess.PIPE, text=True, check=False)
    seconds, cpu = time.perf_counter() - start, _children_cpu() - cpu
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.strip()]
    text = "".join(json.dumps(light(item)) + "\n" for item in lines)
    (out / f"{name}.jsonl").write_text(text, encoding="utf-8")
    if done.returncode != 0:
        print(f"{name}: exit {done.returncode}", file=sys.stderr)
    return seconds, cpu


def measure(args: argparse.Namespace) -> None:
    """Run the chosen evaluations; each adds its times to ``timing.json`` when it ends."""
    out, cache, methods = args.out, args.cache, args.methods.split(",")
    out.mkdir(parents=True, exist_ok=True)
    common = ["--method", ",".join(methods), "--threads", str(args.threads), "--seeds", "1"]
    chosen = {k: v for k, v in runs(args.data_root).items() if k in args.runs.split(",")}
    with tempfile.TemporaryDirectory() as scratch:
        where = cache or Path(scratch)
        for name, run_args in chosen.items():
            cold = not where.exists() or not any(where.iterdir())
            wall, cpu = run_one(name, run_args, out, where, common)
            _record(out / "timing.json", name, methods, args.threads, cold, wall, cpu)


def _record(
    path: Path,
    name: str,
    methods: list[str],
    threads: int,
    cold: bool | None,
    wall: float,
    cpu: float,
    load: bool = True,
    **extra: Any,
) -> None:
    timing = json.loads(path.read_text(encoding="utf-8")) if path.exists() else {}
    timing[name] = {
        "methods": methods,
        "threads": threads,
        "cpus": os.cpu_count(),
        "wall_seconds": round(wall, 1),
        "cpu_seconds": round(cpu, 1),
        **extra,
    }
    if cold is not None:  # None: a cache shared with other runs, so no single answer
        timing[name]["cold_cache"] = cold
    if load:  # the machine's load as the run ended
        timing[name]["load_average_after"] = os.getloadavg()
    path.write_text(json.dumps(timing, indent=2) + "\n", encoding="utf-8")


def read(path: Path) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Method results and paired comparisons of one run's JSON lines."""
    results, comparisons = [], []
    for line in path.read_text(encoding="utf-8").splitlines():
        item = json.loads(line)
        if "method" in item:
            results.append(item)
        comparisons += item.get("comparisons", [])
    return results, comparisons


def _cell(r: dict[str, Any]) -> str:
    ba, acc = format_metric(r, "balanced_accuracy"), format_metric(r, "accuracy")
    return f"{ba} ({acc})"


def table(results: list[dict[str, Any]]) -> str:
    """Balanced accuracy [95 % interval] (accuracy [interval]): a row per method and test set."""
    tests = list(dict.fromkeys(r["dataset"] for r in results))
    cells = {(r["method"], r["dataset"]): r for r in results}
    rows = []
    for m in dict.fromkeys(r["method"] for r in results):
        rows.append([m, *(_cell(cells[m, t]) if (m, t) in cells else "" for t in tests)])
    majority = {r["dataset"]: r["majority"] for r in results}
    rows.append(
        [
            "majority class of the training recordings",
            *(
                f"{majority[t]['balanced_accuracy']:.2f} ({majority[t]['accuracy']:.2f})"
                for t in tests
            ),
        ]
    )
    rows.append(["chance", *("0.33" for _ in tests)])
    trained = {r["dataset"]: ", ".join(r["trained_on"]) for r in results}
    header = ["method", *(f"{t} (trained on {trained[t]})" for t in tests)]
    return markdown_table(header, rows)


def difference_table(comparisons: list[dict[str, Any]]) -> str:
    """Each method's balanced accuracy minus the first method's, paired, with its interval."""
    tests = list(dict.fromkeys(c["dataset"] for c in comparisons))
    cells = {(c["a"], c["dataset"]): c["text"] for c in comparisons}
    first = comparisons[0]["b"] if comparisons else ""
    names = dict.fromkeys(c["a"] for c in comparisons)
    rows = [[f"{a} - {first}", *(cells.get((a, t), "") for t in tests)] for a in names]
    return markdown_table(["paired difference", *tests], rows)


def labels_line(results: list[dict[str, Any]]) -> str:
    """One line per test recording: how its labels were made and its class balance."""
    seen = {}
    for r in results:
        info = r["labels"].get(r["dataset"], {})
        balance = info.get("class_balance")
        seen[r["dataset"]] = f"- {r['dataset']}: {info.get('description', '')}; {balance}"
    return "\n".join(seen.values())


def print_tables(out: Path) -> None:
    timing = json.loads((out / "timing.json").read_text(encoding="utf-8"))
    for name, t in timing.items():
        results, comparisons = read(out / f"{name}.jsonl")
        print(f"\n{name} (measured: {t['wall_seconds']} s wall, {t['cpu_seconds']} s CPU):\n")
        print(table(results))
        print()
        print(difference_table(comparisons))
        print()
        print(labels_line(results))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-root", type=Path, default=Path("../shared/data"))
    parser.add_argument("--out", type=Path, default=Path("docs/results/cross-recording"))
    parser.add_argument("--methods", default=",".join(METHODS))
    parser.add_argument("--cache", type=Path, help="a lasting cache: a stopped run resumes")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--runs", default="leave-one-out,real-sample")
    parser.add_argument("--table", action="store_true", help="only print the tables")
    args = parser.parse_args()
    if not args.table:
        measure(args)
    print_tables(args.out)


if __name__ == "__main__":
    main()
