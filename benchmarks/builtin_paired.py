"""Paired comparison of two built-in recipes scored leave-one-recording-out.

Reads two results files of ``benchmarks/train_builtin.py`` (``docs/results/builtin-*.json``,
which keep the per-frame predictions) and prints, for every recording both left out, the
first recipe's balanced accuracy minus the second's on the same left-out frames, with a
paired block-bootstrap interval (a file scored with several seeds counts their mean)::

    python benchmarks/builtin_paired.py docs/results/builtin-recipe-colour-fdbaddb.json \\
        docs/results/builtin-model.json

A results file of ``builtin_nested.py`` counts its outer scores (the chosen recipes').
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np


def left_out_rows(path: Path) -> dict[str, dict[str, Any]]:
    """Per left-out recording, the recipe's (first) row of a results file (of
    ``train_builtin.py``, or the outer rows of ``builtin_nested.py``)."""
    data = json.loads(path.read_text())
    if "leave_one_out_rows" not in data:
        return {test: entry["outer"] for test, entry in data["outer"].items() if "outer" in entry}
    return {test: methods[0] for test, methods in data["leave_one_out_rows"].items()}


def paired_rows(a: Path, b: Path) -> list[dict[str, Any]]:
    """``a``'s recipe minus ``b``'s, per recording both left out, on the same frames."""
    from qdcnn.direction.scores import format_with_interval, paired_difference

    rows_a, rows_b = left_out_rows(a), left_out_rows(b)
    out = []
    for test in [t for t in rows_a if t in rows_b]:
        ra, rb = rows_a[test], rows_b[test]
        labels = np.asarray(ra["test_labels"]).ravel()
        if not np.array_equal(labels, np.asarray(rb["test_labels"]).ravel()):
            out.append({"left_out": test, "text": "not paired: the files label it differently"})
            continue
        runs_a, runs_b = (np.asarray(r["predictions"]).reshape(-1, labels.size) for r in (ra, rb))
        d = paired_difference(labels, runs_a, runs_b, seed=0)
        text = ("" if d.value < 0 else "+") + format_with_interval(d.value, d.interval)
        out.append({"left_out": test, **d.to_dict(), "text": text})
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("a", type=Path, help="results JSON of the first recipe")
    parser.add_argument("b", type=Path, help="results JSON of the second recipe")
    args = parser.parse_args()
    for row in paired_rows(args.a, args.b):
        print(f"{row['left_out']}: {row['text']}")


if __name__ == "__main__":
    main()
