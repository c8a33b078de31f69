"""Train the built-in QDCNN model and score its recipe leave-one-recording-out.

The recipe (seed 0, CPU, 2 torch threads)
------------------------------------------
* Method: ``qdcnn-head`` (PilotNet trunk, dressed 4-qubit quantum head) with the hybrid
  trainer's recipe (``HYBRID_RECIPE``: class-balanced loss, epochs selected by validation
  balanced accuracy, restarts when the validation predictions are one class) and the
  two-stage transfer training (``--transfer``: PilotNet first, then the head on the frozen
  trunk, then fine-tuning at a tenth of the rate), :data:`EPOCHS` classical epochs, the
  existing augmentation (flips, brightness, shadows), and every frame put on its own scale
  (``--standardise-frames``: its planes minus their means, over its Y spread, so a road in
  shade looks like one in sun). Stage 1 is PilotNet under the same recipe (``--balanced``):
  a model for recordings it never saw meets other class shares, and balanced accuracy is
  what it is scored by.
* One network (:data:`ENSEMBLE`). ``--ensemble K`` is the variant whose K networks of this
  recipe (seeds 0, 1000, ...) decide by the mean of their class probabilities (``ensemble``
  of :class:`~qdcnn.models.training.CNNDirectionClassifier`); three of them, scored
  leave-one-recording-out at e3080e8, did worse on the real sample and were not shipped
  (docs/builtin-model.md).
* Data: the four recordings of ``../shared/data`` and three synthetic presets. Consecutive
  frames of a recording are near duplicates, so each recording is thinned to one frame in
  ``stride`` (:data:`RECORDINGS`: lake 1 in 13, mountain 1 in 3, dark mountain 1 in 15,
  real sample 1 in 3), about 400 frames each, plus 150 frames of each preset, ~2,000 in
  all; with :data:`EPOCHS` = 15 classical epochs (and 3 + 3 of the later stages) one
  network costs 2-10 minutes of CPU on 2 threads (``--ensemble K``: K times that).
  Labels are made on the whole recording (smoothing as ``qdcnn evaluate`` does) and then
  thinned. The simulator tracks
  keep their own unit and default threshold; the real dashcam sample is
  ``@unit=rad,threshold=p33,left=positive`` (the straight class = the 33 % smallest
  |smoothed steering| of all the TRAINING frames, simulator ones included, as the
  cross-recording protocol resolves it, so it gives three classes; its steering, a ROS
  log's, is positive to the left, the simulator's negative: docs/builtin-model.md).
* Frames are cropped and resized to the network input per recording (the real sample is
  640x480, the simulator 320x160), as ``qdcnn evaluate`` does for a CNN.

Leave-one-recording-out
-----------------------
For each left-out recording (:data:`LEAVE_OUT`, in that order) the same recipe is trained
on the other recordings (thinned as above) plus the synthetic presets, and scored on the
left-out recording with :func:`qdcnn.experiments.evaluate_cross.cross_evaluate` (the
``qdcnn evaluate --train/--test`` protocol: balanced accuracy with 95 % block-bootstrap
intervals). The left-out recording is scored on every frame when it has at most
:data:`TEST_ALL_UP_TO` frames, else on one frame in :data:`TEST_STRIDE`. The two classical
references of issue 19, ``hog-logreg`` (frames resized to 320x160 so recordings of both
sizes stack) and ``lines-logreg`` (lane features), are trained on the same frames and
scored on the same test frames; the recipe's paired difference to each (balanced accuracy
on the same left-out frames, paired block-bootstrap interval) is kept with the per-frame
predictions.

Outputs: the model (``src/qdcnn/direction/builtin_models/qdcnn-head.safetensors``, header
``summary.builtin`` = what it was trained on and the leave-one-out scores) and
``docs/results/builtin-model.json``; both are rewritten after every left-out recording, so
a stopped run keeps what finished. Then put the printed SHA-256 into
``qdcnn.direction.builtin.BUILTIN_SHA256``.

    python benchmarks/train_builtin.py --data-root ../shared/data
    python benchmarks/train_builtin.py --skip-final --leave-out real-dashcam-sample
        # the saved model kept: (re)score these left-out recordings, update header and JSON
    python benchmarks/train_builtin.py --colour-augment --model /tmp/colour.safetensors \
        --results /tmp/colour.json
        # the colour-randomised variant (docs/builtin-model.md), written elsewhere
    python benchmarks/train_builtin.py --plain-frames --model /tmp/plain.safetensors \
        --results /tmp/plain.json
        # frames not standardised (the recipe before 5cc9212); --max-shift F: shifted sideways;
        # --edge-frames: the networks see each frame's Sobel edges only; --with-edges: the
        # standardised frame and its edges (six planes)
    python benchmarks/train_builtin.py --tta --model /tmp/tta.safetensors --results /tmp/tta.json
        # each frame decided by the mean of its and its mirror image's class probabilities
        # (left and right swapped): the networks are those of the recipe
    python benchmarks/train_builtin.py --no-final --seeds 3 --leave-out udacity-lake-track \
        --results /tmp/seeds.json
        # only the left-out scores, each pooled over 3 training seeds (0, 1, 2)
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
MODEL_PATH = REPO / "src" / "qdcnn" / "direction" / "builtin_models" / "qdcnn-head.safetensors"
RESULTS_PATH = REPO / "docs" / "results" / "builtin-model.json"
METHOD = "qdcnn-head"
REFERENCES = ("hog-logreg", "lines-logreg")
SEED = 0
#: Training runs per left-out recording (``--seeds``): seeds SEED, SEED + 1, ...; pooled.
SEEDS = 1
#: Networks of the built-in model (``--ensemble``: more are a variant, averaged; seeds SEED,
#: SEED + 1000, ...).
ENSEMBLE = 1
THREADS = 2
EPOCHS = 15
#: recording folder -> (spec suffix, training stride): about 400 frames of each.
RECORDINGS: dict[str, tuple[str, int]] = {
    "udacity-lake-track": ("", 13),
    "udacity-mountain-track": ("", 3),
    "udacity-dark-mountain-track": ("", 15),
    "real-dashcam-sample": ("@unit=rad,threshold=p33,left=positive", 3),
}
SYNTHETIC = ("synthetic:track1:150", "synthetic:track2:150", "synthetic:rain:150")
LEAVE_OUT = (
    "udacity-lake-track",
    "real-dashcam-sample",
    "udacity-mountain-track",
    "udacity-dark-mountain-track",
)
TEST_ALL_UP_TO, TEST_STRIDE = 1500, 4
HOG_SIZE = (320, 160)


@dataclass
class Part:
    """One recording's thinned frames: their labels and the inputs each method reads."""

    name: str
    frames: Any  # FrameSet (full)
    index: np.ndarray
    labels: np.ndarray


