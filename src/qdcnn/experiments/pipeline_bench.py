"""Benchmark of the whole per-frame pipeline: shadow removal, lanes, grouping and the decision.

Frames come from a synthetic drive (or a dataset spec); the classifier is trained
on other frames first. The process can be pinned to one CPU core
(``os.sched_setaffinity``) with OpenCV and BLAS limited to one thread, so the
frames-per-second figure is a one-core number. CNN inference frames/s are
reported beside it when torch is installed.

:func:`bench_lane_stage` times the lane stage alone on 640x480 frames of the synthetic
``dashcam`` preset, as a real windscreen camera gives them: the per-recording camera
estimate (auto ROI, timed once, reported apart) and per frame the colour evidence, Canny,
Hough, the segment filters and the grouping (``qdcnn bench pipeline`` adds it as a row).
"""

from __future__ import annotations

import os
import platform
import time
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._optional import has_torch
from qdcnn._validation import check_int
from qdcnn.config import GroupingConfig, LaneConfig, PipelineConfig
from qdcnn.data.frames import FrameSet, load_frameset
from qdcnn.direction.features import compute_features
from qdcnn.direction.methods import get_method
from qdcnn.direction.model import default_config, train_direction_model
from qdcnn.pipeline import auto_lanes, process_frame, recording_sample


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
    lane_stage: bool = True,
    sizes: tuple[tuple[int, int], ...] = ((640, 480),),
) -> dict[str, Any]:
    """Frames per second of the per-frame pipeline + classifier decision for each method
    (measured; batches of frames as ``qdcnn run`` processes them, :func:`_time_method`).

    Each of ``sizes`` (width, height) adds a row: the first method's trained processor on
    the same drive rendered at that size (the data's synthetic preset, ``track1`` for a
    recording; :func:`_time_at_size`). With ``lane_stage`` the lane stage alone at 640x480
    (:func:`bench_lane_stage`) is one more row of ``pipeline``.
    """
    check_int("frames", frames, 1, 100_000)
    log = say or (lambda _m: None)
    core = pin_to_one_core() if one_core else None
    cfg = replace(default_config(), seed=seed)
    train = load_frameset(data, seed=seed + 1)
    test = load_frameset(data, seed=seed)
    images = [test.image(i) for i in range(min(frames, len(test)))]
    processors = [_trained(method, train, cfg, data, seed, log) for method in methods]
    rows = [_time_method(p, images, log) for p in processors[1:]]
    if processors:
        rows[:0] = _time_with_and_without_kernels(processors[0], images, log)
    for size in sizes if processors else ():
        rows.append(_time_at_size(processors[0], data, len(images), size, seed, log))
    result: dict[str, Any] = {
        "kind": "measured",
        "data": data,
        "frames": len(images),
        "size": list(images[0].shape[1::-1]),
        "one_core": core is not None,
        "machine": {"python": platform.python_version(), "cpus": os.cpu_count()},
        "pipeline": rows,
    }
    if lane_stage:
        log("timing the lane stage at 640x480")
        row = bench_lane_stage(seed=seed)
        rows.append(row)
        result["lane_stage"] = row
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


def _trained(
    method: str,
    train: FrameSet,
    cfg: PipelineConfig,
    data: str,
    seed: int,
    log: Callable[[str], None],
) -> Any:
    """``method`` trained on ``train``, as a :class:`LaneDirectionProcessor`."""
    from qdcnn.direction.processor import LaneDirectionProcessor

    grouping = get_method(method).grouping
    assert grouping is not None
    log(f"training {method}")
    table = compute_features(train, cfg, (grouping,))
    keep = table.readable
    model = train_direction_model(
        method, table.features[grouping][keep], train.labels()[keep], cfg, data, inner_folds=0
    )
    return LaneDirectionProcessor(model, seed=seed)


def _time_method(
    processor: Any, images: list[NDArray[np.uint8]], log: Callable[[str], None], passes: int = 3
) -> dict[str, Any]:
    """Time a trained processor's per-frame pipeline and decision on ``images`` as ``qdcnn
    run`` does them: :meth:`LaneDirectionProcessor.process_batch` on batches of
    :data:`~qdcnn.runtime.chunks.BATCH_FRAMES` frames (shadows and lanes per frame, one
    classifier call per batch, each frame's result the one it gets alone). After one
    warm-up batch; the median of ``passes`` passes."""
    from qdcnn.runtime.chunks import BATCH_FRAMES

    method = processor.model.method
    batches = [
        (images[i : i + BATCH_FRAMES], list(range(i, min(i + BATCH_FRAMES, len(images)))))
        for i in range(0, len(images), BATCH_FRAMES)
    ]
    log(f"timing {method}")
    processor.process_batch(*batches[0])
    times = []
    for _ in range(passes):
        t0 = time.perf_counter()
        for batch, indices in batches:
            processor.process_batch(batch, indices)
        times.append((time.perf_counter() - t0) / len(images))
    per_frame = float(np.median(times))
    return {
        "method": method,
        "ms_per_frame": 1e3 * per_frame,
        "frames_per_second": 1.0 / per_frame,
    }


