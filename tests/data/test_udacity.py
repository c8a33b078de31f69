"""Udacity recording loader: path forms, header detection, skipped rows, timestamps, real data."""

from __future__ import annotations

import datetime as dt
from pathlib import Path

import numpy as np
import pytest

from conftest import shared_recording
from qdcnn.data.recording import Recording
from qdcnn.data.udacity import load_udacity
from qdcnn.errors import InputError, ParameterError

HEADER = "center,left,right,steering,throttle,brake,speed"
WIN = "C:\\Users\\USER\\Desktop\\DATA\\IMG\\"


def stamp_name(cam: str, ms: int) -> str:
    """Simulator-style name for a frame ``ms`` milliseconds after 2023-02-17 17:09:20.000."""
    s, m = divmod(ms, 1000)
    return f"{cam}_2023_02_17_17_09_{20 + s:02d}_{m:03d}.jpg"


def write_recording(
    root: Path,
    lines: list[str],
    *,
    images: list[str],
    header: bool = False,
) -> Path:
    """Write ``driving_log.csv`` (lines as given) and empty files for ``images`` in IMG/."""
    (root / "IMG").mkdir(parents=True, exist_ok=True)
    for name in images:
        (root / "IMG" / name).write_bytes(b"")
    text = "\n".join(([HEADER] if header else []) + lines) + "\n"
    (root / "driving_log.csv").write_text(text)
    return root / "driving_log.csv"


def row(centre: str, steering: str, left: str = "", right: str = "") -> str:
    # the simulator separates fields with ", "
    return ", ".join([centre, left, right, steering, "0", "0", "8.02615E-05"])


def side(name: str, cam: str) -> str:
    return name.replace("center", cam)


def three_frames(prefix: str = WIN) -> tuple[list[str], list[str]]:
    names = [stamp_name("center", ms) for ms in (794, 895, 997)]
    lines = [
        row(
            prefix + n,
            s,
            prefix + n.replace("center", "left"),
            prefix + n.replace("center", "right"),
        )
        for n, s in zip(names, ("0", "-0.25", "1"), strict=True)
    ]
    return names, lines


def test_windows_paths_without_header(tmp_path: Path) -> None:
    names, lines = three_frames()
    write_recording(tmp_path, lines, images=names)
    rec = load_udacity(tmp_path)
    img = tmp_path.resolve() / "IMG"
    assert isinstance(rec, Recording)
    assert rec.kind == "udacity"
    assert len(rec) == 3
    assert rec.frames == [img / n for n in names]
    np.testing.assert_array_equal(rec.steering, [0.0, -0.25, 1.0])
    np.testing.assert_array_equal(rec.rows, [1, 2, 3])
    assert rec.problems == []
    assert rec.left is None and rec.right is None  # no side-camera image exists


def test_header_detected_and_rows_are_line_numbers(tmp_path: Path) -> None:
    names, lines = three_frames()
    csv_file = write_recording(tmp_path, lines, images=names, header=True)
    rec = load_udacity(csv_file)  # the CSV itself is accepted too
    assert len(rec) == 3
    np.testing.assert_array_equal(rec.rows, [2, 3, 4])
    np.testing.assert_array_equal(rec.steering, [0.0, -0.25, 1.0])


def test_header_with_reordered_columns(tmp_path: Path) -> None:
    name = stamp_name("center", 0)
    (tmp_path / "IMG").mkdir()
    (tmp_path / "IMG" / name).write_bytes(b"")
    (tmp_path / "driving_log.csv").write_text(f"Steering, Center\n-0.5, IMG/{name}\n")
    rec = load_udacity(tmp_path)
    assert rec.frames == [tmp_path.resolve() / "IMG" / name]
    np.testing.assert_array_equal(rec.steering, [-0.5])


def test_timestamps_from_file_names(tmp_path: Path) -> None:
    names, lines = three_frames()
    write_recording(tmp_path, lines, images=names)
    rec = load_udacity(tmp_path)
    assert rec.timestamps is not None
    first = dt.datetime(2023, 2, 17, 17, 9, 20, 794000, tzinfo=dt.UTC).timestamp()
    np.testing.assert_allclose(rec.timestamps, first + np.array([0.0, 0.101, 0.203]), atol=1e-6)


