"""Benchmark of the whole per-frame pipeline: shadow removal, lanes, grouping and the decision.

Frames come from a synthetic drive (or a dataset spec); the classifier is trained
on other frames first. The process can be pinned to one CPU core
(``os.sched_setaffinity``) with OpenCV and BLAS limited to one thread, so the
frames-per-second figure is a one-core number. CNN inference frames/s are
reported beside it when torch is installed.
"""

from __future__ import annotations

import os
import platform
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np

from qdcnn._optional import has_torch
from qdcnn._validation import check_int
from qdcnn.data.frames import load_frameset
from qdcnn.experiments.direction_model import default_config, train_direction_model
from qdcnn.experiments.features import compute_features
from qdcnn.experiments.methods import get_method
from qdcnn.pipeline import process_frame


def pin_to_one_core() -> int | None:
    """Restrict this process, OpenCV and BLAS to one core; return the core, if pinning works."""
    import cv2
    from threadpoolctl import threadpool_limits  # type: ignore[import-untyped]

    cv2.setNumThreads(1)
    threadpool_limits(1)
    try:
        core = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {core})
    except (AttributeError, OSError):
        return None
    return core


def bench_pipeline(
    *,
    data: str = "synthetic:track1:200",
    methods: tuple[str, ...] = ("image-split-uu", "image-split-vqc", "kmeans-uu", "spectral-uu"),
    frames: int = 100,
    one_core: bool = True,
    cnn: bool = True,
    seed: int = 0,
    say: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Frames per second of ``process_frame`` + classifier decision for each method (measured)."""
    check_int("frames", frames, 1, 100_000)
    log = say or (lambda _m: None)
    core = pin_to_one_core() if one_core else None
    cfg = replace(default_config(), seed=seed)
    train = load_frameset(data, seed=seed + 1)
    test = load_frameset(data, seed=seed)
    images = [test.image(i) for i in range(min(frames, len(test)))]
    rows = []
    for method in methods:
        grouping = get_method(method).grouping
        assert grouping is not None
        log(f"training {method}")
        table = compute_features(train, cfg, (grouping,))
        keep = table.readable
        model = train_direction_model(
            method, table.features[grouping][keep], train.labels()[keep], cfg, data, inner_folds=0
        )
        rng = np.random.default_rng(seed)
        log(f"timing {method}")

        def run(
            image: np.ndarray, grouping: str = grouping, model: Any = model, rng: Any = rng
        ) -> None:
            lanes = process_frame(image, cfg, (grouping,), rng=rng).lanes[grouping]
            model.predict(lanes.features)

        run(images[0])
        passes = []
        for _ in range(3):
            t0 = time.perf_counter()
            for image in images:
                run(image)
            passes.append((time.perf_counter() - t0) / len(images))
        per_frame = float(np.median(passes))
        rows.append(
            {
                "method": method,
                "ms_per_frame": 1e3 * per_frame,
                "frames_per_second": 1.0 / per_frame,
            }
        )
    result: dict[str, Any] = {
        "kind": "measured",
        "data": data,
        "frames": len(images),
        "size": list(images[0].shape[1::-1]),
        "one_core": core is not None,
        "machine": {"python": platform.python_version(), "cpus": os.cpu_count()},
        "pipeline": rows,
    }
    if cnn and has_torch():
        from qdcnn.models.training import inference_fps

        h, w = images[0].shape[:2]
        result["cnn_inference"] = [
            {
                "arch": arch,
                "frames_per_second": inference_fps(arch, n=64, size=(h, w), num_threads=1),
            }
            for arch in ("pilotnet", "resnet50")
        ]
    return result
