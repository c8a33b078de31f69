"""Writers of synthetic scenes in the real data sets' layouts."""

from __future__ import annotations

from datetime import datetime
from itertools import pairwise
from pathlib import Path

import cv2
import numpy as np
import pytest

from conftest import shared_recording
from qdcnn.data.images import read_image, read_mask
from qdcnn.data.synthetic import RoadScene, generate_drive, generate_scenes
from qdcnn.data.writers import (
    simulator_number,
    write_carla,
    write_shadow_set,
    write_udacity,
)
from qdcnn.errors import ParameterError


@pytest.fixture(scope="module")
def scenes() -> list[RoadScene]:
    return generate_drive("track2", 5, seed=1)


def _stamp(name: str) -> datetime:
    return datetime.strptime(name[len("center_") : -len(".jpg")], "%Y_%m_%d_%H_%M_%S_%f")


def test_udacity_log_matches_the_simulator_layout(scenes: list[RoadScene], tmp_path: Path) -> None:
    log = write_udacity(scenes, tmp_path / "rec", start=datetime(2023, 2, 17, 17, 9, 20, 794000))
    assert log == (tmp_path / "rec" / "driving_log.csv").resolve()
    raw = log.read_text()
    assert not raw.startswith("center") and raw.endswith("\n")
    rows = [line.split(", ") for line in raw.splitlines()]
    assert len(rows) == len(scenes)
    for row, scene in zip(rows, scenes, strict=True):
        assert len(row) == 7
        center, left, right = (Path(p) for p in row[:3])
        assert all(p.is_absolute() for p in (center, left, right))
        assert center.parent == log.parent / "IMG" and center.name.startswith("center_")
        assert center.is_file() and not left.exists() and not right.exists()
        assert left.name == center.name.replace("center_", "left_")
        assert float(row[3]) == pytest.approx(scene.steering, abs=1e-6)
        assert (row[4], row[5]) == ("1", "0")
        assert float(row[6]) == pytest.approx(scene.speed, abs=1e-4)
        back = read_image(center)
        assert back.shape == scene.image.shape
        assert np.abs(back.astype(float) - scene.image).mean() < 4.0  # JPEG, quality 95
    stamps = [_stamp(Path(r[0]).name) for r in rows]
    assert stamps[0] == datetime(2023, 2, 17, 17, 9, 20, 794000)
    assert all((b - a).total_seconds() == pytest.approx(0.1) for a, b in pairwise(stamps))


def test_udacity_timestamps_follow_the_frame_rate(scenes: list[RoadScene], tmp_path: Path) -> None:
    log = write_udacity(scenes, tmp_path, fps=30.0)
    stamps = [_stamp(Path(line.split(", ")[0]).name) for line in log.read_text().splitlines()]
    gaps = [(b - a).total_seconds() for a, b in pairwise(stamps)]
    assert all(abs(g - 1 / 30) <= 0.001 for g in gaps)
    assert (stamps[-1] - stamps[0]).total_seconds() == pytest.approx(4 / 30, abs=0.001)


def test_udacity_numbers_are_formatted_like_the_simulator() -> None:
    assert simulator_number(0.0) == "0"
    assert simulator_number(-0.0) == "0"
    assert simulator_number(1.0) == "1"
    assert simulator_number(-0.06741844) == "-0.06741844"
    assert simulator_number(7.790132e-05) == "7.790132E-05"
    assert simulator_number(30.1903149) == "30.19031"
    with pytest.raises(ParameterError):
        simulator_number(float("nan"))


def test_udacity_rows_have_the_shape_of_a_real_recording(
    scenes: list[RoadScene], tmp_path: Path
) -> None:
    real = shared_recording("udacity-lake-track") / "driving_log.csv"
    real_row = real.read_text().splitlines()[0].split(", ")
    ours = write_udacity(scenes[:1], tmp_path).read_text().splitlines()[0].split(", ")
    assert len(ours) == len(real_row) == 7
    for a, b in zip(ours[:3], real_row[:3], strict=True):
        kind = b.replace("\\", "/").rsplit("/", 1)[1].split("_")[0]
        assert Path(a).name.split("_")[0] == kind
        assert len(Path(a).name) == len(b.replace("\\", "/").rsplit("/", 1)[1])


def test_shadow_set_round_trips_exactly(tmp_path: Path) -> None:
    scenes = generate_scenes("track2", 3, seed=4, width=96, height=48)
    root = write_shadow_set(scenes, tmp_path / "shadows")
    assert sorted(p.name for p in (root / "images").iterdir()) == [
        "scene_000000.png",
        "scene_000001.png",
        "scene_000002.png",
    ]
    for i, scene in enumerate(scenes):
        stem = f"scene_{i:06d}.png"
        assert np.array_equal(read_image(root / "images" / stem), scene.image)
        assert np.array_equal(read_mask(root / "masks" / stem), scene.shadow_mask)
        raw = cv2.imread(str(root / "masks" / stem), cv2.IMREAD_UNCHANGED)
        assert raw.ndim == 2 and set(np.unique(raw)) <= {0, 255}


@pytest.mark.parametrize("labels", ["txt", "csv"])
def test_carla_folder_with_labels(labels: str, tmp_path: Path) -> None:
    scenes = generate_scenes("rain", 4, seed=2, width=64, height=32)
    out = write_carla(scenes, tmp_path / "carla", labels=labels)  # type: ignore[arg-type]
    names = sorted(p.name for p in (tmp_path / "carla" / "images").iterdir())
    assert names == [f"{i:06d}.png" for i in range(4)]
    for name, scene in zip(names, scenes, strict=True):
        assert np.array_equal(read_image(tmp_path / "carla" / "images" / name), scene.image)
    lines = out.read_text().splitlines()
    if labels == "txt":
        assert out.name == "steer_values.txt"
        assert [float(v) for v in lines] == [s.steering for s in scenes]
    else:
        assert out.name == "labels.csv"
        assert lines[0] == "image,steering"
        rows = [line.split(",") for line in lines[1:]]
        assert [r[0] for r in rows] == names
        assert [float(r[1]) for r in rows] == [s.steering for s in scenes]


def test_writers_reject_bad_parameters(scenes: list[RoadScene], tmp_path: Path) -> None:
    with pytest.raises(ParameterError, match="labels='json' is invalid: 'txt' or 'csv'"):
        write_carla(scenes, tmp_path, labels="json")  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="fps=0 is invalid"):
        write_udacity(scenes, tmp_path, fps=0)


def test_written_sets_load_with_the_project_loaders(
    scenes: list[RoadScene], tmp_path: Path
) -> None:
    udacity = pytest.importorskip("qdcnn.data.udacity")
    carla = pytest.importorskip("qdcnn.data.carla")
    rec = udacity.load_udacity(write_udacity(scenes, tmp_path / "u", fps=10.0), strict=True)
    written = sorted(p.name for p in (tmp_path / "u" / "IMG").iterdir())
    assert [p.name for p in rec.frames] == written
    assert np.allclose(rec.steering, [s.steering for s in scenes], atol=1e-6)
    assert rec.timestamps is not None and np.allclose(np.diff(rec.timestamps), 0.1, atol=1e-3)
    for labels in ("txt", "csv"):
        out = write_carla(scenes, tmp_path / labels, labels=labels)  # type: ignore[arg-type]
        rec = carla.load_carla(out.parent, strict=True)
        assert np.allclose(rec.steering, [s.steering for s in scenes])
        assert [p.name for p in rec.frames] == [f"{i:06d}.png" for i in range(len(scenes))]