def test_timestamps_none_for_other_names(tmp_path: Path) -> None:
    write_recording(
        tmp_path, [row("IMG/a.jpg", "0"), row("IMG/b.jpg", "0.1")], images=["a.jpg", "b.jpg"]
    )
    rec = load_udacity(tmp_path)
    assert len(rec) == 2
    assert rec.timestamps is None


def test_posix_absolute_paths_resolve_by_name(tmp_path: Path) -> None:
    names, lines = three_frames(prefix="/home/someone/recording/IMG/")
    write_recording(tmp_path, lines, images=names)
    rec = load_udacity(tmp_path)
    assert rec.frames == [tmp_path.resolve() / "IMG" / n for n in names]


def test_paths_inside_the_recording_resolve_and_paths_outside_it_are_refused(
    tmp_path: Path,
) -> None:
    rec_dir = tmp_path / "rec"
    other = tmp_path / "elsewhere" / "frame_a.jpg"
    other.parent.mkdir()
    other.write_bytes(b"")
    (rec_dir / "sub").mkdir(parents=True)
    (rec_dir / "sub" / "frame_b.jpg").write_bytes(b"")
    rows = [
        row(str(other), "0.1"),
        row("sub\\frame_b.jpg", "0.2"),
        row("IMG/frame_c.jpg", "0.3"),
        row("../elsewhere/frame_a.jpg", "0.4"),
    ]
    write_recording(rec_dir, rows, images=["frame_c.jpg"])
    rec = load_udacity(rec_dir)
    assert rec.frames == [
        (rec_dir / "sub" / "frame_b.jpg").resolve(),
        rec_dir.resolve() / "IMG" / "frame_c.jpg",
    ]
    outside = f"lies outside the recording folder {rec_dir.resolve()}"
    problems = [str(p) for p in rec.problems]
    assert len(problems) == 2 and all(outside in p for p in problems), problems
    assert f"'{other}'" in problems[0] and "'../elsewhere/frame_a.jpg'" in problems[1]


def test_case_only_mismatch_of_windows_name(tmp_path: Path) -> None:
    write_recording(tmp_path, [row(WIN + "CENTER_1.JPG", "0")], images=["center_1.jpg"])
    assert load_udacity(tmp_path).frames == [tmp_path.resolve() / "IMG" / "center_1.jpg"]


def test_missing_side_image_is_allowed(tmp_path: Path) -> None:
    names, lines = three_frames()
    write_recording(tmp_path, lines, images=[*names, names[1].replace("center", "left")])
    rec = load_udacity(tmp_path)
    img = tmp_path.resolve() / "IMG"
    assert rec.problems == []
    assert rec.left == [None, img / names[1].replace("center", "left"), None]
    assert rec.right is None


def bad_rows(tmp_path: Path) -> tuple[Path, list[str]]:
    good = [stamp_name("center", ms) for ms in (0, 100, 200, 300, 400, 500)]
    lines = [
        row(WIN + good[0], "0.1"),
        row(WIN + "center_missing.jpg", "0.2"),  # centre image absent
        ", ".join([WIN + good[2], "", "", "0.3", "0"]),  # 5 columns
        row(WIN + good[3], "abc"),
        row(WIN + good[4], "3.0"),
        row(WIN + good[5], "nan"),
        row(WIN + good[1], "-1"),
    ]
    return write_recording(tmp_path, lines, images=good), good


def test_bad_rows_are_skipped_with_exact_reasons(tmp_path: Path) -> None:
    csv_file, good = bad_rows(tmp_path)
    rec = load_udacity(tmp_path)
    img = tmp_path.resolve() / "IMG"
    assert [str(p) for p in rec.problems] == [
        f"{csv_file}:row 2: centre image '{WIN}center_missing.jpg' not found in {img}",
        f"{csv_file}:row 3: expected 7 columns, found 5",
        f"{csv_file}:row 4: steering 'abc' is not a number",
        f"{csv_file}:row 5: steering 3.0 is outside [-1, 1]",
        f"{csv_file}:row 6: steering 'nan' is not finite",
    ]
    assert rec.problems[0].source == f"{csv_file}:row 2"
    np.testing.assert_array_equal(rec.rows, [1, 7])
    np.testing.assert_array_equal(rec.steering, [0.1, -1.0])
    assert rec.frames == [img / good[0], img / good[1]]


