"""Benchmark of shadow detection: UU-dagger (exact, shots), per-block Aer, IBT, CBS, LBP.

All detectors run in the same process on the same frames, so the ratios are
comparable; per-block Aer (one ``AerSimulator.run`` call per block, as a naive
port of the paper's loop would do) is timed on a subset of blocks and scaled to
the frame's block count, which the result says. The labelled hardware-time
estimates of :mod:`qdcnn.quantum.hardware_time` are reported beside the
measurements, never mixed with them.
"""

from __future__ import annotations

import platform
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._validation import check_int
from qdcnn.config import ShadowConfig
from qdcnn.quantum.hardware_time import PROFILES, estimate_time
from qdcnn.runtime.timing import Timing
from qdcnn.vision.baselines import detect_cbs, detect_ibt, detect_lbp
from qdcnn.vision.shadows import block_grid, detect_shadows_uu

SIZES: tuple[tuple[int, int], ...] = ((320, 160), (1280, 720))
#: Default frames and passes of :func:`bench_shadows` (``qdcnn bench shadows``): with 5 x 5
#: single calls the UU-dagger / IBT ratios of two runs on a busy machine differed by up to
#: 30 %; the report's Table IV uses these or more.
BENCH_FRAMES, BENCH_REPEATS = 5, 15


def bench_frames(width: int, height: int, n: int, seed: int = 0) -> list[NDArray[np.uint8]]:
    """Synthetic ``track2`` frames (shadowed mountain road) at the given size."""
    from qdcnn.data.synthetic import generate_scenes

    return [s.image for s in generate_scenes("track2", n, seed=seed, width=width, height=height)]


def _aer_per_block_seconds(
    frame: NDArray[np.uint8], cfg: ShadowConfig, blocks: int, seed: int
) -> tuple[float, int]:
    """Median seconds of one Aer run call on one block circuit with ``cfg.shots`` shots."""
    from qdcnn._optional import require
    from qdcnn.quantum.circuits import uu_dagger_circuit
    from qdcnn.quantum.qiskit_bridge import to_qiskit
    from qdcnn.quantum.uu_dagger import value_to_angle

    aer = require("qiskit_aer", "the per-block Aer benchmark")
    result = detect_shadows_uu(frame, replace(cfg, shots=None))
    values = result.block_values.ravel()
    pick = np.random.default_rng(seed).choice(
        values.size, size=min(blocks, values.size), replace=False
    )
    circuits = to_qiskit(
        uu_dagger_circuit(value_to_angle(result.centroid), value_to_angle(values[pick]))
    )
    sim = aer.AerSimulator()
    samples = []
    for i, qc in enumerate(circuits):
        qc.measure_all()
        t0 = time.perf_counter()
        sim.run(qc, shots=cfg.shots or 1024, seed_simulator=seed + i).result().get_counts()
        samples.append(time.perf_counter() - t0)
    return float(np.median(samples[1:] or samples)), values.size


def time_in_turns(
    fns: dict[str, Callable[[Any], object]], items: list[Any], *, repeats: int = 3
) -> dict[str, Timing]:
    """Median time of one call of each function over ``repeats`` passes over ``items``.

    The functions take turns on every item, so a change of machine load falls on all of
    them alike, and the median of the single calls (not of whole passes) ignores the
    calls that another process interrupted; their ratios stay comparable between runs on
    a busy machine. The order of the turns rotates from item to item, so no function
    always runs first on a frame (with its pixels not yet in cache). Each function is
    first called once untimed.
    """
    for fn in fns.values():
        fn(items[0])
    samples: dict[str, list[float]] = {name: [] for name in fns}
    turns = list(fns.items())
    clock = time.perf_counter
    for turn in range(repeats * len(items)):
        item = items[turn % len(items)]
        start = turn % len(turns)
        for name, fn in turns[start:] + turns[:start]:
            t0 = clock()
            fn(item)
            samples[name].append(clock() - t0)
    out = {}
    for name, values in samples.items():
        arr = np.asarray(values)
        out[name] = Timing(name, float(np.median(arr)), float(arr.min()), float(arr.max()), repeats)
    return out


def _aer_row(
    frame: NDArray[np.uint8], cfg: ShadowConfig, timings: dict[str, Timing], blocks: int, seed: int
) -> dict[str, Any]:
    """Per-block Aer time of one frame, and its ratios to the UU-dagger detectors."""
    per_block, total = _aer_per_block_seconds(frame, cfg, blocks, seed)
    per_frame = per_block * total
    return {
        "aer_per_block": {
            "seconds_per_block": per_block,
            "blocks_timed": min(blocks, total),
            "seconds_per_frame": per_frame,
            "note": "measured per block (one AerSimulator.run call, 1024 shots),"
            " scaled to the frame's block count",
        },
        "ratio_aer_per_block_to_uu_shots": per_frame / timings["uu-1024-shots"].median_s,
        "ratio_aer_per_block_to_uu_exact": per_frame / timings["uu-exact"].median_s,
    }