def load_sets(root: Path, synthetic: tuple[str, ...] = SYNTHETIC) -> dict[str, Any]:
    """Every recording and synthetic preset as a FrameSet, by name."""
    from qdcnn.data.frames import load_frameset

    specs = [f"udacity:{root / name}{suffix}" for name, (suffix, _) in RECORDINGS.items()]
    sets = [load_frameset(s, seed=SEED) for s in (*specs, *synthetic)]
    return {fs.name: fs for fs in sets}


def thin(fs: Any, stride: int) -> np.ndarray:
    return np.arange(0, len(fs), stride)


def make_parts(sets: dict[str, Any], names: list[str], test: str | None) -> list[Part]:
    """The training parts (``names``) and, last, the test part, labelled as the protocol
    says: a percentile threshold from the training recordings only."""
    from qdcnn.config import LabelConfig

    train_sets = [sets[n] for n in names]
    parts = []
    for n in names:
        stride = RECORDINGS[n][1] if n in RECORDINGS else 1
        y = sets[n].labels(LabelConfig(), train=train_sets)
        idx = thin(sets[n], stride)
        parts.append(Part(n, sets[n], idx, y[idx]))
    if test is not None:
        fs = sets[test]
        stride = 1 if len(fs) <= TEST_ALL_UP_TO else TEST_STRIDE
        idx = thin(fs, stride)
        parts.append(Part(test, fs, idx, fs.labels(LabelConfig(), train=train_sets)[idx]))
    return parts


