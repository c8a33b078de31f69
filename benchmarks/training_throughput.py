"""PilotNet training throughput: one epoch with and without the frame cache, and the share
of an evaluate run spent outside the network's forward and backward passes (issue 22 item 3).

All times are **measured** wall-clock seconds in this process, torch on ``--threads``
threads (default 2), on the first ``--frames`` frames (default 5,000) of ``--data``
(default the dark mountain track; a synthetic drive when that recording is absent).

(a) **One epoch**, with the method's own settings (``dnn-pilotnet`` of the registry, one
epoch, its validation split included):

- *without the cache* (every fit before the frame cache): the frames are decoded from
  their files (:func:`qdcnn.data.frames.stack_images`), and ``fit`` crops and resizes them
  to the network input before its epoch;
- *with the cache*: the recording's cached ``uint8`` array
  (:func:`qdcnn.direction.frame_cache.network_frames`) is memory-mapped, and ``fit``
  copies it and runs its epoch. Building the entry once (decode, resize, write) is
  timed apart, in a fresh cache folder.

(b) **An evaluate run** (:func:`qdcnn.experiments.evaluate.evaluate_frames` of
``dnn-pilotnet``: ``--folds`` contiguous folds, ``--epochs`` epochs each, the frames read
from the cache built in (a)) with the time inside the network's passes summed by global
hooks: forward passes (outermost module call; training and inference apart), the
backward pass (``Tensor.backward``) and the optimiser step. The rest (batch assembly,
augmentation, colour conversion, gradient norms, early-stopping copies, scoring, the
bootstrap) is the share outside. The hooks cost a few microseconds per module call, which
counts as outside.

Usage::

    python benchmarks/training_throughput.py [--data SPEC] [--frames 5000] [--threads 2]
        [--folds 3] [--epochs 2] [--out docs/results/training-throughput.json]

About four minutes on an idle two-core machine with the defaults; ``--frames 1000`` for a
quick check.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

DEFAULT_DATA = "udacity:" + str(
    (Path(__file__).parents[1] / ".." / "shared" / "data" / "udacity-dark-mountain-track").resolve()
)
METHOD = "dnn-pilotnet"


def load_frames(spec: str, n: int) -> tuple[Any, str]:
    """The first ``n`` frames of ``spec``; a synthetic drive when a recording is absent."""
    from qdcnn.data.frames import load_frameset, parse_data_spec

    parsed = parse_data_spec(spec)
    if parsed.kind != "synthetic" and not Path(parsed.value).exists():
        spec = f"synthetic:track1:{min(n, 10_000)}"
    frames = load_frameset(spec)
    return first_frames(frames, n), spec


def first_frames(frames: Any, n: int) -> Any:
    """A FrameSet of the first ``n`` frames of ``frames``."""
    n = min(n, len(frames))

    def cut(value: Any) -> Any:
        return None if value is None else value[:n]

    return replace(
        frames,
        steering=frames.steering[:n],
        timestamps=cut(frames.timestamps),
        sources=frames.sources[:n],
        images=cut(frames.images),
        paths=cut(frames.paths),
        positions=cut(frames.positions),
        problems=[],
    )


def estimator(threads: int, epochs: int) -> Any:
    from qdcnn.config import PipelineConfig
    from qdcnn.direction.methods import TrainingOptions, get_method

    options = TrainingOptions(epochs=epochs, threads=threads)
    return get_method(METHOD).estimator(PipelineConfig(), options)[0]


def timed(fn: Any, *args: Any, **kw: Any) -> tuple[Any, float]:
    t0 = time.perf_counter()
    out = fn(*args, **kw)
    return out, time.perf_counter() - t0


def part_epoch(frames: Any, labels: np.ndarray, threads: int) -> dict[str, Any]:
    """One epoch without the cache (decode, resize inside fit) and with it (memory map)."""
    from qdcnn.data.frames import stack_images
    from qdcnn.direction.frame_cache import network_frames
    from qdcnn.models.networks import input_spec

    spec = input_spec("pilotnet", None)
    warm = min(len(frames), 64)  # torch's one-time start-up is in neither timed fit
    estimator(threads, 1).fit(stack_images(first_frames(frames, warm))[0], labels[:warm])
    (images, readable, _), decode_s = timed(stack_images, frames)
    y = labels[readable]
    raw = images[readable]
    plain = estimator(threads, 1)
    _, fit_raw_s = timed(plain.fit, raw, y)
    del images, raw
    _, build_s = timed(network_frames, frames, spec)  # cold: decode, resize, write
    (cached, ok, _), map_s = timed(network_frames, frames, spec)  # warm: memory map
    cached_est = estimator(threads, 1)
    _, fit_cached_s = timed(cached_est.fit, cached[ok], labels[ok])
    epoch_raw = float(plain.history_[0]["seconds"])
    epoch_cached = float(cached_est.history_[0]["seconds"])
    return {
        "frames": int(readable.sum()),
        "input": [spec.height, spec.width],
        "without_cache": {
            "decode_s": decode_s,
            "fit_s": fit_raw_s,
            "of_which_epoch_s": epoch_raw,
            "total_s": decode_s + fit_raw_s,
        },
        "with_cache": {
            "cache_build_once_s": build_s,
            "memory_map_s": map_s,
            "fit_s": fit_cached_s,
            "of_which_epoch_s": epoch_cached,
            "total_s": map_s + fit_cached_s,
        },
    }


class PassTimer:
    """Seconds inside the network's forward passes, backward passes and optimiser steps."""

    def __init__(self) -> None:
        self.seconds = {"forward_train": 0.0, "forward_inference": 0.0, "backward": 0.0}
        self.seconds["optimiser_step"] = 0.0
        self.calls = dict.fromkeys(self.seconds, 0)
        self._depth = 0
        self._start = 0.0
        self._step_start = 0.0
        self._handles: list[Any] = []
        self._backward: Any = None

    def __enter__(self) -> PassTimer:
        import torch
        from torch.nn.modules import module
        from torch.optim import optimizer

        self._handles = [
            module.register_module_forward_pre_hook(self._pre),
            module.register_module_forward_hook(self._post),
            optimizer.register_optimizer_step_pre_hook(self._step_pre),
            optimizer.register_optimizer_step_post_hook(self._step_post),
        ]
        self._backward = torch.Tensor.backward
        original, seconds, calls = self._backward, self.seconds, self.calls

        def backward(tensor: Any, *args: Any, **kw: Any) -> Any:
            t0 = time.perf_counter()
            try:
                return original(tensor, *args, **kw)
            finally:
                seconds["backward"] += time.perf_counter() - t0
                calls["backward"] += 1

        torch.Tensor.backward = backward  # type: ignore[method-assign]
        return self

    def __exit__(self, *_: object) -> None:
        import torch

        for handle in self._handles:
            handle.remove()
        torch.Tensor.backward = self._backward  # type: ignore[method-assign]

    def _pre(self, _module: Any, _inputs: Any) -> None:
        if self._depth == 0:
            self._start = time.perf_counter()
        self._depth += 1

    def _post(self, _module: Any, _inputs: Any, _output: Any) -> None:
        import torch

        self._depth -= 1
        if self._depth == 0:
            key = "forward_train" if torch.is_grad_enabled() else "forward_inference"
            self.seconds[key] += time.perf_counter() - self._start
            self.calls[key] += 1

    def _step_pre(self, *_: Any) -> None:
        self._step_start = time.perf_counter()

    def _step_post(self, *_: Any) -> None:
        self.seconds["optimiser_step"] += time.perf_counter() - self._step_start
        self.calls["optimiser_step"] += 1


