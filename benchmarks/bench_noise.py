"""Time of the full noise grid: 6 channels x 10 strengths x 2 methods on 300 frames' features.

Target (issue 4): at most 10 s on one core. The timed region is
:func:`qdcnn.experiments.noise.direction_sweep` with its defaults: 5 contiguous folds
(gap 5), inner 3-fold hyperparameter search, every fold's UU-dagger and VQC model trained
once without noise, then all test frames classified under each of the 60 (channel, p)
settings with exact density-matrix probabilities (the estimators' batched
``predict_many``). Frames, labels and lane features come from
:func:`qdcnn.direction.lane_data.load_lane_data` (computed or read from the cache) before
timing, exactly as ``run_noise_sweep`` gets them. The process is pinned to one CPU and
BLAS/OpenMP are limited to one thread.

Usage::

    python benchmarks/bench_noise.py [--data synthetic:track2:300] [--repeats 3]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from dataclasses import replace

import numpy as np
from threadpoolctl import threadpool_limits

from qdcnn.config import PipelineConfig
from qdcnn.direction.lane_data import load_lane_data
from qdcnn.experiments.noise import PAPER_STRENGTHS, direction_sweep
from qdcnn.quantum.noise import PAPER_CHANNELS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default="synthetic:track2:300")
    parser.add_argument("--grouping", default="image-split")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    cfg = replace(PipelineConfig(), seed=args.seed)
    lanes = load_lane_data(args.data, cfg, (args.grouping,), seed=args.seed)
    X, y = lanes.features(args.grouping), lanes.y

    times = []
    with threadpool_limits(1):
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            rows = direction_sweep({args.grouping: X}, y, config=cfg, seed=args.seed)
            times.append(time.perf_counter() - t0)
    points = len(PAPER_CHANNELS) * len(PAPER_STRENGTHS) * 2
    assert len(rows) == points
    print(
        json.dumps(
            {
                "benchmark": "noise-grid",
                "data": args.data,
                "frames": len(y),
                "grid": f"{len(PAPER_CHANNELS)} channels x {len(PAPER_STRENGTHS)} p x 2 methods",
                "points": points,
                "seconds_best": round(min(times), 3),
                "seconds_median": round(float(np.median(times)), 3),
                "repeats": args.repeats,
                "target_seconds": 10.0,
                "cpus": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
                "python": platform.python_version(),
                "machine": platform.machine(),
            }
        )
    )


if __name__ == "__main__":
    main()
