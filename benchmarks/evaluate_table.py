"""A Markdown table of ``qdcnn evaluate --json`` outputs: a row per method, a column per dataset.

README's CNN and hybrid rows are this script's output for the files that

    qdcnn evaluate --data udacity:PATH --method METHOD --threads 1 --json > OUT.json

wrote (one file per run, or several methods in one file: one JSON object per line).
Each cell is the pooled accuracy under the contiguous folds +- the spread of the fold
accuracies; the last row is the majority class of the training folds. Nothing is
recomputed. (Training times are left out: these runs share a busy machine; the epoch
times of ``benchmarks/bench_hybrid.py`` are the measured ones.)

    python benchmarks/evaluate_table.py OUT.json [OUT2.json ...]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from readme_tables import markdown_table


def read_results(paths: list[Path]) -> list[dict[str, Any]]:
    """Every per-method result line of the files (summary lines are skipped)."""
    rows = []
    for path in paths:
        for line in path.read_text(encoding="utf-8").splitlines():
            item = json.loads(line) if line.strip() else {}
            if "method" in item and "accuracy" in item:
                rows.append(item)
    return rows


def table(results: list[dict[str, Any]]) -> str:
    datasets = list(dict.fromkeys(r["dataset"] for r in results))
    methods = list(dict.fromkeys(r["method"] for r in results))
    cells = {(r["method"], r["dataset"]): r for r in results}
    rows = []
    for m in methods:
        row = [m]
        for d in datasets:
            r = cells.get((m, d))
            row.append("" if r is None else f"{r['accuracy']:.3f} ± {r['accuracy_std']:.3f}")
        rows.append(row)
    majority = {r["dataset"]: r["majority_baseline"] for r in results}
    rows.append(["majority class of the training folds", *(f"{majority[d]:.3f}" for d in datasets)])
    return markdown_table(["method", *datasets], rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+", type=Path)
    print(table(read_results(parser.parse_args().files)))


if __name__ == "__main__":
    main()