def _detectors(calibrated: ShadowConfig, fixed: ShadowConfig) -> dict[str, Callable[[Any], object]]:
    """The timed detectors. The shot-sampled ones draw from one generator each, as the
    pipeline and the video runner do (seeding a new generator costs 20-40 us a call)."""
    shots = replace(fixed, shots=1024)
    shots_calibrated = replace(calibrated, shots=1024)
    stream, stream_calibrated = np.random.default_rng(1), np.random.default_rng(1)
    return {
        "uu-exact": lambda im: detect_shadows_uu(im, fixed),
        "uu-exact-calibrated": lambda im: detect_shadows_uu(im, calibrated),
        "uu-1024-shots": lambda im: detect_shadows_uu(im, shots, rng=stream),
        "uu-1024-shots-calibrated": lambda im: detect_shadows_uu(
            im, shots_calibrated, rng=stream_calibrated
        ),
        "ibt": detect_ibt,
    }


#: UU-dagger variants whose time is reported as a ratio to IBT, with the issue-22 targets.
IBT_TARGETS: dict[str, float] = {
    "uu-exact": 1.0,
    "uu-exact-calibrated": 1.0,
    "uu-1024-shots": 1.5,
    "uu-1024-shots-calibrated": 1.5,
}


def bench_shadows(
    sizes: Sequence[tuple[int, int]] = SIZES,
    *,
    frames: int = BENCH_FRAMES,
    repeats: int = BENCH_REPEATS,
    aer_blocks: int = 200,
    include_lbp: bool = True,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Time every detector per frame and report medians, ratios and labelled estimates.

    The detectors take turns frame by frame and each reports the median of its single
    calls (:func:`time_in_turns`), so a change of load during the run falls on all of
    them alike and the ratios to IBT stay comparable between runs. The UU-dagger
    variants and IBT take turns together; the slow baselines (CBS, LBP) take theirs
    after them, on the same frames.

    Parameters
    ----------
    sizes : sequence of (width, height)
        Frame sizes (default 320x160 and 1280x720).
    frames : int
        Synthetic frames per size.
    repeats : int
        Passes over the frames; each timing is the median of the ``frames * repeats`` calls.
    aer_blocks : int
        Block circuits timed one by one on Aer (0 skips Aer).
    """
    check_int("frames", frames, 1, 1000)
    check_int("repeats", repeats, 1, 1000)
    check_int("aer_blocks", aer_blocks, 0, 100_000)
    say = progress or (lambda _msg: None)
    rows: list[dict[str, Any]] = []
    for width, height in sizes:
        images = bench_frames(width, height, frames, seed)
        calibrated = ShadowConfig(shots=None)
        fixed = replace(calibrated, centroid=detect_shadows_uu(images[0], calibrated).centroid)
        methods = _detectors(calibrated, fixed)
        slow: dict[str, Callable[[Any], object]] = {"cbs": detect_cbs}
        if include_lbp:
            slow["lbp"] = detect_lbp
        size = f"{width}x{height}"
        say(f"{size} {', '.join([*methods, *slow])}")
        # The slow baselines (milliseconds, megabytes of temporaries) take turns among
        # themselves: between two calls of 0.05 ms they would leave caches cold for
        # whichever fast detector came next and make its time depend on its neighbours.
        timings = time_in_turns(methods, images, repeats=repeats)
        timings.update(time_in_turns(slow, images, repeats=repeats))
        grid = block_grid((height, width), calibrated.downsample, calibrated.grid)
        n_blocks = grid.grid_shape[0] * grid.grid_shape[1]
        row: dict[str, Any] = {
            "size": size,
            "blocks": n_blocks,
            "frames": frames,
            "repeats": repeats,
            "seconds": {k: t.median_s for k, t in timings.items()},
        }
        if aer_blocks > 0:
            say(f"{size} aer per block")
            row.update(_aer_row(images[0], replace(fixed, shots=1024), timings, aer_blocks, seed))
        ibt = timings["ibt"].median_s
        row["ratio_uu_exact_to_ibt"] = timings["uu-exact"].median_s / ibt
        row["ratios_to_ibt"] = {name: timings[name].median_s / ibt for name in IBT_TARGETS}
        rows.append(row)
    estimates = [estimate_time(name).to_dict() for name in PROFILES]
    return {
        "kind": "measured",
        "machine": {
            "python": platform.python_version(),
            "processor": platform.processor() or platform.machine(),
        },
        "results": rows,
        "hardware_estimates": estimates,
    }