def test_strict_raises_first_problem(tmp_path: Path) -> None:
    csv_file, _ = bad_rows(tmp_path)
    with pytest.raises(InputError) as info:
        load_udacity(tmp_path, strict=True)
    assert str(info.value) == (
        f"{csv_file}:row 2: centre image '{WIN}center_missing.jpg' not found in "
        f"{tmp_path.resolve() / 'IMG'}"
    )


def test_missing_csv_and_empty_folder(tmp_path: Path) -> None:
    with pytest.raises(InputError) as info:
        load_udacity(tmp_path)
    assert str(info.value) == (
        f"{tmp_path}: empty folder (a Udacity recording holds driving_log.csv and IMG/)"
    )
    (tmp_path / "IMG").mkdir()
    with pytest.raises(InputError) as info:
        load_udacity(tmp_path)
    assert str(info.value) == (
        f"{tmp_path}: no driving_log.csv in this folder "
        "(a Udacity recording holds driving_log.csv and IMG/)"
    )
    with pytest.raises(InputError) as info:
        load_udacity(tmp_path / "log.csv")
    assert str(info.value) == f"{tmp_path / 'log.csv'}: file not found"


@pytest.mark.parametrize("text", ["", "\n\n", HEADER + "\n"])
def test_empty_csv(tmp_path: Path, text: str) -> None:
    (tmp_path / "driving_log.csv").write_text(text)
    with pytest.raises(InputError) as info:
        load_udacity(tmp_path)
    assert str(info.value) == f"{tmp_path / 'driving_log.csv'}: empty file: no data rows"


def test_no_usable_row(tmp_path: Path) -> None:
    csv_file = write_recording(tmp_path, [row("IMG/a.jpg", "x"), row("IMG/b.jpg", "2")], images=[])
    with pytest.raises(InputError) as info:
        load_udacity(tmp_path)
    assert str(info.value) == (
        f"{csv_file}: no usable rows: all 2 rows were skipped "
        f"(first: {csv_file}:row 1: steering 'x' is not a number)"
    )


def test_header_without_steering(tmp_path: Path) -> None:
    (tmp_path / "driving_log.csv").write_text("center,left,right\nIMG/a.jpg,,\n")
    with pytest.raises(InputError, match="header has no 'steering' column"):
        load_udacity(tmp_path)


def test_subset(tmp_path: Path) -> None:
    names, lines = three_frames()
    write_recording(tmp_path, lines, images=[*names, names[2].replace("center", "right")])
    rec = load_udacity(tmp_path)
    sub = rec.subset([2, 0])
    assert sub.frames == [rec.frames[2], rec.frames[0]]
    np.testing.assert_array_equal(sub.steering, [1.0, 0.0])
    np.testing.assert_array_equal(sub.rows, [3, 1])
    assert rec.timestamps is not None and sub.timestamps is not None
    np.testing.assert_array_equal(sub.timestamps, rec.timestamps[[2, 0]])
    assert sub.right == [rec.frames[2].with_name(names[2].replace("center", "right")), None]
    assert len(rec.subset(np.array([False, True, True]))) == 2
    assert rec.subset(slice(1, None)).rows.tolist() == [2, 3]
    with pytest.raises(ParameterError, match="idx"):
        rec.subset([5])


def test_real_lake_track() -> None:
    rec = load_udacity(shared_recording("udacity-lake-track"))
    assert len(rec) == 5113
    assert rec.problems == []
    assert rec.timestamps is not None
    assert np.all(np.abs(rec.steering) <= 1)
    gaps = np.flatnonzero(np.diff(rec.timestamps) > 1.0)
    # the recording breaks after rows 2604 and 3858
    np.testing.assert_array_equal(rec.rows[gaps], [2604, 3858])
    assert np.median(np.diff(rec.timestamps)) == pytest.approx(0.1, abs=0.01)


def test_real_mountain_track() -> None:
    rec = load_udacity(shared_recording("udacity-mountain-track"))
    # driving_log.csv has 1084 rows, each with its centre image in IMG/
    assert len(rec) == 1084
    assert rec.problems == []
    assert rec.timestamps is not None
    assert np.all(np.diff(rec.timestamps) <= 1.0)