def _time_with_and_without_kernels(
    processor: Any, images: list[NDArray[np.uint8]], log: Callable[[str], None]
) -> list[dict[str, Any]]:
    """:func:`_time_method` with the compiled kernels (shadow detector, road-fill removal)
    and with their NumPy paths (``QDCNN_KERNELS=numpy``), pass for pass in turns: what the
    kernels gain, measured on the same frames while the machine's speed drifts alike for
    both."""
    from qdcnn.vision.compiled import KERNELS_VARIABLE

    before = os.environ.get(KERNELS_VARIABLE)
    passes: dict[str, list[dict[str, Any]]] = {"numba": [], "numpy": []}
    try:
        for _ in range(3):
            for kernels, out in passes.items():
                os.environ[KERNELS_VARIABLE] = kernels
                out.append(_time_method(processor, images, log, passes=1))
    finally:
        if before is None:
            os.environ.pop(KERNELS_VARIABLE, None)
        else:
            os.environ[KERNELS_VARIABLE] = before
    rows = [_median_row(out) for out in passes.values()]
    rows[1]["method"] += f", NumPy paths, no compiled kernels ({KERNELS_VARIABLE}=numpy)"
    return rows


def _median_row(rows: list[dict[str, Any]]) -> dict[str, Any]:
    per_frame = float(np.median([row["ms_per_frame"] for row in rows])) / 1e3
    return {**rows[0], "ms_per_frame": 1e3 * per_frame, "frames_per_second": 1.0 / per_frame}


def _time_at_size(
    processor: Any,
    data: str,
    frames: int,
    size: tuple[int, int],
    seed: int,
    log: Callable[[str], None],
) -> dict[str, Any]:
    """:func:`_time_method` on ``frames`` frames of the data's synthetic preset (``track1``
    for a recording) rendered at ``size``, with the processor trained at the data's size."""
    from qdcnn.data.frames import parse_data_spec
    from qdcnn.data.synthetic import generate_drive

    parsed = parse_data_spec(data)
    preset = parsed.value.partition(":")[0] if parsed.kind == "synthetic" else "track1"
    w, h = size
    log(f"rendering {frames} {preset} frames at {w}x{h}")
    images = [s.image for s in generate_drive(preset, frames, seed=seed, width=w, height=h)]
    row = _time_method(processor, images, log)
    row["method"] = f"{row['method']}, {w}x{h} ({preset} rendered at that size)"
    row["size"] = [w, h]
    return row


def lane_stage_config() -> PipelineConfig:
    """The lane settings the 640x480 row times: ``dashcam`` with Lab marks and both filters."""
    lanes = LaneConfig.dashcam(
        remove_shadows=False,
        marks="lab",
        min_segment_angle=20.0,
        max_segment_angle=80.0,
        vp_tolerance=0.3,
    )
    return PipelineConfig(lanes=lanes, grouping=GroupingConfig(inner_lines=True))


def bench_lane_stage(
    *, frames: int = 60, size: tuple[int, int] = (640, 480), seed: int = 0, passes: int = 3
) -> dict[str, Any]:
    """Measured one-thread time of the lane stage (no shadow removal, no decision).

    Auto ROI (:func:`qdcnn.pipeline.auto_lanes` on the drive's sample frames) once, then per
    frame :func:`process_frame` with image-split grouping under :func:`lane_stage_config`
    (Lab marks, angle and vanishing-point filters, innermost lines). The median of
    ``passes`` passes over the frames is reported, as wall time and as this process's CPU
    time (the two agree on an idle core; on a shared machine the wall time also counts
    the other processes' turns).
    """
    from qdcnn.data.synthetic import generate_drive

    w, h = size
    images = [s.image for s in generate_drive("dashcam", frames, seed=seed, width=w, height=h)]
    t0 = time.perf_counter()
    cfg, camera = auto_lanes(
        [images[i] for i in recording_sample(len(images))], lane_stage_config()
    )
    estimate = time.perf_counter() - t0
    process_frame(images[0], cfg, ("image-split",))
    runs, cpu = [], []
    for _ in range(passes):
        t0, c0 = time.perf_counter(), time.process_time()
        for image in images:
            process_frame(image, cfg, ("image-split",))
        runs.append((time.perf_counter() - t0) / len(images))
        cpu.append((time.process_time() - c0) / len(images))
    per_frame = float(np.median(runs))
    return {
        "method": f"lane stage only, {w}x{h} (auto ROI, Lab marks, filters, image-split)",
        "ms_per_frame": 1e3 * per_frame,
        "frames_per_second": 1.0 / per_frame,
        # CPU time of this process: what the wall time is when no other process shares the core
        "cpu_ms_per_frame": 1e3 * float(np.median(cpu)),
        "camera_estimate_s": estimate,
        "camera": camera.describe(),
        "size": [w, h],
    }
