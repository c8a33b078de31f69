"""CARLA-style loader: steer_values.txt by natural order, label CSVs by name, skipped rows."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from qdcnn.data.carla import load_carla
from qdcnn.errors import InputError


def touch_images(folder: Path, names: list[str]) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        (folder / name).write_bytes(b"")
    return [(folder / n).resolve() for n in names]


def test_synthetic_writer_layout_with_txt(tmp_path: Path) -> None:
    frames = touch_images(tmp_path / "images", [f"{i:06d}.png" for i in range(3)])
    (tmp_path / "steer_values.txt").write_text("-0.5\n0\n0.25\n\n")
    rec = load_carla(tmp_path)
    assert rec.kind == "carla"
    assert rec.frames == frames
    np.testing.assert_array_equal(rec.steering, [-0.5, 0.0, 0.25])
    np.testing.assert_array_equal(rec.rows, [1, 2, 3])
    assert rec.timestamps is None and rec.problems == []
    assert rec.root == tmp_path.resolve()


def test_synthetic_writer_layout_with_csv(tmp_path: Path) -> None:
    frames = touch_images(tmp_path / "images", [f"{i:06d}.png" for i in range(3)])
    lines = ["image,steering", *(f"images/{i:06d}.png,{v}" for i, v in enumerate((0.1, -0.2, 0)))]
    (tmp_path / "labels.csv").write_text("\n".join(lines) + "\n")
    rec = load_carla(tmp_path)
    assert rec.frames == frames
    np.testing.assert_array_equal(rec.steering, [0.1, -0.2, 0.0])
    np.testing.assert_array_equal(rec.rows, [2, 3, 4])
    assert rec.timestamps is None and rec.problems == []


def test_txt_natural_order_images_in_folder(tmp_path: Path) -> None:
    touch_images(tmp_path, ["10.png", "2.png", "1.png", "notes.md"])
    (tmp_path / "steer_values.txt").write_text("0.1\n0.2\n0.3\n")
    rec = load_carla(tmp_path / "steer_values.txt")  # the label file itself is accepted
    assert [p.name for p in rec.frames] == ["1.png", "2.png", "10.png"]
    np.testing.assert_array_equal(rec.steering, [0.1, 0.2, 0.3])


def test_txt_count_mismatch_names_both_counts(tmp_path: Path) -> None:
    touch_images(tmp_path / "images", ["0.png", "1.png"])
    (tmp_path / "steer_values.txt").write_text("0\n0\n0\n")
    with pytest.raises(InputError) as info:
        load_carla(tmp_path)
    assert str(info.value) == (
        f"{tmp_path.resolve() / 'steer_values.txt'}: 3 steering values but 2 images in "
        f"{tmp_path.resolve() / 'images'}"
    )


def test_txt_bad_value_skips_its_image_only(tmp_path: Path) -> None:
    frames = touch_images(tmp_path / "images", ["0.png", "1.png", "2.png", "3.png"])
    (tmp_path / "steer_values.txt").write_text("0.1\nleft\n\n-0.3\n")
    rec = load_carla(tmp_path)
    txt = tmp_path.resolve() / "steer_values.txt"
    assert [str(p) for p in rec.problems] == [
        f"{txt}:row 2: steering 'left' is not a number",
        f"{txt}:row 3: steering '' is not a number",
    ]
    assert rec.frames == [frames[0], frames[3]]
    np.testing.assert_array_equal(rec.steering, [0.1, -0.3])
    np.testing.assert_array_equal(rec.rows, [1, 4])
    with pytest.raises(InputError, match="row 2: steering 'left' is not a number"):
        load_carla(tmp_path, strict=True)


def test_csv_alternative_names_frame_numbers_and_timestamps(tmp_path: Path) -> None:
    frames = touch_images(tmp_path / "images", ["000007.png", "000008.png"])
    (tmp_path / "run.csv").write_text(" Frame , Steer , Timestamp\n8, 0.5, 1.5\n7, -0.5, 1.0\n")
    rec = load_carla(tmp_path)
    assert rec.frames == [frames[1], frames[0]]  # label-file order
    np.testing.assert_array_equal(rec.steering, [0.5, -0.5])
    assert rec.timestamps is not None
    np.testing.assert_array_equal(rec.timestamps, [1.5, 1.0])


def test_csv_malformed_rows_are_problems(tmp_path: Path) -> None:
    frames = touch_images(tmp_path / "images", ["a.png", "b.png", "c.png"])
    lines = [
        "filename,angle,timestamp",
        "a.png,0.1,0.0",
        "b.png,0.2",
        "b.png,abc,0.2",
        "b.png,-2,0.2",
        "b.png,0.2,soon",
        "missing.png,0.2,0.3",
        "c.png,-0.1,0.4",
    ]
    (tmp_path / "labels.csv").write_text("\n".join(lines) + "\n")
    rec = load_carla(tmp_path)
    csv_file = tmp_path.resolve() / "labels.csv"
    assert [str(p) for p in rec.problems] == [
        f"{csv_file}:row 3: expected 3 columns, found 2",
        f"{csv_file}:row 4: steering 'abc' is not a number",
        f"{csv_file}:row 5: steering -2 is outside [-1, 1]",
        f"{csv_file}:row 6: timestamp 'soon' is not a number",
        f"{csv_file}:row 7: image 'missing.png' not found",
    ]
    assert rec.frames == [frames[0], frames[2]]
    np.testing.assert_array_equal(rec.rows, [2, 8])


def test_csv_header_without_steering_column(tmp_path: Path) -> None:
    (tmp_path / "labels.csv").write_text("image,throttle\na.png,0.1\n")
    with pytest.raises(InputError) as info:
        load_carla(tmp_path)
    assert str(info.value) == (
        f"{tmp_path.resolve() / 'labels.csv'}: header 'image,throttle' has no steering column "
        "(image: image, filename, file_name, file, frame, image_path, img, path, center; "
        "steering: steering, steer, angle, steering_angle, steer_value)"
    )


def test_several_csvs_without_labels_csv(tmp_path: Path) -> None:
    (tmp_path / "a.csv").write_text("image,steering\n")
    (tmp_path / "b.csv").write_text("image,steering\n")
    with pytest.raises(InputError) as info:
        load_carla(tmp_path)
    assert str(info.value) == (
        f"{tmp_path.resolve()}: several CSV files (a.csv, b.csv): "
        "name the labels file labels.csv or pass its path"
    )


def test_missing_folder_and_missing_labels(tmp_path: Path) -> None:
    with pytest.raises(InputError) as info:
        load_carla(tmp_path / "nope")
    assert str(info.value) == f"{tmp_path / 'nope'}: not found"
    touch_images(tmp_path / "images", ["0.png"])
    with pytest.raises(InputError) as info:
        load_carla(tmp_path)
    assert str(info.value) == f"{tmp_path.resolve()}: no steer_values.txt or labels CSV found"


def test_empty_label_files(tmp_path: Path) -> None:
    touch_images(tmp_path / "images", ["0.png"])
    (tmp_path / "steer_values.txt").write_text("\n")
    with pytest.raises(InputError) as info:
        load_carla(tmp_path)
    assert (
        str(info.value)
        == f"{tmp_path.resolve() / 'steer_values.txt'}: empty file: no steering values"
    )
    (tmp_path / "steer_values.txt").unlink()
    (tmp_path / "labels.csv").write_text("image,steering\n")
    with pytest.raises(InputError) as info:
        load_carla(tmp_path)
    assert str(info.value) == f"{tmp_path.resolve() / 'labels.csv'}: empty file: no data rows"


def test_txt_without_images(tmp_path: Path) -> None:
    (tmp_path / "images").mkdir()
    (tmp_path / "steer_values.txt").write_text("0\n")
    with pytest.raises(InputError) as info:
        load_carla(tmp_path)
    assert str(info.value) == f"{tmp_path.resolve() / 'images'}: no image files"


def test_an_image_path_outside_the_recording_is_refused(tmp_path: Path) -> None:
    rec_dir = tmp_path / "rec"
    frames = touch_images(rec_dir / "images", ["a.png"])
    outside = touch_images(tmp_path / "elsewhere", ["x.png"])[0]
    lines = ["filename,angle", "a.png,0.1", "../elsewhere/x.png,0.2", f"{outside},0.3"]
    (rec_dir / "labels.csv").write_text("\n".join(lines) + "\n")
    rec = load_carla(rec_dir)
    assert rec.frames == frames
    problems = [str(p) for p in rec.problems]
    assert len(problems) == 2
    assert all(f"lies outside the recording folder {rec_dir.resolve()}" in p for p in problems)
