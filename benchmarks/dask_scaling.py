"""Strong scaling of the video runner on a Dask LocalCluster, and a model for bigger machines.

Measured (wall-clock, the same synthetic 320x160 video, overlay off, image-split-uu):
the runner in one process, then on ``local:W`` (W single-threaded worker processes) for
each W of ``--workers`` (default 1, 2, 4), cluster start-up excluded; a no-op task's round
trip; the bytes each chunk moves (its share of the video read by a worker, and its share
of the result files assembled from the chunks' rows).

Modelled (an **estimate**, not a measurement): the run time on W workers as

    T(W) = S + F + (N * c + n_chunks * o) / W

with F the fixed cost of a cluster run (shipping the processor to the workers, their first
chunk's warm-up; fitted as local:1's measured time minus the rest of the model), S the
serial part (reading the manifest, assembling frames.csv; taken from the one-process run as
its wall time minus the chunks' own time), c the per-frame cost of one
worker (the one-process run's per-frame processing and decoding), o the per-task overhead
(the measured no-op round trip) and N / n_chunks the frames and chunks. The model is
checked against the measured W, then evaluated for a 16-core machine and a cluster of ten
16-core machines on a 10,000-hour fleet recording at 30 frames/s (1.08e9 frames), where
the scheduler's own cost per task (``--scheduler-ms``, Dask's documented order of 1 ms)
caps the tasks per second and so sets the smallest useful chunk.

    python benchmarks/dask_scaling.py [--frames 4000] [--workers 1,2,4] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

from bench_video import cached_video, processor, timed_run

FLEET_FRAMES = 10_000 * 3600 * 30
MACHINES = {"16-core machine": 16, "10 machines x 16 cores": 160}


def measure(frames: int, workers: list[int]) -> dict[str, Any]:
    video = cached_video(320, 160, frames)
    proc = processor()
    one = timed_run(video, False, None, proc)
    runs = {w: timed_run(video, False, f"local:{w}", proc) for w in workers}
    chunks = one["chunks"]
    return {
        "frames": one["frames"],
        "chunks": chunks,
        "cpus": os.cpu_count(),
        "load_average": os.getloadavg(),
        "one_process": _slim(one),
        "local": {str(w): _slim(r) for w, r in runs.items()},
        "speedup": {str(w): one["seconds"] / r["seconds"] for w, r in runs.items()},
        "bytes_per_chunk": {
            "video_read": video.stat().st_size / chunks,
            "chunk_results": _result_bytes(video, proc) / chunks,
        },
    }


def _slim(run: dict[str, Any]) -> dict[str, Any]:
    keys = ("seconds", "frames_per_second", "workers", "ms_per_frame", "chunks")
    return {k: run[k] for k in keys} | {"noop_task_seconds": run["noop_task_overhead_seconds"]}


def _result_bytes(video: Path, proc: Any) -> float:
    """Bytes a run's chunk results amount to (frames.csv and timings.csv), measured."""
    import tempfile

    from qdcnn.runtime.engine import RunOptions, run_inputs

    with tempfile.TemporaryDirectory() as out:
        run_inputs([video], proc, out, options=RunOptions(overlay=False))
        return float(sum(f.stat().st_size for f in Path(out).rglob("*.csv")))


def fit_model(m: dict[str, Any]) -> dict[str, float]:
    """S, c and o of the model from the one-process run and the measured no-op task."""
    one = m["one_process"]
    per_frame = one["ms_per_frame"]["process"] + one["ms_per_frame"]["decode_and_the_rest"]
    chunk_time = m["frames"] * per_frame / 1e3
    serial = max(one["seconds"] - chunk_time, 0.0)
    noop = [r["noop_task_seconds"] for r in m["local"].values() if r["noop_task_seconds"]]
    overhead = min(noop) if noop else 0.0
    model = {"serial_s": serial, "frame_s": per_frame / 1e3, "task_overhead_s": overhead}
    one_worker = m["local"].get("1")
    fixed = 0.0
    if one_worker is not None:
        rest = predict({**model, "fixed_s": 0.0}, m["frames"], m["chunks"], 1)
        fixed = max(one_worker["seconds"] - rest, 0.0)
    return {**model, "fixed_s": fixed}


def predict(model: dict[str, float], frames: float, chunks: float, workers: int) -> float:
    """Modelled seconds for ``frames`` in ``chunks`` chunks on ``workers`` workers."""
    work = frames * model["frame_s"] + chunks * model["task_overhead_s"]
    return model["serial_s"] + model["fixed_s"] + work / workers


def check_model(m: dict[str, Any], model: dict[str, float]) -> dict[str, Any]:
    """Modelled against measured seconds at each measured worker count."""
    out = {}
    for w, run in m["local"].items():
        workers = min(int(w), m["cpus"] or 1)  # more workers than cores share the cores
        modelled = predict(model, m["frames"], m["chunks"], workers)
        out[w] = {"measured_s": run["seconds"], "modelled_s": modelled}
    return out


def fleet(model: dict[str, float], scheduler_ms: float) -> dict[str, Any]:
    """Modelled frames/s and hours for the fleet recording, and the chunk size each needs."""
    out = {}
    for name, workers in MACHINES.items():
        # the scheduler hands out at most 1000/scheduler_ms tasks a second: chunks must be
        # long enough that the workers ask for fewer than that
        chunk_s_needed = workers * scheduler_ms / 1e3
        chunk = max(512, int(2 * chunk_s_needed / model["frame_s"]))
        chunks = FLEET_FRAMES / chunk
        steady = {**model, "serial_s": 0.0, "fixed_s": 0.0}  # negligible over 1e9 frames
        seconds = predict(steady, FLEET_FRAMES, chunks, workers)
        out[name] = {
            "workers": workers,
            "chunk_frames": chunk,
            "frames_per_second": FLEET_FRAMES / seconds,
            "hours": seconds / 3600,
        }
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=4000)
    parser.add_argument("--workers", default="1,2,4")
    parser.add_argument("--scheduler-ms", type=float, default=1.0)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--out", type=Path, help="also write the JSON here")
    args = parser.parse_args()
    t0 = time.perf_counter()
    m = measure(args.frames, [int(w) for w in args.workers.split(",")])
    model = fit_model(m)
    result = {
        "measured": m,
        "model": model,
        "model_check": check_model(m, model),
        "fleet_estimate": fleet(model, args.scheduler_ms),
        "benchmark_seconds": time.perf_counter() - t0,
    }
    text = json.dumps(result, indent=2)
    if args.out:
        args.out.write_text(text + "\n", encoding="utf-8")
    if args.json:
        print(text)
    else:
        print_summary(result)


def print_summary(r: dict[str, Any]) -> None:
    m = r["measured"]
    print(f"{m['frames']} frames, {m['chunks']} chunks, {m['cpus']} CPUs, load {m['load_average']}")
    print(f"one process: {m['one_process']['frames_per_second']:.0f} frames/s (measured)")
    for w, run in m["local"].items():
        check = r["model_check"][w]
        print(
            f"local:{w}: {run['frames_per_second']:.0f} frames/s, {m['speedup'][w]:.2f}x "
            f"(measured {check['measured_s']:.1f} s, modelled {check['modelled_s']:.1f} s)"
        )
    print("model:", {k: round(v, 6) for k, v in r["model"].items()})
    for name, f in r["fleet_estimate"].items():
        print(
            f"{name} (estimate): {f['frames_per_second']:.0f} frames/s, {f['hours']:.0f} h "
            f"for 1.08e9 frames, chunks of {f['chunk_frames']} frames"
        )
    sys.stdout.flush()


if __name__ == "__main__":
    main()
