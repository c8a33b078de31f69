"""Fuzzing the recording loaders: random label files, and good rows unchanged by bad ones."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from fuzz_support import fuzz_settings, hang_guard

from qdcnn.data.carla import load_carla
from qdcnn.data.recording import Recording
from qdcnn.data.udacity import load_udacity
from qdcnn.errors import InputError

hypothesis = pytest.importorskip("hypothesis")
st = hypothesis.strategies
given = hypothesis.given
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")  # numpy overflow and the like

N_IMAGES = 24
SIM_NAMES = [
    f"center_2023_02_17_17_09_{20 + i // 10:02d}_{(i % 10) * 100:03d}.jpg" for i in range(N_IMAGES)
]
CARLA_NAMES = [f"{i:06d}.png" for i in range(N_IMAGES)]
HEADER = "center,left,right,steering,throttle,brake,speed"


@pytest.fixture(scope="module")
def udacity_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("fuzz-udacity")
    (root / "IMG").mkdir()
    for name in SIM_NAMES:
        (root / "IMG" / name).write_bytes(b"")
    return root


@pytest.fixture(scope="module")
def carla_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("fuzz-carla")
    (root / "images").mkdir()
    for name in CARLA_NAMES:
        (root / "images" / name).write_bytes(b"")
    return root


def check_recording(rec: Recording) -> None:
    """What every loaded recording promises, however odd its file."""
    n = len(rec)
    assert n > 0 and len(rec.steering) == n and len(rec.rows) == n
    assert np.all(np.diff(rec.rows) > 0)  # file order, one frame per row
    assert len(set(rec.frames)) == n  # no image twice
    assert np.all(np.isfinite(rec.steering)) and np.all(np.abs(rec.steering) <= rec.unit.limit)
    assert all(p.is_file() for p in rec.frames)
    for problem in rec.problems:
        assert isinstance(problem, InputError) and ":row " in problem.source
        assert "\n" not in str(problem)
    assert not set(rec.rows.tolist()) & {int(p.source.rsplit(" ", 1)[1]) for p in rec.problems}


def load_or_error(load: object, path: Path, **kwargs: object) -> Recording | None:
    with hang_guard():
        try:
            rec = load(path, **kwargs)  # type: ignore[operator]
        except InputError as exc:
            assert "\n" not in str(exc)
            hypothesis.event("InputError: " + exc.reason.split(":")[0][:30])
            return None
    check_recording(rec)
    hypothesis.event("recording")
    return rec


cells = st.one_of(
    st.sampled_from(["", " ", "0", "-1", "1", "0.5", "nan", "inf", "1e999", "IMG/x.jpg", '"']),
    st.sampled_from(SIM_NAMES + [f"IMG/{n}" for n in SIM_NAMES] + CARLA_NAMES),
    st.text(max_size=12),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
)
csv_row = st.one_of(st.lists(cells, min_size=7, max_size=7), st.lists(cells, max_size=9))
csv_text = st.lists(csv_row.map(", ".join), max_size=30).map("\n".join)


@fuzz_settings(200)
@given(text=csv_text, header=st.booleans())
def test_random_driving_logs(udacity_dir: Path, text: str, header: bool) -> None:
    (udacity_dir / "driving_log.csv").write_text((HEADER + "\n" if header else "") + text)
    load_or_error(load_udacity, udacity_dir)


@fuzz_settings(100)
@given(raw=st.binary(max_size=400))
def test_random_driving_log_bytes(udacity_dir: Path, raw: bytes) -> None:
    (udacity_dir / "driving_log.csv").write_bytes(raw)
    load_or_error(load_udacity, udacity_dir)


def sim_row(name: str, steering: str) -> str:
    return ", ".join([f"C:\\data\\IMG\\{name}", "", "", steering, "0", "0", "1.5"])


plain_cells = st.text(st.characters(codec="utf-8", exclude_characters='"\r\n\x00'), max_size=8)


@st.composite
def bad_row(draw: st.DrawFn, listed: list[str]) -> str | None:
    """One unusable row; ``None`` when the kind drawn does not apply here."""
    kind = draw(st.sampled_from(("columns", "steering", "missing", "range", "repeat")))
    if kind == "columns":  # never 7 columns
        row = ", ".join(draw(st.lists(plain_cells, min_size=1, max_size=6)))
        return row if row.replace(",", "").strip() else None  # a blank line is not a row
    if kind == "steering":
        text = draw(st.sampled_from(["nan", "-inf", "abc", "", "1e999", "0x10", "--1", "1.5.2"]))
        return sim_row(draw(st.sampled_from(SIM_NAMES)), text)
    if kind == "missing":
        return sim_row("center_2023_01_01_00_00_00_000.jpg", "0.1")
    if kind == "range":  # any image, even one a good row lists later: it must not claim it
        value = draw(st.floats(1.0001, 1e6)) * draw(st.sampled_from([1, -1]))
        return sim_row(draw(st.sampled_from(SIM_NAMES)), repr(value))
    if not listed:
        return None
    return sim_row(draw(st.sampled_from(listed)), repr(draw(st.floats(-1, 1))))


@st.composite
def good_and_bad_rows(draw: st.DrawFn) -> tuple[list[str], list[str], list[int]]:
    """Good rows (distinct images); the same with bad rows put in; the bad rows' line numbers."""
    picks = draw(st.lists(st.integers(0, N_IMAGES - 1), min_size=1, max_size=N_IMAGES, unique=True))
    values = draw(st.lists(st.floats(-1, 1), min_size=len(picks), max_size=len(picks)))
    good = [sim_row(SIM_NAMES[i], repr(v)) for i, v in zip(picks, values, strict=True)]
    lines: list[str] = []
    bad_lines: list[int] = []
    listed: list[str] = []
    for i, line in zip(picks, good, strict=True):
        for _ in range(draw(st.integers(0, 2))):
            bad = draw(bad_row(listed))
            if bad is not None:
                lines.append(bad)
                bad_lines.append(len(lines))
        lines.append(line)
        listed.append(SIM_NAMES[i])
    for _ in range(draw(st.integers(0, 2))):  # and after the last good row
        bad = draw(bad_row(listed))
        if bad is not None:
            lines.append(bad)
            bad_lines.append(len(lines))
    return good, lines, bad_lines


