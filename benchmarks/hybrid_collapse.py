"""Why ``qdcnn-head`` collapses to one class on the lake track, and what ends it (issue 20).

Trains ``qdcnn-head`` (and its classical twin) on a contiguous piece of a recording and
scores it on the block after it (a gap of ``--gap`` frames between), in variants:

* ``old``: the original head (``dressed=False``: ``pi tanh`` encoding, PennyLane's uniform
  ``[0, 2 pi)`` layer angles, the fixed read-out gain 10) and the original trainer
  (unweighted loss, epoch kept by validation loss, no restart);
* ``dressed``: the dressed head (bounded trainable input scale, near-identity start,
  trainable output scale and bias) with the original trainer;
* ``new``: the dressed head with the new trainer (class-balanced loss, epoch kept by
  validation balanced accuracy, restart with the next seed on a one-class collapse);
* ``transfer``: ``new`` trained in stages (trunk with a linear head, then the head on the
  frozen trunk, then everything at a tenth of the rate);
* each with ``-twin``: the same for the classical twin.

Per epoch it prints the trainer's diagnostics (validation predicted-class counts, gradient
norms of trunk and head, spread of the encoded angles and of ``<Z_i>``), then the test
balanced accuracy and predicted-class counts. Run from the repository root::

    python benchmarks/hybrid_collapse.py --data ../shared/data/udacity-lake-track \\
        --start 0 --stop 1500 --epochs 6 --variants old,new [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import numpy as np

from qdcnn.data.frames import load_frameset
from qdcnn.data.labels import DIRECTIONS
from qdcnn.models.trainer import balanced_accuracy
from qdcnn.models.training import CNNDirectionClassifier

OLD_TRAINER: dict[str, Any] = {"class_weight": None, "select": "loss", "restarts": 0}
NEW_TRAINER: dict[str, Any] = {
    "class_weight": "balanced",
    "select": "balanced_accuracy",
    "restarts": 2,
}
VARIANTS: dict[str, tuple[dict[str, Any], dict[str, Any]]] = {
    "old": ({"dressed": False}, OLD_TRAINER),
    "dressed": ({"dressed": True}, OLD_TRAINER),
    "new": ({"dressed": True}, NEW_TRAINER),
    "transfer": ({"dressed": True}, {**NEW_TRAINER, "transfer": True}),
}


def load_piece(path: str, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
    """Frames ``start:stop`` of a Udacity recording and their direction labels (labels
    from the whole recording's smoothed steering, as ``evaluate`` makes them)."""
    frames = load_frameset(f"udacity:{path}")
    labels = frames.labels()
    rows = range(start, min(stop, len(frames)))
    return np.stack([frames.image(i) for i in rows]), labels[rows.start : rows.stop]


def describe_epoch(record: dict[str, Any]) -> str:
    def f(key: str) -> str:
        value = record.get(key)
        return "-" if value is None else f"{value:.3g}"

    return (
        f"  {record.get('stage', ''):9s} ep {record['epoch']:2d} loss {f('train_loss')} "
        f"val bal {f('val_balanced_accuracy')} pred {record['val_predictions']} "
        f"|g| trunk {f('grad_norm_trunk')} head {f('grad_norm_head')} "
        f"angle std {f('angle_std')} [{f('angle_min')}, {f('angle_max')}] "
        f"<Z> std {f('feature_std')} [{f('feature_min')}, {f('feature_max')}]"
    )


def run_variant(
    name: str, x: np.ndarray, y: np.ndarray, test: slice, train: slice, args: argparse.Namespace
) -> dict[str, Any]:
    base, _, twin = name.partition("-")
    network, trainer = VARIANTS[base]
    params = {**network, "head": "classical" if twin else "quantum"}
    clf = CNNDirectionClassifier(
        "qdcnn-head",
        epochs=args.epochs,
        seed=args.seed,
        num_threads=args.threads,
        device="cpu",
        progress=False,
        network_params=params,
        **trainer,
    )
    t0 = time.perf_counter()
    clf.fit(x[train], y[train])
    seconds = time.perf_counter() - t0
    predicted = clf.predict(x[test])
    counts = np.bincount(predicted, minlength=3).tolist()
    out = {
        "variant": name,
        "network_params": params,
        "trainer": trainer,
        "test_balanced_accuracy": balanced_accuracy(y[test], predicted),
        "test_accuracy": float(np.mean(predicted == y[test])),
        "test_predictions": dict(zip(DIRECTIONS, counts, strict=True)),
        "best_epoch": clf.best_epoch_,
        "restarts": clf.restarts_,
        "seed_used": clf.seed_,
        "train_seconds": seconds,
        "history": clf.history_,
    }
    print(f"{name}: {seconds:.0f} s, restarts {clf.restarts_}", flush=True)
    for record in clf.history_:
        print(describe_epoch(record), flush=True)
    print(
        f"  -> kept epoch {clf.best_epoch_}; test balanced accuracy "
        f"{out['test_balanced_accuracy']:.3f}, accuracy {out['test_accuracy']:.3f}, "
        f"predictions {out['test_predictions']}",
        flush=True,
    )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default="../shared/data/udacity-lake-track")
    parser.add_argument("--start", type=int, default=0)
    parser.add_argument("--stop", type=int, default=1500)
    parser.add_argument("--test-fraction", type=float, default=0.2)
    parser.add_argument("--gap", type=int, default=5)
    parser.add_argument("--epochs", type=int, default=6)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--variants", default="old,old-twin,new,new-twin")
    parser.add_argument("--json", default=None, help="Write the results (with histories) here.")
    args = parser.parse_args()
    x, y = load_piece(args.data, args.start, args.stop)
    n_test = round(len(y) * args.test_fraction)
    train, test = slice(0, len(y) - n_test - args.gap), slice(len(y) - n_test, len(y))
    train_counts = np.bincount(y[train], minlength=3).tolist()
    test_counts = np.bincount(y[test], minlength=3).tolist()
    print(
        f"{args.data} frames {args.start}..{args.start + len(y) - 1}: train {train_counts} "
        f"test {test_counts} (left, straight, right), {args.epochs} epochs, seed {args.seed}",
        flush=True,
    )
    results = [
        run_variant(v.strip(), x, y, test, train, args)
        for v in args.variants.split(",")
        if v.strip()
    ]
    if args.json:
        from qdcnn._fileio import atomic_write_text

        payload = {"args": vars(args), "train_counts": train_counts, "test_counts": test_counts}
        atomic_write_text(args.json, json.dumps({**payload, "results": results}, indent=1))


if __name__ == "__main__":
    main()
