"""Synthetic drives and the writers stream: one scene at a time, identical results."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from qdcnn.data import synthetic
from qdcnn.data.images import read_image
from qdcnn.data.synthetic import RoadScene, generate_drive, iter_drive
from qdcnn.data.writers import (
    CarlaWriter,
    ShadowSetWriter,
    UdacityWriter,
    write_carla,
    write_layouts,
    write_shadow_set,
    write_udacity,
    write_video,
)
from qdcnn.errors import ParameterError


def _same(a: RoadScene, b: RoadScene) -> bool:
    return (
        np.array_equal(a.image, b.image)
        and np.array_equal(a.shadow_mask, b.shadow_mask)
        and np.array_equal(a.road_mask, b.road_mask)
        and len(a.lane_lines) == len(b.lane_lines)
        and all(np.array_equal(x, y) for x, y in zip(a.lane_lines, b.lane_lines, strict=True))
        and (a.steering, a.curvature, a.direction, a.speed, a.frame)
        == (b.steering, b.curvature, b.direction, b.speed, b.frame)
    )


@pytest.mark.parametrize("preset", ["track1", "track2", "rain"])
def test_iter_drive_yields_the_scenes_of_generate_drive(preset: str) -> None:
    listed = generate_drive(preset, 12, seed=4, width=96, height=48, fps=15.0)
    streamed = list(iter_drive(preset, 12, seed=4, width=96, height=48, fps=15.0))
    assert len(streamed) == 12 and all(_same(a, b) for a, b in zip(listed, streamed, strict=True))


def test_iter_drive_renders_only_what_is_taken(monkeypatch: pytest.MonkeyPatch) -> None:
    rendered = []
    original = synthetic._scene

    def counting(*args: object, **kwargs: object) -> RoadScene:
        rendered.append(1)
        return original(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(synthetic, "_scene", counting)
    scenes = iter_drive("track1", 5000, seed=1, width=64, height=32)
    assert isinstance(scenes, Iterator) and rendered == []
    first = [next(scenes) for _ in range(3)]
    assert len(rendered) == 3 and [s.frame for s in first] == [0, 1, 2]


def test_iter_drive_checks_arguments_when_called() -> None:
    with pytest.raises(ParameterError, match="preset='mars' is invalid"):
        iter_drive("mars", 3)
    with pytest.raises(ParameterError, match="n=-1 is invalid"):
        iter_drive("track1", -1)
    with pytest.raises(ParameterError, match="fps=0 is invalid"):
        iter_drive("track1", 3, fps=0)
    assert list(iter_drive("track1", 0)) == []


def _files(root: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
    }


def test_writers_give_the_same_files_from_an_iterator_as_from_a_list(tmp_path: Path) -> None:
    scenes = generate_drive("track2", 6, seed=2, width=64, height=32)
    for name, writer in (("shadows", write_shadow_set), ("carla", write_carla)):
        writer(scenes, tmp_path / "list" / name)
        writer(iter_drive("track2", 6, seed=2, width=64, height=32), tmp_path / "iter" / name)
        assert _files(tmp_path / "list" / name) == _files(tmp_path / "iter" / name)
    a = write_udacity(scenes, tmp_path / "list" / "u").read_text()
    b = write_udacity(iter(scenes), tmp_path / "iter" / "u").read_text()
    assert a.replace("/list/", "/") == b.replace("/iter/", "/")


def test_one_pass_feeds_several_layouts_and_a_video(tmp_path: Path) -> None:
    av = pytest.importorskip("av")
    from qdcnn.data.writers import VideoSceneWriter

    sinks = [
        UdacityWriter(tmp_path / "u"),
        ShadowSetWriter(tmp_path / "s"),
        CarlaWriter(tmp_path / "c"),
        VideoSceneWriter(tmp_path / "drive.mp4", fps=10),
    ]
    paths = write_layouts(iter_drive("rain", 7, seed=3, width=64, height=32), sinks)
    assert paths[0].name == "driving_log.csv" and len(paths[0].read_text().splitlines()) == 7
    assert len(list((tmp_path / "s" / "masks").iterdir())) == 7
    assert len((tmp_path / "c" / "steer_values.txt").read_text().splitlines()) == 7
    with av.open(str(tmp_path / "drive.mp4")) as c:
        assert sum(1 for _ in c.decode(video=0)) == 7
    scene = next(iter_drive("rain", 7, seed=3, width=64, height=32))
    assert np.array_equal(read_image(tmp_path / "c" / "images" / "000000.png"), scene.image)


def test_write_video_streams_frames_or_scenes(tmp_path: Path) -> None:
    pytest.importorskip("av")
    from qdcnn.data.video import VideoReader

    path = write_video(iter_drive("track1", 9, seed=5, width=64, height=32), tmp_path / "a.mp4")
    frames = (np.full((32, 64, 3), i * 20, np.uint8) for i in range(5))
    write_video(frames, tmp_path / "b.mp4", fps=5)
    with VideoReader(path) as a, VideoReader(tmp_path / "b.mp4") as b:
        assert (len(a), len(b), b.info.fps) == (9, 5, 5.0)
        means = [float(f.image.mean()) for f in b]
    assert np.allclose(means, [0, 20, 40, 60, 80], atol=1.5)  # limited-range YUV rounding


def test_a_failing_stream_leaves_no_label_file(tmp_path: Path) -> None:
    def broken() -> Iterator[RoadScene]:
        yield from iter_drive("track1", 2, seed=1, width=64, height=32)
        raise RuntimeError("renderer crashed")

    with pytest.raises(RuntimeError):
        write_udacity(broken(), tmp_path / "u")
    with pytest.raises(RuntimeError):
        write_carla(broken(), tmp_path / "c", labels="csv")
    left = [p.name for p in tmp_path.rglob("*") if p.is_file() and p.suffix != ".jpg"]
    assert [n for n in left if not n.endswith(".png")] == []  # no log, no label, no temp file
