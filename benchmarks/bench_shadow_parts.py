"""Where a calibrated UU-dagger detection's time goes: its parts timed in turns with IBT.

``qdcnn bench shadows`` gives each detector's time as a ratio to IBT's. This script splits
the two calibrated detectors (exact and 1024 shots) into the parts they run, each timed on
its own in the same turns as IBT and the whole detectors, on the bench's frames
(:func:`qdcnn.experiments.shadow_bench.bench_frames`, the frames rotating), in one process
pinned to one core:

- ``greyscale``: OpenCV's conversion, which IBT pays too;
- ``block sums``: :func:`qdcnn.vision.block_kernels.block_sums` (sums and means);
- ``calibration``: :func:`~qdcnn.vision.block_kernels.calibrate_with` of the block means;
- ``shot decisions``: :func:`~qdcnn.vision.block_kernels.shot_mask` at the frame's centroid;
- ``mask``: :func:`~qdcnn.vision.block_kernels.expand_median` of the frame's decisions;
- ``uniforms``: one uniform per block from a generator;
- ``exact kernel``: :func:`~qdcnn.vision.block_kernels.detect_calibrated`, the one call the
  exact detector makes;
- ``exact detector`` / ``shots detector``: :func:`qdcnn.vision.shadows.detect_shadows_uu`.

Each part's time includes its own call from Python (about 0.4 us for an array or two). Run
with another commit's code (``PYTHONPATH=<clone>/src``) to compare, in turns with this one.
All times are **measured**: medians of single calls, in microseconds.

Usage::

    python benchmarks/bench_shadow_parts.py [--json] [--passes 50] [--frames 20]
        [--sizes 320x160,1280x720]
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from in_turns import main, measured


def _frame_inputs(image: Any, cfg: Any) -> dict[str, Any]:
    """What the detector's kernels take for one frame, as the detector builds it."""
    import cv2

    from qdcnn.vision import shadows

    grey = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    geometry = shadows.block_grid(grey.shape, cfg.downsample, cfg.grid)
    lookup = shadows.state_lookup(geometry, grey.shape[1], cfg.downsample)
    assert lookup is not None
    exact = shadows.detect_shadows_uu(image, cfg)
    half = exact.centroid * (math.pi / 255.0) / 2.0
    edges = shadows._pixel_edges(geometry, cfg.downsample)
    return {
        "grey": grey,
        "edges": edges,
        "means": exact.block_values.ravel().copy(),
        "sums": shadows.compiled_kernels().block_sums(grey, *edges)[0],
        "decided": exact.block_mask.view("uint8"),
        "centroid": (math.cos(half), math.sin(half)),
        "amplitudes": (lookup.offsets, lookup.cos_half, lookup.sin_half),
        "image_of": (geometry.row_of, geometry.col_of, cfg.median_ksize),
    }


def _parts(images: list[Any]) -> dict[str, Callable[[Any], object]]:
    """Each part as a function of the frame (its inputs looked up by the frame's id)."""
    import cv2
    import numpy as np

    from qdcnn.quantum.sampling import CDF_GRID
    from qdcnn.vision import shadows
    from qdcnn.vision.baselines import detect_ibt

    kernels = shadows.compiled_kernels()
    assert kernels is not None, "Numba is needed (or QDCNN_KERNELS=numpy is set)"
    cfg = shadows.ShadowConfig(shots=None)
    shots = shadows.ShadowConfig(shots=1024)
    inputs = {id(im): _frame_inputs(im, cfg) for im in images}
    tables, _ = shadows._shot_tables(1024, cfg.threshold)
    calibration = (shadows._half_angle_tangents(), shadows._calibration_settings(cfg))
    uniforms, stream = np.random.default_rng(1), np.random.default_rng(2)
    u = uniforms.random(next(iter(inputs.values()))["means"].size)

    def of(fn: Callable[[dict[str, Any]], object]) -> Callable[[Any], object]:
        return lambda image: fn(inputs[id(image)])

    return {
        "ibt": detect_ibt,
        "greyscale": lambda image: cv2.cvtColor(image, cv2.COLOR_RGB2GRAY),
        "block sums": of(lambda f: kernels.block_sums(f["grey"], *f["edges"])),
        "calibration": of(lambda f: kernels.calibrate_with(f["means"], *calibration)),
        "shot decisions": of(
            lambda f: kernels.shot_mask(
                f["sums"], *f["amplitudes"], *f["centroid"], u, tables, CDF_GRID
            )
        ),
        "mask": of(lambda f: kernels.expand_median(f["decided"], *f["image_of"])),
        "uniforms": lambda image: uniforms.random(u.size),
        "exact kernel": of(
            lambda f: kernels.detect_calibrated(
                f["grey"], f["edges"], *calibration, f["amplitudes"], cfg.threshold, *f["image_of"]
            )
        ),
        "exact detector": lambda image: shadows.detect_shadows_uu(image, cfg),
        "shots detector": lambda image: shadows.detect_shadows_uu(image, shots, rng=stream),
    }


def bench(sizes: list[tuple[int, int]], passes: int, frames: int) -> dict[str, Any]:
    from qdcnn.experiments.pipeline_bench import pin_to_one_core
    from qdcnn.experiments.shadow_bench import bench_frames, time_in_turns

    core = pin_to_one_core()
    rows = []
    for w, h in sizes:
        images = bench_frames(w, h, frames)
        timings = time_in_turns(_parts(images), images, repeats=passes)
        us = {name: 1e6 * t.median_s for name, t in timings.items()}
        rows.append({"size": [w, h], "us_per_frame": us})
    what = "parts of the calibrated UU-dagger detectors, in turns with IBT (medians, us)"
    return measured(what, frames, core is not None, rows)


def _line(row: dict[str, Any]) -> str:
    w, h = row["size"]
    parts = ", ".join(f"{name} {us:.1f}" for name, us in row["us_per_frame"].items())
    return f"{w}x{h}: {parts} (us a frame)"


if __name__ == "__main__":
    main(__doc__, bench, (50, 20, "320x160,1280x720"), _line)
