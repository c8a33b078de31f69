"""Frames per second of the video runner: decode, image-split-uu pipeline, overlay encode.

Targets (issue 22, raised from issue 12's 300 and 500): a 10,000-frame 320x160 synthetic
video, decode + image-split-uu + overlay encode on one core at >= 500 frames/s, >= 800
without the overlay; frames/s at 640x480 and 1280x720; ``local:2`` (a Dask LocalCluster
of two worker processes) at >= 1.7x one process on the same 10,000-frame job, with the
per-task overhead.

All times are **measured** wall-clock times of :func:`qdcnn.runtime.engine.run_inputs`
(reading the file, every frame's processing, writing chunks, assembling frames.csv and
overlay.mp4, the manifest). One-core parts run in a child process pinned to one CPU
(``os.sched_setaffinity``, OpenCV and BLAS limited to one thread, PyAV decoding and
encoding on the calling thread). The breakdown comes from the run's ``timings.csv``
(processing and overlay per frame); "decode and the rest" is the remainder of the wall time.
Means are what the wall time is made of; medians show a frame's cost without the spikes
that other processes on a shared machine add (both measured; compare runs by the load
averages printed with them).

The videos are rendered once with :func:`qdcnn.data.synthetic.iter_drive` (track1) and
cached in ``$QDCNN_CACHE/bench-video`` (default ``~/.cache/qdcnn``; about 80 s the first
time). The direction model is image-split-uu trained on ``synthetic:track1:300`` (seed 0).

Usage::

    python benchmarks/bench_video.py [--json] [--frames 10000] [--parts all]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

PARTS = ("one-core", "sizes", "scaling")
SIZES = ((640, 480, 600), (1280, 720, 300))  # width, height, frames


def cached_video(width: int, height: int, frames: int) -> Path:
    """The synthetic drive video of this size, rendered on first use."""
    from qdcnn.data.synthetic import iter_drive
    from qdcnn.data.writers import write_video
    from qdcnn.direction.features import cache_dir

    path = cache_dir() / "bench-video" / f"track1-{width}x{height}-{frames}.mp4"
    if not path.exists():
        print(f"rendering {path} (once)", file=sys.stderr)
        scenes = iter_drive("track1", frames, seed=0, width=width, height=height)
        write_video(scenes, path, fps=10.0)
    return path


def processor() -> Any:
    from qdcnn.direction.processor import LaneDirectionProcessor

    return LaneDirectionProcessor.train("image-split-uu", data="synthetic:track1:300", seed=0)


def timed_run(
    video: Path, overlay: bool, scheduler: str | None = None, proc: Any = None
) -> dict[str, Any]:
    """One run of the runner into a fresh folder; wall time and the per-frame breakdown."""
    from qdcnn.runtime.engine import RunOptions, run_inputs
    from qdcnn.runtime.scheduler import Executor

    proc = proc or processor()
    with tempfile.TemporaryDirectory() as out, Executor(scheduler, timeout=120) as ex:
        overhead = ex.measure_overhead(20 if scheduler else 200)
        t0 = time.perf_counter()
        result = run_inputs([video], proc, out, options=RunOptions(overlay=overlay), executor=ex)
        wall = time.perf_counter() - t0
        name = result.inputs[0].name
        with open(Path(out) / name / "timings.csv", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
    frames = result.frames_processed
    process_ms = [float(r["process_ms"]) for r in rows]
    overlay_ms = [float(r["overlay_ms"]) for r in rows]
    process_s, overlay_s = sum(process_ms) / 1e3, sum(overlay_ms) / 1e3
    return {
        "video": video.name,
        "frames": frames,
        "overlay": overlay,
        "scheduler": scheduler or "none",
        "workers": ex.workers,
        "seconds": wall,
        "frames_per_second": frames / wall,
        "ms_per_frame": {
            "process": 1e3 * process_s / frames,
            "overlay_draw_and_encode": 1e3 * overlay_s / frames,
            "decode_and_the_rest": 1e3 * max(wall * ex.workers - process_s - overlay_s, 0) / frames,
        },
        "median_ms_per_frame": {
            "process": statistics.median(process_ms),
            "overlay_draw_and_encode": statistics.median(overlay_ms),
        },
        "chunks": result.inputs[0].chunks,
        "ok": result.ok,
        "noop_task_overhead_seconds": overhead,
        "executor": result.executor.get("stats"),
    }


def part_one_core(frames: int) -> dict[str, Any]:
    from qdcnn.experiments.pipeline_bench import pin_to_one_core

    core = pin_to_one_core()
    video = cached_video(320, 160, frames)
    proc = processor()
    return {
        "core": core,
        "decode_only": decode_only(video),
        "with_overlay": timed_run(video, True, proc=proc),
        "without_overlay": timed_run(video, False, proc=proc),
    }


def decode_only(video: Path) -> dict[str, Any]:
    """Frames/s of decoding alone (PyAV, one thread, RGB arrays), and the median frame."""
    from qdcnn.data.video import VideoReader

    times = []
    t0 = time.perf_counter()
    with VideoReader(video) as reader:
        start = time.perf_counter()
        for _ in reader:
            now = time.perf_counter()
            times.append(now - start)
            start = now
    wall = time.perf_counter() - t0
    return {
        "frames": len(times),
        "seconds": wall,
        "frames_per_second": len(times) / wall,
        "median_ms_per_frame": 1e3 * statistics.median(times),
    }


def part_sizes() -> dict[str, Any]:
    from qdcnn.experiments.pipeline_bench import pin_to_one_core

    core = pin_to_one_core()
    proc = processor()
    rows = []
    for w, h, n in SIZES:
        video = cached_video(w, h, n)
        for overlay in (True, False):
            rows.append({"size": f"{w}x{h}", **timed_run(video, overlay, proc=proc)})
    return {"core": core, "runs": rows}


def part_scaling(frames: int) -> dict[str, Any]:
    video = cached_video(320, 160, frames)
    proc = processor()
    one = timed_run(video, True, None, proc)
    two = timed_run(video, True, "local:2", proc)
    return {
        "one_process": one,
        "local_2": two,
        "speedup": one["seconds"] / two["seconds"],
        "note": "both unpinned on the same machine; local:2 excludes cluster start-up",
    }


def run_part(part: str, frames: int) -> dict[str, Any]:
    """Run a part in a child process (so pinning one core does not affect the others)."""
    cmd = [sys.executable, __file__, "--part-child", part, "--frames", str(frames)]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"part {part} failed:\n{done.stderr[-4000:]}")
    return dict(json.loads(done.stdout.strip().splitlines()[-1]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.add_argument("--frames", type=int, default=10_000)
    parser.add_argument("--parts", default="all", help="all or a comma list of " + ",".join(PARTS))
    parser.add_argument("--part-child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.part_child:
        out = {
            "one-core": lambda: part_one_core(args.frames),
            "sizes": part_sizes,
            "scaling": lambda: part_scaling(args.frames),
        }[args.part_child]()
        print(json.dumps(out))
        return
    parts = PARTS if args.parts == "all" else tuple(args.parts.split(","))
    cached_video(320, 160, args.frames)  # render before any timing
    for w, h, n in SIZES if "sizes" in parts else ():
        cached_video(w, h, n)
    result: dict[str, Any] = {
        "kind": "measured",
        "machine": {
            "python": platform.python_version(),
            "cpus": os.cpu_count(),
            "load_average_at_start": os.getloadavg(),
        },
        "targets": {
            "one_core_with_overlay_fps": 500,
            "one_core_without_overlay_fps": 800,
            "local_2_speedup": 1.7,
        },
    }
    for part in parts:
        t0 = time.perf_counter()
        result[part] = run_part(part, args.frames)
        result[part]["part_seconds"] = time.perf_counter() - t0
    result["machine"]["load_average_at_end"] = os.getloadavg()
    if args.json:
        print(json.dumps(result))
    else:
        print_table(result)


def print_table(result: dict[str, Any]) -> None:
    def line(label: str, run: dict[str, Any]) -> None:
        ms, med = run["ms_per_frame"], run["median_ms_per_frame"]
        print(
            f"{label:<38} {run['frames_per_second']:8.1f} fps  "
            f"(mean ms: process {ms['process']:.2f}, overlay {ms['overlay_draw_and_encode']:.2f}, "
            f"decode+rest {ms['decode_and_the_rest']:.2f}; median ms: process "
            f"{med['process']:.2f}, overlay {med['overlay_draw_and_encode']:.2f}; "
            f"{run['frames']} frames)"
        )

    print("measured; load average", result["machine"]["load_average_at_start"])
    if "one-core" in result:
        part = result["one-core"]
        dec = part["decode_only"]
        print(
            f"{'320x160, one core, decode only':<38} {dec['frames_per_second']:8.1f} fps  "
            f"(median {dec['median_ms_per_frame']:.2f} ms per frame)"
        )
        line("320x160, one core, with overlay", part["with_overlay"])
        line("320x160, one core, without overlay", part["without_overlay"])
    if "sizes" in result:
        for run in result["sizes"]["runs"]:
            line(f"{run['size']}, one core, overlay={run['overlay']}", run)
    if "scaling" in result:
        part = result["scaling"]
        line("320x160, one process (2 cores free)", part["one_process"])
        line("320x160, local:2", part["local_2"])
        print(
            f"local:2 speedup {part['speedup']:.2f}x; no-op task overhead "
            f"{1e3 * part['local_2']['noop_task_overhead_seconds']:.2f} ms (local:2), "
            f"{1e3 * part['one_process']['noop_task_overhead_seconds']:.4f} ms (in-process)"
        )


if __name__ == "__main__":
    main()
