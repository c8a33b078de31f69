"""Recording loaders at the input boundary: repeated images, steering units, odd names, folders."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest

from conftest import SHARED_DATA, shared_recording
from qdcnn.data.carla import load_carla
from qdcnn.data.images import display_path
from qdcnn.data.labels import SteeringUnit
from qdcnn.data.udacity import load_udacity
from qdcnn.errors import InputError, ParameterError


def stamp_name(ms: int) -> str:
    s, m = divmod(ms, 1000)
    return f"center_2023_02_17_17_09_{20 + s:02d}_{m:03d}.jpg"


def udacity(root: Path, rows: list[tuple[str, str]], images: list[str] | None = None) -> Path:
    """``driving_log.csv`` with (centre, steering) rows and empty image files in IMG/."""
    (root / "IMG").mkdir(parents=True, exist_ok=True)
    for name in images if images is not None else sorted({c for c, _ in rows}):
        (root / "IMG" / name).write_bytes(b"")
    text = "".join(f"IMG/{c}, , , {s}, 0, 0, 1.5\n" for c, s in rows)
    (root / "driving_log.csv").write_text(text)
    return root / "driving_log.csv"


def test_repeated_image_rows_are_dropped_and_reported(tmp_path: Path) -> None:
    names = [stamp_name(ms) for ms in (0, 100, 200)]
    rows = [
        (names[0], "0.1"),
        (names[1], "0.2"),
        (names[0], "0.1"),  # the same row again
        (names[2], "-0.3"),
        (names[1], "0.9"),  # the same image with another steering
    ]
    csv_file = udacity(tmp_path, rows)
    rec = load_udacity(tmp_path)
    assert len(rec) == 3
    np.testing.assert_array_equal(rec.steering, [0.1, 0.2, -0.3])
    np.testing.assert_array_equal(rec.rows, [1, 2, 4])
    assert [str(p) for p in rec.problems] == [
        f"{csv_file}:row 3: image '{names[0]}' listed again (first at row 1): dropped",
        f"{csv_file}:row 5: image '{names[1]}' listed again (first at row 2) "
        "(steering 0.9, not 0.2): dropped",
    ]
    with pytest.raises(InputError, match="row 3: image .* listed again"):
        load_udacity(tmp_path, strict=True)


def test_repeated_images_in_a_carla_csv(tmp_path: Path) -> None:
    (tmp_path / "images").mkdir()
    for i in range(2):
        (tmp_path / "images" / f"{i:06d}.png").write_bytes(b"")
    text = "image,steering\n000000.png,0.1\n1,0.2\nimages/000000.png,0.1\n0,-0.4\n"
    (tmp_path / "labels.csv").write_text(text)
    rec = load_carla(tmp_path)
    csv_file = tmp_path.resolve() / "labels.csv"
    assert [p.name for p in rec.frames] == ["000000.png", "000001.png"]
    np.testing.assert_array_equal(rec.rows, [2, 3])
    assert [str(p) for p in rec.problems] == [
        f"{csv_file}:row 4: image '000000.png' listed again (first at row 2): dropped",
        f"{csv_file}:row 5: image '000000.png' listed again (first at row 2) "
        "(steering -0.4, not 0.1): dropped",
    ]


def test_problems_carry_row_numbers_in_file_order(tmp_path: Path) -> None:
    names = [stamp_name(ms) for ms in range(0, 600, 100)]
    rows = [
        (names[0], "0.1"),
        (names[1], "5.0"),  # outside [-1, 1]: found once the unit is settled
        (names[2], "nan"),
        ("center_missing.jpg", "0.2"),
        (names[0], "0.1"),
        (names[3], ""),
    ]
    csv_file = udacity(tmp_path, rows, images=names)
    rec = load_udacity(tmp_path)
    assert [p.source for p in rec.problems] == [f"{csv_file}:row {n}" for n in (2, 3, 4, 5, 6)]
    assert str(rec.problems[0]) == f"{csv_file}:row 2: steering 5.0 is outside [-1, 1]"
    assert rec.unit.unit == "norm"
    with pytest.raises(InputError) as info:
        load_udacity(tmp_path, strict=True)
    assert str(info.value) == str(rec.problems[0])  # strict raises the first row's problem


def test_every_row_keeps_its_place_among_the_data_rows(tmp_path: Path) -> None:
    from qdcnn.data.recording import RowError

    names = [stamp_name(ms) for ms in range(0, 500, 100)]
    rows = [(names[0], "0.1"), (names[1], "abc"), (names[2], ""), (names[3], "0.2")]
    rows += [(names[0], "0.1"), (names[4], "-0.1")]
    csv_file = udacity(tmp_path, rows, images=names)
    csv_file.write_text("center,left,right,steering,throttle,brake,speed\n" + csv_file.read_text())
    rec = load_udacity(tmp_path)
    np.testing.assert_array_equal(rec.rows, [2, 5, 7])  # line numbers, after the header
    np.testing.assert_array_equal(rec.positions, [0, 3, 5])  # places among the data rows
    assert all(isinstance(p, RowError) for p in rec.problems)
    assert [(p.row, p.position) for p in rec.problems] == [(3, 1), (4, 2), (6, 4)]  # type: ignore[attr-defined]
    np.testing.assert_array_equal(rec.subset([2, 0]).positions, [5, 0])


def test_simulator_recording_is_norm_and_angles_are_recognised(tmp_path: Path) -> None:
    names = [stamp_name(ms) for ms in range(0, 500, 100)]
    udacity(tmp_path / "sim", [(n, "0.3") for n in names])
    rec = load_udacity(tmp_path / "sim")
    assert rec.unit.unit == "norm" and "simulator image names" in rec.unit.reason
    # the same layout from a real car, steering-wheel angle in degrees
    frames = [f"frame{i}.jpg" for i in range(6)]
    values = ["-45.5", "-20", "0", "12.5", "30", "90"]
    udacity(tmp_path / "car", list(zip(frames, values, strict=True)))
    car = load_udacity(tmp_path / "car")
    assert car.unit.unit == "deg" and car.problems == []
    np.testing.assert_array_equal(car.steering, [-45.5, -20, 0, 12.5, 30, 90])
    assert car.labels(window=0).labels.tolist() == [0, 0, 1, 1, 2, 2]  # 18.75 degrees
    assert car.subset([0, 5]).unit == car.unit
    # in radians, up to a full turn
    udacity(
        tmp_path / "rad", [(f, str(float(v) / 20)) for f, v in zip(frames, values, strict=True)]
    )
    assert load_udacity(tmp_path / "rad").unit.unit == "rad"


def test_explicit_unit_overrides_auto(tmp_path: Path) -> None:
    names = [stamp_name(ms) for ms in range(0, 300, 100)]
    csv_file = udacity(tmp_path, [(names[0], "0.5"), (names[1], "2.0"), (names[2], "-0.1")])
    rec = load_udacity(tmp_path)
    assert rec.unit.unit == "norm" and len(rec) == 2  # simulator names: 2.0 is a bad row
    as_rad = load_udacity(tmp_path, steering_unit="rad")
    assert as_rad.unit == SteeringUnit("rad", "rad", "given", False)
    np.testing.assert_array_equal(as_rad.steering, [0.5, 2.0, -0.1])
    as_deg = load_carla_like_txt(tmp_path / "carla", ["0.5", "20", "1000"], "deg")
    assert [str(p) for p in as_deg.problems] == [
        f"{(tmp_path / 'carla').resolve() / 'steer_values.txt'}:row 3: "
        "steering 1000 is outside [-900, 900] (deg)"
    ]
    with pytest.raises(ParameterError, match="steering_unit='radians' is invalid"):
        load_udacity(csv_file, steering_unit="radians")
    with pytest.raises(ParameterError, match="steering_unit="):
        load_carla(tmp_path, steering_unit="")


def load_carla_like_txt(folder: Path, lines: list[str], unit: str) -> object:
    (folder / "images").mkdir(parents=True)
    for i in range(len(lines)):
        (folder / "images" / f"{i}.png").write_bytes(b"")
    (folder / "steer_values.txt").write_text("\n".join(lines) + "\n")
    return load_carla(folder, steering_unit=unit)


def test_nanosecond_names_give_timestamps(tmp_path: Path) -> None:
    names = ["1479425441182877835.jpg", "1479425441232704425.jpg", "1479425443282730750.jpg"]
    udacity(tmp_path, [(n, "0.01") for n in names])
    rec = load_udacity(tmp_path)
    assert rec.timestamps is not None
    np.testing.assert_allclose(np.diff(rec.timestamps), [0.049826590, 2.050026325], atol=1e-6)


def test_empty_folders_give_one_line_errors(tmp_path: Path) -> None:
    for loader in (load_udacity, load_carla):
        with pytest.raises(InputError) as info:
            loader(tmp_path)
        message = str(info.value)
        assert message.startswith(f"{tmp_path}: empty folder") and "\n" not in message


def test_non_utf8_image_names_in_a_carla_folder(tmp_path: Path) -> None:
    folder = os.fsencode(tmp_path / "rec") + b"\xe9"
    os.makedirs(folder + b"/images")
    for name in (b"1.png", b"2\xff.png", b"3.png"):
        with open(folder + b"/images/" + name, "wb"):
            pass
    with open(folder + b"/steer_values.txt", "w") as fh:
        fh.write("0.1\nbad\n-0.2\n")
    rec = load_carla(os.fsdecode(folder))
    assert [p.name for p in rec.frames] == ["1.png", "3.png"]
    shown = display_path(folder)
    (problem,) = rec.problems
    assert str(problem) == f"{shown}/steer_values.txt:row 2: steering 'bad' is not a number"
    str(problem).encode("utf-8")  # printable on a UTF-8 terminal
    # the odd name is read as a frame when its value is good, and it can be shown
    with open(folder + b"/steer_values.txt", "w") as fh:
        fh.write("0.1\n0.3\n-0.2\n")
    again = load_carla(os.fsdecode(folder))
    assert display_path(again.frames[1]).endswith("images/2\\xff.png")
    # and a labels CSV naming it: the name cannot be written in UTF-8, so it is not found
    os.remove(folder + b"/steer_values.txt")
    with open(folder + b"/labels.csv", "wb") as fh:
        fh.write(b"image,steering\n1.png,0.1\n2\xff.png,0.2\n3.png,-0.2\n")
    csv_rec = load_carla(os.fsdecode(folder))
    assert [p.name for p in csv_rec.frames] == ["1.png", "3.png"]
    (problem,) = csv_rec.problems
    assert str(problem) == f"{shown}/labels.csv:row 3: image '2\ufffd.png' not found"


def test_unicode_digits_and_long_numbers_are_not_frame_numbers(tmp_path: Path) -> None:
    (tmp_path / "images").mkdir()
    for name in ("000001.png", "\u00b2.png"):  # superscript two: isdigit() but not int()
        (tmp_path / "images" / name).write_bytes(b"")
    text = "image,steering\n1,0.1\n\u00b2,0.2\n" + "9" * 5000 + ",0.3\n"
    (tmp_path / "labels.csv").write_text(text)
    rec = load_carla(tmp_path)
    assert [p.name for p in rec.frames] == ["000001.png", "\u00b2.png"]
    assert len(rec.problems) == 1 and "row 4: image '9999" in str(rec.problems[0])


@pytest.mark.realdata
@pytest.mark.parametrize(
    ("name", "unit"),
    [
        ("udacity-lake-track", "norm"),
        ("udacity-mountain-track", "norm"),
        ("udacity-dark-mountain-track", "norm"),
        ("real-dashcam-sample", "rad"),
    ],
)
def test_auto_unit_on_the_shared_recordings(name: str, unit: str) -> None:
    rec = load_udacity(shared_recording(name))
    assert rec.unit.unit == unit and not rec.unit.assumed
    assert rec.problems == []
    labels = rec.labels()
    assert labels.threshold == pytest.approx({"norm": 0.05, "rad": math.radians(18.75)}[unit])
    counts = labels.counts()
    assert min(counts.values()) > 0 and sum(counts.values()) == len(rec)
    assert (SHARED_DATA / name).is_dir()
