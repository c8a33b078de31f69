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

from dataclasses import replace
from typing import Any

from in_turns import main, measured, size_row, turn_name


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
            name = turn_name(turn, list(paths))
            removal.compiled = paths[name]  # type: ignore[assignment]
            times[name].append(_time_method(processor, images, _quiet, passes=1)["ms_per_frame"])
        removal.compiled = compiled  # type: ignore[assignment]
        rows.append(size_row((w, h), times, "ms_per_frame", 4))
    what = "image-split-uu pipeline + decision, road-fill split compiled vs NumPy path"
    return measured(what, frames, core is not None, rows)


def _quiet(_message: str) -> None:
    pass


def _line(row: dict[str, Any]) -> str:
    ms = row["ms_per_frame"]
    return (
        f"{row['size'][0]}x{row['size'][1]}: kernel {ms['kernel']:.3f} ms, NumPy path "
        f"{ms['numpy']:.3f} ms a frame ({row['numpy_over_kernel']:.2f}x)"
    )


if __name__ == "__main__":
    main(__doc__, bench, (6, 100, "640x480,320x160"), _line)