def inputs(part: Part, method: str) -> np.ndarray:
    """``part``'s frames as ``method`` reads them (prepared network input, resized frames
    for HOG, lane features for lines-logreg)."""
    import cv2

    from qdcnn.config import PipelineConfig
    from qdcnn.direction.features import compute_features
    from qdcnn.direction.methods import get_method
    from qdcnn.models.networks import input_spec
    from qdcnn.models.preprocess import PreparedFrames, prepare_frames

    if method == "lines-logreg":
        sub = _subset(part.frames, part.index)
        table = compute_features(sub, PipelineConfig(seed=SEED), ("image-split",))
        return np.asarray(table.features["image-split"])
    images = [part.frames.image(int(i)) for i in part.index]
    if method == "hog-logreg":
        return np.stack([cv2.resize(im, HOG_SIZE, interpolation=cv2.INTER_AREA) for im in images])
    estimator = get_method(METHOD).estimator(PipelineConfig(seed=SEED), training_options())[0]
    spec = input_spec(estimator.arch, estimator.crop)
    prepared = np.concatenate([prepare_frames(im[None], spec) for im in images])
    return PreparedFrames(prepared, spec)


def _subset(fs: Any, index: np.ndarray) -> Any:
    """``fs`` thinned to ``index`` (frames read lazily as before)."""
    return replace(
        fs,
        steering=fs.steering[index],
        timestamps=None if fs.timestamps is None else fs.timestamps[index],
        sources=[fs.sources[i] for i in index],
        images=None if fs.images is None else [fs.images[i] for i in index],
        paths=None if fs.paths is None else [fs.paths[i] for i in index],
        positions=None,
        problems=[],
    )


#: Options of a recipe variant (``--colour-augment``, ``--plain-frames``, ``--edge-frames``,
#: ``--with-edges``, ``--max-shift``, ``--ensemble``, ``--tta``, ``--synthetic``); empty: the
#: recipe.
VARIANT: dict[str, Any] = {}
#: Variant keys that choose the training data, not the estimator.
DATA_KEYS = ("synthetic",)


def training_options() -> Any:
    from qdcnn.direction.methods import FRAME_FRONTS, TrainingOptions

    epochs = int(os.environ.get("BUILTIN_EPOCHS", EPOCHS))  # a quick try: BUILTIN_EPOCHS=1
    return TrainingOptions(
        epochs=epochs,
        threads=THREADS,
        progress=False,
        transfer=True,
        balanced=True,
        params=_params(FRAME_FRONTS),
        standardise_frames=bool(VARIANT.get("standardise_frames", True)),
        edge_frames=bool(VARIANT.get("edge_frames", False)),
    )


def _params(fronts: tuple[str, ...]) -> dict[str, Any]:
    """The estimator parameters of the recipe and its variant (the fronts are options)."""
    params = {k: v for k, v in VARIANT.items() if k not in (*fronts, *DATA_KEYS)}
    networks = int(params.pop("ensemble", ENSEMBLE))
    return {**params, "ensemble": networks} if networks > 1 else params


def stacked(parts: list[Part], method: str) -> tuple[np.ndarray, np.ndarray]:
    from qdcnn.models.preprocess import PreparedFrames

    xs = [inputs(p, method) for p in parts]
    x = np.concatenate(xs)
    if isinstance(xs[0], PreparedFrames):
        x = PreparedFrames(x, xs[0].spec)
    return x, np.concatenate([p.labels for p in parts])


