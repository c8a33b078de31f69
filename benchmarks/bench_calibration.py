"""The per-image centroid calibration of the UU-dagger detector: compiled kernel against NumPy.

The calibrated detector (``qdcnn bench shadows``, row ``uu-exact-calibrated``) finds each
frame's centroid from its block means: Otsu's two-class split, then the propagation's fixed
point. This script times that step alone on the bench's frames (track2 rendered at each
``--sizes``): :func:`qdcnn.vision.block_kernels.calibrate_with` (what the detector runs)
and :func:`qdcnn.vision.shadows.calibrate_centroid` (the NumPy reference it is tested against),
in turns, in one process pinned to one core. Timing one step of about 15 us inside the
whole detector's 60 us leaves it in the machine's drift; timed alone, in turns with its
reference, a change to it shows. All times are **measured**, medians over ``--passes``.

Usage::

    python benchmarks/bench_calibration.py [--json] [--passes 7] [--sizes 320x160,1280x720]
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from typing import Any

from in_turns import main, measured, size_row, turn_name


def _per_call_us(fn: Callable[[], object], calls: int) -> float:
    t0 = time.perf_counter()
    for _ in range(calls):
        fn()
    return 1e6 * (time.perf_counter() - t0) / calls


def _calls(means: Any) -> dict[str, Callable[[], object]]:
    """The kernel's and the reference's calibration of one frame's block means."""
    from qdcnn.vision import shadows

    cfg = shadows.ShadowConfig(shots=None)
    settings = shadows._calibration_settings(cfg)
    tables = shadows._half_angle_tangents()
    kernels = shadows.compiled_kernels()
    assert kernels is not None, "Numba is needed (or QDCNN_KERNELS=numpy is set)"
    values = means.ravel()
    return {
        "kernel": lambda: kernels.calibrate_with(values, tables, settings),
        "numpy": lambda: shadows.calibrate_centroid(means, "intensity", cfg),
    }


def bench(sizes: list[tuple[int, int]], passes: int, frames: int) -> dict[str, Any]:
    from qdcnn.experiments.pipeline_bench import pin_to_one_core
    from qdcnn.experiments.shadow_bench import bench_frames
    from qdcnn.vision import shadows

    core = pin_to_one_core()
    rows = []
    for w, h in sizes:
        cfg = shadows.ShadowConfig(shots=None)
        images = bench_frames(w, h, frames)
        blocks = [shadows.detect_shadows_uu(im, cfg).block_values for im in images]
        calls = [_calls(b) for b in blocks]
        for call in calls:  # warm-up: the kernel loaded (or compiled) before any turn
            call["kernel"](), call["numpy"]()
        times: dict[str, list[float]] = {"kernel": [], "numpy": []}
        for turn in range(2 * passes):
            name = turn_name(turn, ("kernel", "numpy"))
            repeat = 2000 if name == "kernel" else 100
            times[name].append(statistics.mean(_per_call_us(c[name], repeat) for c in calls))
        rows.append(size_row((w, h), times, "us_per_frame", 2, blocks=int(blocks[0].size)))
    what = "per-image centroid calibration of the block means: kernel vs NumPy reference"
    return measured(what, frames, core is not None, rows)


def _line(row: dict[str, Any]) -> str:
    w, h = row["size"]
    us = row["us_per_frame"]
    return (
        f"{w}x{h} ({row['blocks']} blocks): kernel {us['kernel']:.2f} us, "
        f"NumPy {us['numpy']:.1f} us a frame ({row['numpy_over_kernel']:.1f}x)"
    )


if __name__ == "__main__":
    main(__doc__, bench, (7, 5, "320x160,1280x720"), _line)