@fuzz_settings(200)
@given(case=good_and_bad_rows())
def test_bad_rows_never_change_the_good_ones(
    udacity_dir: Path, case: tuple[list[str], list[str], list[int]]
) -> None:
    good, mixed, bad_lines = case
    csv_file = udacity_dir / "driving_log.csv"
    csv_file.write_text("\n".join(good) + "\n")
    clean = load_or_error(load_udacity, udacity_dir)
    csv_file.write_text("\n".join(mixed) + "\n")
    dirty = load_or_error(load_udacity, udacity_dir)
    assert clean is not None and dirty is not None
    assert dirty.frames == clean.frames
    np.testing.assert_array_equal(dirty.steering, clean.steering)
    assert [int(p.source.rsplit(" ", 1)[1]) for p in dirty.problems] == bad_lines
    assert dirty.rows.tolist() == [n for n in range(1, len(mixed) + 1) if n not in bad_lines]
    assert dirty.unit == clean.unit and dirty.unit.unit == "norm"  # simulator names


@fuzz_settings(150)
@given(
    lines=st.lists(
        st.one_of(st.floats(-1, 1).map(repr), st.sampled_from(["nan", "x", "", "inf", "2", "--1"])),
        min_size=N_IMAGES,
        max_size=N_IMAGES,
    )
)
def test_steer_values_txt_keeps_each_good_line_with_its_image(
    carla_dir: Path, lines: list[str]
) -> None:
    (carla_dir / "steer_values.txt").write_text("\n".join(lines) + "\n")
    rec = load_or_error(load_carla, carla_dir, steering_unit="norm")
    if not lines[-1].strip():  # trailing blank lines are not values: one value short
        assert rec is None
        return
    good = []
    for i, text in enumerate(lines):
        try:
            value = float(text)
        except ValueError:
            continue
        if math.isfinite(value) and abs(value) <= 1:
            good.append((i, value))
    if not good:
        assert rec is None
        return
    assert rec is not None
    assert [p.name for p in rec.frames] == [CARLA_NAMES[i] for i, _ in good]
    np.testing.assert_array_equal(rec.steering, [v for _, v in good])
    assert rec.rows.tolist() == [i + 1 for i, _ in good]
    assert len(rec.problems) == len(lines) - len(good)


carla_cells = st.one_of(
    st.sampled_from([*CARLA_NAMES, "images/000003.png", "7", "0007", "\u00b2", "9" * 50]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.text(max_size=10),
)


@fuzz_settings(100)
@given(
    lines=st.lists(
        st.one_of(st.text(max_size=10), carla_cells), min_size=N_IMAGES, max_size=N_IMAGES
    )
)
def test_random_steer_values(carla_dir: Path, lines: list[str]) -> None:
    (carla_dir / "steer_values.txt").write_text("\n".join(lines))
    load_or_error(load_carla, carla_dir)


def column_cell(name: str) -> st.SearchStrategy[str]:
    """Mostly what the column means (image name, steering, time), sometimes anything."""
    meant = {
        "image": st.sampled_from([*CARLA_NAMES, "3", "images/000004.png"]),
        "frame": st.integers(0, N_IMAGES + 2).map(str),
        "steering": st.floats(-1, 1).map(repr),
        "angle": st.floats(-1, 1).map(repr),
        "timestamp": st.floats(0, 1e6).map(repr),
    }
    return st.one_of(meant[name], carla_cells) if name in meant else carla_cells


label_headers = st.one_of(
    st.sampled_from([["image", "steering"], ["frame", "angle", "timestamp"], ["steer", "file"]]),
    st.lists(
        st.sampled_from(["image", "frame", "steering", "angle", "timestamp", "x", ""]), max_size=4
    ),
)


@fuzz_settings(100)
@given(header=label_headers, data=st.data())
def test_random_label_csv(carla_dir: Path, header: list[str], data: st.DataObject) -> None:
    width = st.integers(max(len(header) - 1, 0), len(header) + 1)
    odd_row = width.flatmap(lambda k: st.lists(carla_cells, min_size=k, max_size=k))
    fitting_row = st.tuples(*(column_cell(name) for name in header)).map(list)
    rows = data.draw(st.lists(st.one_of(fitting_row, odd_row), max_size=20))
    text = "\n".join([",".join(header), *(",".join(r) for r in rows)])
    (carla_dir / "labels.csv").write_text(text)
    txt = carla_dir / "steer_values.txt"
    txt.unlink(missing_ok=True)
    load_or_error(load_carla, carla_dir)
