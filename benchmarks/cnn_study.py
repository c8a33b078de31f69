"""CNN baselines study: PilotNet under contiguous folds, ResNet-50 cost, inference frames/s.

Four parts, each optional:

0. ``dev`` (not run by default): how training settings were chosen without test folds.
   For outer contiguous fold k, the model trains on the frames outside folds k and k+1
   (gap 5 around each) and is scored on fold k+1 only, never on fold k; mean over k.
   ``--dev-set NAME:KEY=JSON,KEY=JSON`` adds a variant (repeatable); ``--dev-data`` picks
   the recording (default: mountain, so the lake and synthetic sets stay for confirming).
1. ``pilotnet``: :func:`qdcnn.experiments.evaluate.evaluate_frames` with PilotNet on each
   dataset (5 contiguous folds, gap 5, the classifier's defaults): accuracy mean and std over
   folds, majority baseline, per-class recall, pooled confusion matrix, wall time.
2. ``resnet``: seconds per training frame of ResNet-50 (224x224 input, one epoch over
   ``--resnet-frames`` frames of the first dataset, no validation), extrapolated to the
   paper's 25 epochs x 5 folds on each dataset. ``--resnet-fold-epochs N`` also trains it
   for N epochs on the last contiguous fold of ``--resnet-fold-data`` and tests it there
   (``--weights``: a local torchvision ImageNet file; none ships, so by default from scratch).
3. ``fps``: :func:`qdcnn.models.training.inference_fps` of both networks on 320x160 frames.

Everything runs on ``--threads`` torch CPU threads (default 1). Datasets default to the
recordings in ``../shared/data`` beside the repository and ``synthetic:track2:600``.

Usage::

    python benchmarks/cnn_study.py [--parts pilotnet,resnet,fps] [--data NAME=SPEC ...]
        [--epochs 25] [--threads 1] [--set KEY=JSON ...] [--json results.json]

PilotNet on the lake track (5,113 frames) takes about an hour on one loaded CPU core.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path
from typing import Any

import numpy as np

from qdcnn.config import PipelineConfig
from qdcnn.data.frames import load_frameset, stack_images
from qdcnn.data.labels import DIRECTIONS
from qdcnn.direction.methods import TrainingOptions
from qdcnn.direction.protocol import ContiguousKFold
from qdcnn.experiments.evaluate import evaluate_frames
from qdcnn.models.training import CNNDirectionClassifier, inference_fps

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
DEFAULT_DATA = (
    f"lake=udacity:{SHARED / 'udacity-lake-track'}",
    f"mountain=udacity:{SHARED / 'udacity-mountain-track'}",
    "synthetic-track2=synthetic:track2:600",
)
PAPER_EPOCHS, PAPER_FOLDS = 25, 5


def parse_pairs(items: list[str], what: str) -> dict[str, str]:
    pairs = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise SystemExit(f"{what}: expected KEY=VALUE, got {item!r}")
        pairs[key] = value
    return pairs


def dev_part(
    datasets: dict[str, str], args: argparse.Namespace, variants: dict[str, dict[str, Any]]
) -> dict[str, Any]:
    spec = datasets.get(args.dev_data, args.dev_data)
    frames = load_frameset(spec, seed=args.seed)
    images, readable, _ = stack_images(frames)
    labels = frames.labels()[readable]
    images = images[readable]
    folds = list(ContiguousKFold(args.folds, args.gap).split(labels))
    out: dict[str, Any] = {}
    for name, settings in variants.items():
        accs = []
        t0 = time.perf_counter()
        for k, (train, _) in enumerate(folds):
            _, dev = folds[(k + 1) % len(folds)]
            lo, hi = dev[0] - args.gap, dev[-1] + args.gap
            inner = train[(train < lo) | (train > hi)]
            clf = CNNDirectionClassifier(
                "pilotnet",
                epochs=args.epochs,
                num_threads=args.threads,
                seed=args.seed,
                progress=False,
                **settings,
            ).fit(images[inner], labels[inner])
            accs.append(float(np.mean(clf.predict(images[dev]) == labels[dev])))
        out[name] = {"settings": settings, "dev_accuracies": accs}
        print(
            f"dev {frames.name} {name:12s} {np.mean(accs):.3f} ± {np.std(accs):.3f}  "
            f"{[round(a, 3) for a in accs]}  {settings}  {time.perf_counter() - t0:.0f} s",
            flush=True,
        )
    return out


def parse_variant(text: str) -> tuple[str, dict[str, Any]]:
    name, _, body = text.partition(":")
    pairs = parse_pairs([p for p in body.split(",") if p], "--dev-set")
    return name, {k: json.loads(v) for k, v in pairs.items()}


def pilotnet_part(
    datasets: dict[str, str], args: argparse.Namespace, params: dict[str, Any]
) -> list[dict[str, Any]]:
    rows = []
    for name, spec in datasets.items():
        frames = load_frameset(spec, seed=args.seed)
        labels = frames.labels()
        t0 = time.perf_counter()
        options = TrainingOptions(epochs=args.epochs, threads=args.threads, params=params)
        res, _ = evaluate_frames(
            "dnn-pilotnet",
            frames,
            labels,
            config=PipelineConfig(seed=args.seed),
            options=options,
            folds=args.folds,
            gap=args.gap,
        )
        wall = time.perf_counter() - t0
        row = {"dataset": name, "spec": spec, "wall_s": wall, **res.to_dict()}
        row.pop("failures", None)
        rows.append(row)
        recall = " / ".join(f"{res.per_class[d]['recall']:.2f}" for d in DIRECTIONS)
        print(
            f"{name:18s} n={res.n:5d}  acc {res.accuracy:.3f} ± {res.accuracy_std:.3f}  "
            f"majority {res.majority_baseline:.3f}  recall L/S/R {recall}  "
            f"folds {[round(a, 3) for a in res.fold_accuracies]}  "
            f"epochs run {res.extra['epochs_run']}  wall {wall:.0f} s",
            flush=True,
        )
        print(f"{'':18s} confusion (rows true L/S/R, columns predicted): {res.confusion}")
    return rows


def resnet_part(datasets: dict[str, str], args: argparse.Namespace) -> dict[str, Any]:
    name, spec = next(iter(datasets.items()))
    frames = load_frameset(spec, seed=args.seed)
    images, readable, _ = stack_images(frames)
    labels = frames.labels()[readable]
    images = images[readable]
    idx = np.linspace(0, len(labels) - 1, min(args.resnet_frames, len(labels))).astype(int)
    clf = CNNDirectionClassifier(
        "resnet50",
        epochs=1,
        batch_size=16,
        val_fraction=0.0,
        device="cpu",
        num_threads=args.threads,
        seed=args.seed,
        progress=False,
    )
    t0, c0 = time.perf_counter(), time.process_time()
    clf.fit(images[idx], labels[idx])
    per_frame = (time.perf_counter() - t0) / len(idx)
    cpu_per_frame = (time.process_time() - c0) / len(idx)
    out: dict[str, Any] = {
        "frames_timed": len(idx),
        "train_wall_s_per_frame": per_frame,
        "train_cpu_s_per_frame": cpu_per_frame,
        "from": name,
    }
    print(
        f"ResNet-50 training, {len(idx)} frames of {name}, one epoch: {per_frame:.3f} s/frame "
        f"wall, {cpu_per_frame:.3f} s/frame CPU (the wall time on an otherwise idle core)"
    )
    for dname, dspec in datasets.items():
        n = len(load_frameset(dspec, seed=args.seed))
        train_frames = n * (PAPER_FOLDS - 1) / PAPER_FOLDS
        hours = cpu_per_frame * train_frames * PAPER_EPOCHS * PAPER_FOLDS / 3600
        out[f"paper_protocol_cpu_hours_{dname}"] = hours
        print(
            f"  {dname}: {PAPER_EPOCHS} epochs x {PAPER_FOLDS} folds on {train_frames:.0f} "
            f"training frames ~ {hours:.1f} h of one core"
        )
    if args.resnet_fold_epochs:
        out["one_fold"] = resnet_one_fold(datasets, args)
    return out


def resnet_one_fold(datasets: dict[str, str], args: argparse.Namespace) -> dict[str, Any]:
    """ResNet-50 on the last of the contiguous folds only, for a few epochs."""
    spec = datasets.get(args.resnet_fold_data, args.resnet_fold_data)
    frames = load_frameset(spec, seed=args.seed)
    images, readable, _ = stack_images(frames)
    labels = frames.labels()[readable]
    images = images[readable]
    train, test = list(ContiguousKFold(args.folds, args.gap).split(labels))[-1]
    clf = CNNDirectionClassifier(
        "resnet50",
        epochs=args.resnet_fold_epochs,
        patience=0,
        device="cpu",
        num_threads=args.threads,
        seed=args.seed,
        progress=False,
        weights=args.weights,
    )
    t0, c0 = time.perf_counter(), time.process_time()
    clf.fit(images[train], labels[train])
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    acc = float(np.mean(clf.predict(images[test]) == labels[test]))
    majority = float(np.mean(labels[test] == np.bincount(labels[train], minlength=3).argmax()))
    print(
        f"  ResNet-50, last fold of {frames.name} ({len(train)} training frames), "
        f"{args.resnet_fold_epochs} epochs, weights {args.weights}: accuracy {acc:.3f} "
        f"(majority {majority:.3f}); {wall:.0f} s wall, {cpu:.0f} s CPU"
    )
    return {
        "data": frames.name,
        "epochs": args.resnet_fold_epochs,
        "train_frames": len(train),
        "test_frames": len(test),
        "accuracy": acc,
        "majority": majority,
        "wall_s": wall,
        "cpu_s": cpu,
        "history": clf.history_,
    }


def fps_part(args: argparse.Namespace) -> dict[str, float]:
    out = {}
    for arch, n in (("pilotnet", 512), ("resnet50", 64)):
        for clock in ("wall", "cpu"):
            fps = max(
                inference_fps(
                    arch,  # type: ignore[arg-type]
                    n=n,
                    size=(160, 320),
                    batch_size=32,
                    num_threads=args.threads,
                    clock=clock,
                )
                for _ in range(args.fps_repeats)
            )
            out[f"{arch}_{clock}"] = fps
            print(
                f"inference {arch}: {fps:.1f} frames/s at 320x160 ({clock} clock, "
                f"{args.threads} thread(s), best of {args.fps_repeats})"
            )
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="pilotnet,resnet,fps")
    parser.add_argument("--data", nargs="*", default=list(DEFAULT_DATA), help="NAME=SPEC")
    parser.add_argument("--epochs", type=int, default=PAPER_EPOCHS)
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--gap", type=int, default=5)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", nargs="*", default=[], help="classifier KEY=JSON, e.g. tta=false")
    parser.add_argument("--dev-data", default="mountain")
    parser.add_argument(
        "--dev-set",
        nargs="*",
        default=["defaults:"],
        help="NAME:KEY=JSON,... classifier variants for the dev part",
    )
    parser.add_argument("--resnet-frames", type=int, default=48)
    parser.add_argument("--resnet-fold-epochs", type=int, default=0)
    parser.add_argument("--resnet-fold-data", default="synthetic-track2")
    parser.add_argument("--weights", type=Path, default=None, help="ImageNet ResNet-50 file")
    parser.add_argument("--fps-repeats", type=int, default=3)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()

    datasets = parse_pairs(args.data, "--data")
    params = {k: json.loads(v) for k, v in parse_pairs(args.set, "--set").items()}
    parts = set(args.parts.split(","))
    report: dict[str, Any] = {
        "machine": platform.processor() or platform.machine(),
        "args": {k: str(v) if isinstance(v, Path) else v for k, v in vars(args).items()},
    }
    if "dev" in parts:
        report["dev"] = dev_part(datasets, args, dict(parse_variant(v) for v in args.dev_set))
    if "pilotnet" in parts:
        report["pilotnet"] = pilotnet_part(datasets, args, params)
    if "resnet" in parts:
        report["resnet50"] = resnet_part(datasets, args)
    if "fps" in parts:
        report["inference_fps"] = fps_part(args)
    if args.json is not None:
        args.json.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