def part_evaluate(
    frames: Any, labels: np.ndarray, threads: int, folds: int, epochs: int
) -> dict[str, Any]:
    """A short evaluate run of PilotNet, split into the network's passes and the rest."""
    from qdcnn.direction.methods import TrainingOptions
    from qdcnn.experiments.evaluate import evaluate_frames

    options = TrainingOptions(epochs=epochs, threads=threads)
    with PassTimer() as passes:
        t0 = time.perf_counter()
        result, _ = evaluate_frames(
            METHOD, frames, labels, options=options, folds=folds, use_cache=True
        )
        total = time.perf_counter() - t0
    inside = sum(passes.seconds.values())
    train_passes = inside - passes.seconds["forward_inference"]
    return {
        "folds": folds,
        "epochs": epochs,
        "total_s": total,
        "passes_s": passes.seconds,
        "calls": passes.calls,
        "inside_passes_s": inside,
        "outside_share": 1.0 - inside / total,
        "outside_training_passes_share": 1.0 - train_passes / total,
        "balanced_accuracy": result.balanced_accuracy,
    }


def print_table(result: dict[str, Any]) -> None:
    a, b = result["epoch"], result["evaluate"]
    w, c = a["without_cache"], a["with_cache"]
    print(
        f"measured; {a['frames']} frames of {result['data']}, PilotNet input "
        f"{a['input'][1]}x{a['input'][0]}, {result['threads']} torch threads; load average "
        f"{result['machine']['load_average_at_start']}"
    )
    print(f"{'one epoch':<44} {'without cache':>14} {'with cache':>12}")
    print(f"{'  decode / memory-map (s)':<44} {w['decode_s']:>14.2f} {c['memory_map_s']:>12.2f}")
    print(f"{'  fit: resize or copy + epoch (s)':<44} {w['fit_s']:>14.2f} {c['fit_s']:>12.2f}")
    print(
        f"{'    of which the epoch (s)':<44} {w['of_which_epoch_s']:>14.2f} "
        f"{c['of_which_epoch_s']:>12.2f}"
    )
    print(f"{'  total (s)':<44} {w['total_s']:>14.2f} {c['total_s']:>12.2f}")
    print(f"{'  building the cache entry, once (s)':<44} {'':>14} {c['cache_build_once_s']:>12.2f}")
    p = b["passes_s"]
    print(
        f"evaluate ({b['folds']} folds x {b['epochs']} epochs): {b['total_s']:.1f} s; forward "
        f"(training) {p['forward_train']:.1f} s, backward {p['backward']:.1f} s, optimiser "
        f"{p['optimiser_step']:.1f} s, forward (inference) {p['forward_inference']:.1f} s; "
        f"outside the passes {100 * b['outside_share']:.1f} % "
        f"(outside the training passes {100 * b['outside_training_passes_share']:.1f} %)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=DEFAULT_DATA, help="dataset spec (udacity:PATH, ...)")
    parser.add_argument("--frames", type=int, default=5000)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--folds", type=int, default=3)
    parser.add_argument("--epochs", type=int, default=2, help="epochs per fold in (b)")
    parser.add_argument("--out", type=Path, default=Path("docs/results/training-throughput.json"))
    parser.add_argument("--json", action="store_true", help="print the JSON, not the table")
    args = parser.parse_args()
    frames, spec = load_frames(args.data, args.frames)
    labels = frames.labels()
    result: dict[str, Any] = {
        "kind": "measured",
        "data": spec,
        "threads": args.threads,
        "machine": {
            "python": platform.python_version(),
            "cpus": os.cpu_count(),
            "load_average_at_start": os.getloadavg(),
        },
    }
    with tempfile.TemporaryDirectory() as cache:
        os.environ["QDCNN_CACHE"] = cache  # a fresh cache: the build is timed cold
        result["epoch"] = part_epoch(frames, labels, args.threads)
        result["evaluate"] = part_evaluate(frames, labels, args.threads, args.folds, args.epochs)
    result["machine"]["load_average_at_end"] = os.getloadavg()
    text = json.dumps(result, indent=2)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text + "\n", encoding="utf-8")
    if args.json:
        print(text)
    else:
        print_table(result)


if __name__ == "__main__":
    main()
