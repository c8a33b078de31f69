"""What the compiled road-fill split gains in the whole pipeline, pass for pass.

``qdcnn.vision.removal_kernels.lit_levels`` replaced two ROI masks and three masked OpenCV
histograms per frame (the NumPy path of :func:`qdcnn.vision.removal.lit_medians`). This
script times image-split-uu's per-frame pipeline and decision (``qdcnn bench pipeline``'s
:func:`~qdcnn.experiments.pipeline_bench._time_method`, batches as ``qdcnn run`` makes them)
with the kernel and with the NumPy path, in turns (``--passes`` passes each, the order
alternating), in one process pinned to one core, on track1 frames rendered at each
``--sizes``. Only the removal's path changes between the turns; the shadow detector keeps
its kernels. All times are **measured**; the medians over the passes are reported.

Usage::

    python benchmarks/bench_road_fill.py [--json] [--passes 6] [--sizes 640x480,320x160]
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import sys
from dataclasses import replace
from typing import Any


def _size(text: str) -> tuple[int, int]:
    w, _, h = text.partition("x")
    return int(w), int(h)


def bench(sizes: list[tuple[int, int]], passes: int, frames: int) -> dict[str, Any]:
    from qdcnn.data.frames import load_frameset
    from qdcnn.data.synthetic import generate_drive
    from qdcnn.direction.model import default_config
    from qdcnn.experiments.pipeline_bench import _time_method, _trained, pin_to_one_core
    from qdcnn.vision import removal
    from qdcnn.vision.compiled import compiled

    core = pin_to_one_core()
    data = "synthetic:track1:200"
    cfg = replace(default_config(), seed=0)
    processor = _trained("image-split-uu", load_frameset(data, seed=1), cfg, data, 0, _quiet)
    paths = {"kernel": compiled, "numpy": lambda _module: None}
    rows = []
    for w, h in sizes:
        images = [s.image for s in generate_drive("track1", frames, seed=0, width=w, height=h)]
        times: dict[str, list[float]] = {name: [] for name in paths}
        for turn in range(2 * passes):
            name = list(paths)[turn % 2 if (turn // 2) % 2 == 0 else 1 - turn % 2]
            removal.compiled = paths[name]  # type: ignore[assignment]
            times[name].append(_time_method(processor, images, _quiet, passes=1)["ms_per_frame"])
        removal.compiled = compiled  # type: ignore[assignment]
        medians = {name: statistics.median(t) for name, t in times.items()}
        rows.append(
            {
                "size": [w, h],
                "ms_per_frame": medians,
                "passes": {name: [round(t, 4) for t in ts] for name, ts in times.items()},
                "numpy_over_kernel": medians["numpy"] / medians["kernel"],
            }
        )
    return {
        "kind": "measured",
        "what": "image-split-uu pipeline + decision, road-fill split compiled vs NumPy path",
        "frames": frames,
        "one_core": core is not None,
        "machine": {"python": platform.python_version()},
        "rows": rows,
    }


def _quiet(_message: str) -> None:
    pass


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--passes", type=int, default=6)
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--sizes", default="640x480,320x160")
    args = parser.parse_args()
    result = bench([_size(s) for s in args.sizes.split(",")], args.passes, args.frames)
    if args.json:
        print(json.dumps(result))
        return
    for row in result["rows"]:
        ms = row["ms_per_frame"]
        print(
            f"{row['size'][0]}x{row['size'][1]}: kernel {ms['kernel']:.3f} ms, NumPy path "
            f"{ms['numpy']:.3f} ms a frame ({row['numpy_over_kernel']:.2f}x)",
            file=sys.stdout,
        )


if __name__ == "__main__":
    main()
