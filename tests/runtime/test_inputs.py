"""A run's inputs: unique names, what planning reads of them, and their identity."""

from __future__ import annotations

from pathlib import Path

from video_fakes import ListSource, write_clip

from qdcnn.data.video import MAX_VIDEO_PIXELS, VideoIndex
from qdcnn.runtime.inputs import (
    DEFAULT_OVERLAY_FPS,
    SourceInput,
    VideoInput,
    input_identity,
    probe_input,
    resolve_inputs,
)


def test_inputs_get_unique_names_and_sources_stay_with_the_client(tmp_path: Path) -> None:
    first = write_clip(tmp_path / "a" / "drive.mp4", 4)
    second = write_clip(tmp_path / "b" / "drive.mp4", 4)
    clash = write_clip(tmp_path / "summary.json.mp4", 4)
    memory, again = ListSource(3), ListSource(2)
    inputs, sources = resolve_inputs([first, second, clash, memory, again])
    names = [i.name for i in inputs]
    assert names == ["drive", "drive-2", "summary.json-2", "memory", "memory-2"]
    assert isinstance(inputs[0], VideoInput) and isinstance(inputs[3], SourceInput)
    assert sources == {"memory": memory, "memory-2": again}


def test_a_probe_reads_frames_size_and_frame_rate(tmp_path: Path) -> None:
    clip = write_clip(tmp_path / "drive.mp4", 6)
    inputs, sources = resolve_inputs([clip, ListSource(3)])
    video = probe_input(
        inputs[0], sources, decoder="auto", max_pixels=MAX_VIDEO_PIXELS, overlay_fps=None
    )
    assert (video.frames, video.size, video.use_timestamps, video.fps) == (6, (64, 48), True, 10.0)
    assert video.info is not None and video.truncated_from is None
    assert isinstance(sources["drive"], VideoIndex)  # chunks reopen the file with it
    source = probe_input(
        inputs[1], sources, decoder="auto", max_pixels=MAX_VIDEO_PIXELS, overlay_fps=None
    )
    assert (source.frames, source.size, source.use_timestamps) == (3, (64, 48), False)
    assert source.fps == DEFAULT_OVERLAY_FPS and source.info is None
    assert input_identity(inputs[1], sources) == {
        "kind": "source",
        "spec": "memory:3",
        "frames": 3,
        "fingerprint": "list-3",
    }
