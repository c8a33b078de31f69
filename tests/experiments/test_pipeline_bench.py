"""The pipeline bench: one row per method, one with the NumPy paths, one per extra
frame size (structure, not speed)."""

from __future__ import annotations

import os

from qdcnn.experiments.pipeline_bench import bench_pipeline


def test_a_size_row_times_the_first_method_on_the_drive_rendered_at_that_size() -> None:
    said: list[str] = []
    kernels = os.environ.get("QDCNN_KERNELS")
    result = bench_pipeline(
        data="synthetic:track1:40",
        methods=("image-split-uu",),
        frames=8,
        one_core=False,
        cnn=False,
        lane_stage=False,
        sizes=((96, 64),),
        say=said.append,
    )
    first, numpy_paths, sized = result["pipeline"]
    assert first["method"] == "image-split-uu" and result["size"] == [320, 160]
    assert (
        numpy_paths["method"]
        == "image-split-uu, NumPy paths, no compiled kernels (QDCNN_KERNELS=numpy)"
    )
    assert os.environ.get("QDCNN_KERNELS") == kernels  # restored after the row
    assert sized["size"] == [96, 64] and sized["method"].startswith("image-split-uu, 96x64")
    assert all(row["frames_per_second"] > 0 for row in result["pipeline"])
    assert "rendering 8 track1 frames at 96x64" in said