def train_final(sets: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
    """The built-in model: the recipe on every recording and preset."""
    from qdcnn.config import PipelineConfig
    from qdcnn.direction.model import train_direction_model

    names = list(sets)
    parts = make_parts(sets, names, None)
    x, y = stacked(parts, METHOD)
    t0, c0 = time.perf_counter(), time.process_time()
    model = train_direction_model(
        METHOD,
        x,
        y,
        PipelineConfig(seed=SEED),
        " + ".join(sets[n].spec for n in names),
        options=training_options(),
    )
    info = {
        "recordings": {
            p.name: {
                "spec": p.frames.spec,
                "frames": int(p.index.size),
                "of": len(p.frames),
                "stride": int(p.index[1] - p.index[0]) if p.index.size > 1 else 1,
                "class_counts": np.bincount(p.labels, minlength=3).tolist(),
            }
            for p in parts
        },
        "frames": int(y.size),
        "wall_s": round(time.perf_counter() - t0, 1),
        "cpu_s": round(time.process_time() - c0, 1),
    }
    return model, info


def leave_one_out(sets: dict[str, Any], test: str) -> list[dict[str, Any]]:
    """The recipe and the references trained without ``test``, scored on it; each reference
    is paired with the recipe."""
    names = [n for n in sets if n != test]
    parts = make_parts(sets, names, test)
    out, results = [], []
    for method in (METHOD, *REFERENCES):
        res, row = left_out_score(parts, method)
        out.append(row)
        results.append(res)
    for res in results[1:]:
        out[0].setdefault("paired", []).append(paired_row(results[0], res))
        print(f"left out {test}: {out[0]['paired'][-1]}", flush=True)
    return out


def left_out_score(parts: list[Part], method: str) -> tuple[Any, dict[str, Any]]:
    """``method`` trained on ``parts`` but the last (with :data:`SEEDS` seeds), scored on the
    last: its result and its row (with the per-frame predictions)."""
    from qdcnn.config import PipelineConfig
    from qdcnn.direction.methods import get_method
    from qdcnn.experiments.evaluate import EvaluationSpec
    from qdcnn.experiments.evaluate_cross import Recording, cross_evaluate

    test = parts[-1].name
    spec = EvaluationSpec(
        "",
        METHOD,
        PipelineConfig(seed=SEED),
        training=training_options(),
        train=tuple(p.frames.spec for p in parts[:-1]),
        test=(parts[-1].frames.spec,),
        seeds=SEEDS,
    )
    recs = [Recording(p.name, *_one(p, method)) for p in parts]
    t0, c0 = time.perf_counter(), time.process_time()
    (res,) = cross_evaluate(get_method(method), recs[:-1], recs[-1:], spec)
    row = res.to_dict()  # with the per-frame predictions: paired comparisons stay possible
    row["predicted_counts"] = np.bincount(res.predictions[0], minlength=3).tolist()
    row["test_frames"] = {"of": len(parts[-1].frames), "stride": _stride(parts[-1])}
    row["wall_s"] = round(time.perf_counter() - t0, 1)
    row["cpu_s"] = round(time.process_time() - c0, 1)
    print(
        f"left out {test}: {method} BA {res.balanced_accuracy:.3f} "
        f"{res.balanced_accuracy_ci} ({row['wall_s']} s)",
        flush=True,
    )
    return res, row


def paired_row(a: Any, b: Any) -> dict[str, Any]:
    """``a``'s balanced accuracy minus ``b``'s on the same left-out frames, paired interval."""
    from qdcnn.direction.scores import format_with_interval, paired_difference

    d = paired_difference(a.test_labels, a.predictions, b.predictions, seed=SEED)
    text = format_with_interval(d.value, d.interval)
    return {
        "a": a.method,
        "b": b.method,
        **d.to_dict(),
        "text": ("" if d.value < 0 else "+") + text,
    }


def _one(part: Part, method: str) -> tuple[np.ndarray, np.ndarray]:
    x = inputs(part, method)
    return x, part.labels


def _stride(part: Part) -> int:
    return int(part.index[1] - part.index[0]) if part.index.size > 1 else 1


def commit() -> str:
    try:
        out = subprocess.run(
            ["git", "-C", str(REPO), "rev-parse", "HEAD"], capture_output=True, text=True
        )
        return out.stdout.strip() or "unknown"
    except OSError:
        return "unknown"


def save(
    model: Any,
    info: dict[str, Any],
    loo: dict[str, list[dict[str, Any]]],
    paths: tuple[Path, Path] = (MODEL_PATH, RESULTS_PATH),
) -> None:
    """The model (if any) with its header, and the results JSON."""
    from qdcnn._fileio import atomic_write_bytes

    summary = {
        "recipe": __doc__.split("Leave-one-recording-out")[0].strip() if __doc__ else "",
        "seed": SEED,
        **({"leave_one_out_seeds": SEEDS} if SEEDS > 1 else {}),
        **({"variant": dict(VARIANT)} if VARIANT else {}),
        "commit": commit(),
        "training": info,
        "leave_one_out": {
            test: {
                r["method"]: {
                    "balanced_accuracy": r["balanced_accuracy"],
                    "balanced_accuracy_ci": r["balanced_accuracy_ci"],
                    "accuracy": r["accuracy"],
                    "accuracy_ci": r["accuracy_ci"],
                    "n": r["n"],
                    "seconds": r["wall_s"],
                    **({"paired": r["paired"]} if "paired" in r else {}),
                }
                for r in rows
            }
            for test, rows in loo.items()
        },
    }
    result: dict[str, Any] = {"builtin": summary, "leave_one_out_rows": loo}
    if model is not None:
        model.summary["builtin"] = summary
        path = model.save(paths[0])
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        result["model"] = {
            "path": str(path.relative_to(REPO) if path.is_relative_to(REPO) else path),
            "sha256": digest,
            "bytes": path.stat().st_size,
        }
        print(f"model {path} ({path.stat().st_size} bytes) sha256 {digest}", flush=True)
    text = json.dumps(result, indent=1, default=_plain) + "\n"
    atomic_write_bytes(paths[1], text.encode())


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(type(value).__name__)


def _saved_rows(path: Path) -> dict[str, list[dict[str, Any]]]:
    """The leave-one-out rows of the results JSON at ``path``, if any."""
    if not path.is_file():
        return {}
    rows: dict[str, list[dict[str, Any]]] = json.loads(path.read_text())["leave_one_out_rows"]
    return rows


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--data-root", type=Path, default=REPO.parent / "shared" / "data")
    parser.add_argument("--leave-out", default=",".join(LEAVE_OUT))
    parser.add_argument(
        "--skip-final",
        action="store_true",
        help="keep the saved model (add the scores to its header and to the JSON)",
    )
    parser.add_argument(
        "--colour-augment",
        action="store_true",
        help="the colour-randomised variant of the recipe (docs/builtin-model.md)",
    )
    parser.add_argument(
        "--plain-frames",
        action="store_true",
        help="the variant whose networks do not standardise each frame (docs/builtin-model.md)",
    )
    parser.add_argument(
        "--edge-frames",
        action="store_true",
        help="the variant whose networks see each frame's edges only (docs/builtin-model.md)",
    )
    parser.add_argument(
        "--with-edges",
        action="store_true",
        help="the variant whose networks see each frame standardised and its edges (six planes)",
    )
    parser.add_argument(
        "--max-shift",
        type=float,
        default=0.0,
        help="the variant whose training frames shift sideways by up to this share of the width",
    )
    parser.add_argument(
        "--seeds",
        type=int,
        default=SEEDS,
        help="training runs (seeds 0, 1, ...) per left-out recording, pooled in its scores",
    )
    parser.add_argument(
        "--ensemble",
        type=int,
        default=ENSEMBLE,
        help=f"networks averaged (seeds 0, 1000, ...); the recipe: {ENSEMBLE}; more: a variant",
    )
    parser.add_argument(
        "--tta",
        action="store_true",
        help="the variant that averages each frame's and its mirror image's probabilities",
    )
    parser.add_argument(
        "--synthetic",
        default=",".join(s.removeprefix("synthetic:") for s in SYNTHETIC),
        help="the synthetic drives trained on, PRESET:N separated by commas; others: a variant",
    )
    parser.add_argument(
        "--no-final",
        action="store_true",
        help="score the left-out recordings only: no final training, no model file",
    )
    parser.add_argument("--model", type=Path, default=MODEL_PATH, help="model file to write")
    parser.add_argument("--results", type=Path, default=RESULTS_PATH, help="results JSON")
    return parser


def synthetic_specs(parser: argparse.ArgumentParser, text: str) -> tuple[str, ...]:
    """``--synthetic``'s drives as data specs (``synthetic:PRESET:N``), checked."""
    from qdcnn.data.synthetic_presets import PRESETS

    specs = tuple(f"synthetic:{item.strip()}" for item in text.split(",") if item.strip())
    for spec in specs:
        preset, _, count = spec.removeprefix("synthetic:").partition(":")
        if preset not in PRESETS or not count.isdigit() or int(count) < 1:
            parser.error(f"--synthetic {text!r}: give PRESET:N items, a preset in {PRESETS}")
    presets = [spec.split(":")[1] for spec in specs]
    if len(set(presets)) < len(presets):
        parser.error(f"--synthetic {text!r}: each preset once")
    return specs


def main() -> None:
    parser = _parser()
    args = parser.parse_args()
    paths = (args.model.resolve(), args.results.resolve())
    for option in ("colour_augment", "max_shift", "tta"):
        if getattr(args, option):
            VARIANT[option] = getattr(args, option)
    synthetic = synthetic_specs(parser, args.synthetic)
    if synthetic != SYNTHETIC:
        VARIANT["synthetic"] = list(synthetic)
    if args.skip_final and args.no_final:
        parser.error("--skip-final and --no-final: give one of them")
    fronts = [f for f in ("plain_frames", "edge_frames", "with_edges") if getattr(args, f)]
    if len(fronts) > 1:
        parser.error("--plain-frames, --edge-frames and --with-edges: give one of them")
    from qdcnn.models.ensemble import MAX_ENSEMBLE

    if not 1 <= args.ensemble <= MAX_ENSEMBLE:
        parser.error(f"--ensemble {args.ensemble}: give 1 to {MAX_ENSEMBLE} networks")
    if args.ensemble != ENSEMBLE:
        VARIANT["ensemble"] = args.ensemble
    if args.plain_frames or args.edge_frames:
        VARIANT["standardise_frames"] = False
    if args.edge_frames or args.with_edges:
        VARIANT["edge_frames"] = True
    writes_model = not args.no_final  # --skip-final rewrites the saved model's header
    if VARIANT and (RESULTS_PATH in paths or (writes_model and MODEL_PATH in paths)):
        need = "--model and --results (not the shipped files)" if writes_model else "--results"
        parser.error(f"a recipe variant: give {need}")
    if (args.no_final or args.seeds > 1) and RESULTS_PATH in paths:
        parser.error("--no-final and --seeds: give --results (not the shipped file)")
    if args.seeds < 1:
        parser.error(f"--seeds {args.seeds}: give at least 1")
    global SEEDS
    SEEDS = args.seeds
    import torch

    from qdcnn.direction.model import DirectionModel

    torch.set_num_threads(THREADS)
    os.environ.setdefault("OMP_NUM_THREADS", str(THREADS))
    sets = load_sets(args.data_root, synthetic)
    loo: dict[str, list[dict[str, Any]]] = {}
    model: Any = None
    info: dict[str, Any] = {}
    if args.skip_final:  # the saved model, its header updated with the scores
        model = DirectionModel.load(paths[0])
        if model.summary["builtin"].get("variant", {}) != VARIANT:
            parser.error(f"--skip-final: {paths[0]} was trained with another recipe variant")
        info = model.summary["builtin"]["training"]
        loo = {k: v for k, v in _saved_rows(paths[1]).items() if k not in args.leave_out.split(",")}
    elif not args.no_final:
        model, info = train_final(sets)
        print(f"trained on {info['frames']} frames in {info['wall_s']} s", flush=True)
        save(model, info, loo, paths)
    for test in filter(None, args.leave_out.split(",")):
        loo[test] = leave_one_out(sets, test)
        save(model, info, loo, paths)


if __name__ == "__main__":
    main()
