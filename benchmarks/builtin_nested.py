"""The built-in recipe chosen without the recording it is scored on: nested leave-one-out.

The shipped recipe was chosen among candidates by their leave-one-recording-out scores, so
those scores are a little optimistic for a new recording. Here the choice is part of what is
scored. For each outer recording R:

1. every candidate recipe (:data:`CANDIDATES`: what the network sees) is trained on all
   recordings but R and one inner recording Q, plus the synthetic presets, and scored on Q,
   for every Q other than R (balanced accuracy);
2. the candidate with the highest mean inner balanced accuracy is chosen (ties: the earlier
   in :data:`CANDIDATES`);
3. the chosen candidate is trained on all recordings but R and scored on R.

R takes no part in the choice, so its score estimates what the whole procedure, choice
included, gives on a recording nobody has seen. Data, thinning, labels and training are
``train_builtin.py``'s (one seed: :data:`train_builtin.SEED`). Finished trainings are kept
in the fold-result cache, so a stopped run started again goes on where it stopped; the
results JSON is rewritten after every score.

    python benchmarks/builtin_nested.py --results /tmp/nested.json
    python benchmarks/builtin_nested.py --candidates standardised,edges \\
        --outer udacity-lake-track --results /tmp/nested.json
"""

from __future__ import annotations

import argparse
import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

import train_builtin as tb

#: candidate name -> its variant of the recipe (``train_builtin.VARIANT``); the shipped
#: recipe is "standardised".
CANDIDATES: dict[str, dict[str, Any]] = {
    "plain": {"standardise_frames": False},
    "standardised": {},
    "edges": {"standardise_frames": False, "edge_frames": True},
    "with-edges": {"edge_frames": True},
}


#: What a saved score was trained with; a score trained otherwise is trained again.
TRAINED_BY = ("epochs", "synthetic", "data_root")


@contextmanager
def recipe(variant: dict[str, Any]) -> Iterator[None]:
    """``train_builtin``'s recipe set to ``variant`` while the block runs."""
    saved = dict(tb.VARIANT)
    tb.VARIANT.clear()
    tb.VARIANT.update(variant)
    try:
        yield
    finally:
        tb.VARIANT.clear()
        tb.VARIANT.update(saved)


def score(sets: dict[str, Any], train: list[str], test: str, candidate: str) -> dict[str, Any]:
    """``candidate`` trained on ``train`` (and the presets), scored on ``test``: its row."""
    names = [n for n in sets if n in train or n.startswith("synthetic-")]
    with recipe(CANDIDATES[candidate]):
        _, row = tb.left_out_score(tb.make_parts(sets, names, test), tb.METHOD)
    return row


def choose(means: dict[str, float]) -> str:
    """The candidate with the highest mean inner balanced accuracy (ties: the first)."""
    return max(means, key=means.__getitem__)


def resumed(saved: dict[str, Any], setup: dict[str, Any]) -> dict[str, Any]:
    """What of a saved entry still holds under ``setup``: nothing when it was trained
    otherwise (epochs, presets, data), else the inner scores of the current candidates
    and the outer score (kept only if the choice comes out the same)."""
    before = saved.get("setup", {})
    if any(before.get(k) != setup[k] for k in TRAINED_BY):
        saved = {}
    inner = {c: saved.get("inner", {}).get(c, {}) for c in setup["candidates"]}
    kept = {"outer": saved["outer"]} if "outer" in saved else {}
    return {"setup": setup, "inner": inner, **kept}


def nested(
    sets: dict[str, Any], outer: str, setup: dict[str, Any], saved: dict[str, Any]
) -> Iterator[dict[str, Any]]:
    """The outer recording's entry, yielded after every new score (resumed from ``saved``)."""
    recordings = [n for n in tb.RECORDINGS if n in sets]
    candidates = setup["candidates"]
    entry = resumed(saved, setup)
    for candidate in candidates:
        for q in [n for n in recordings if n != outer]:
            if q in entry["inner"][candidate]:
                continue
            train = [n for n in recordings if n not in (outer, q)]
            row = score(sets, train, q, candidate)
            entry["inner"][candidate][q] = row["balanced_accuracy"]
            yield entry
    entry["inner_mean"] = {c: float(np.mean(list(entry["inner"][c].values()))) for c in candidates}
    entry["chosen"] = choose(entry["inner_mean"])
    if entry.get("outer", {}).get("method_variant") != entry["chosen"]:
        train = [n for n in recordings if n != outer]
        entry["outer"] = {"method_variant": entry["chosen"]}
        entry["outer"].update(score(sets, train, outer, entry["chosen"]))
        yield entry


def report(outer: str, entry: dict[str, Any], fresh: bool) -> str:
    means = ", ".join(f"{c} {v:.3f}" for c, v in entry["inner_mean"].items())
    ba = entry["outer"]["balanced_accuracy"]
    saved = "" if fresh else " (saved)"
    return f"outer {outer}: chose {entry['chosen']} (inner means {means}), BA {ba:.3f}{saved}"


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--data-root", type=Path, default=tb.REPO.parent / "shared" / "data")
    parser.add_argument("--outer", default=",".join(tb.LEAVE_OUT), help="outer recordings")
    parser.add_argument("--candidates", default=",".join(CANDIDATES), help="recipes to choose from")
    parser.add_argument("--results", type=Path, required=True, help="results JSON")
    return parser


def main() -> None:
    parser = _parser()
    args = parser.parse_args()
    candidates = [c for c in args.candidates.split(",") if c]
    outers = [r for r in args.outer.split(",") if r]
    if unknown := [c for c in candidates if c not in CANDIDATES]:
        parser.error(f"--candidates: {', '.join(unknown)} not in {', '.join(CANDIDATES)}")
    if len(candidates) < 2:
        parser.error("--candidates: give at least two recipes to choose from")
    if unknown := [r for r in outers if r not in tb.RECORDINGS]:
        parser.error(f"--outer: {', '.join(unknown)} not in {', '.join(tb.RECORDINGS)}")
    import torch

    from qdcnn._fileio import atomic_write_bytes

    torch.set_num_threads(tb.THREADS)
    os.environ.setdefault("OMP_NUM_THREADS", str(tb.THREADS))
    results: dict[str, Any] = {"recipes": CANDIDATES, "outer": {}}
    if args.results.is_file():
        results["outer"] = json.loads(args.results.read_text()).get("outer", {})
    sets = tb.load_sets(args.data_root)
    if missing := [n for n in tb.RECORDINGS if n not in sets]:
        parser.error(f"--data-root {args.data_root}: no recording named {', '.join(missing)}")
    setup = {
        "candidates": candidates,
        "epochs": tb.training_options().epochs,
        "synthetic": list(tb.SYNTHETIC),
        "data_root": str(args.data_root.resolve()),
        "commit": tb.commit(),
    }
    for outer in outers:
        fresh = False
        for entry in nested(sets, outer, setup, results["outer"].get(outer, {})):
            fresh, results["outer"][outer] = True, entry
            text = json.dumps(results, indent=1, default=tb._plain) + "\n"
            atomic_write_bytes(args.results, text.encode())
        print(report(outer, results["outer"][outer], fresh), flush=True)
    scores = [results["outer"][o]["outer"]["balanced_accuracy"] for o in outers]
    print(f"mean over {len(outers)} outer recordings: BA {np.mean(scores):.3f}", flush=True)


if __name__ == "__main__":
    main()
