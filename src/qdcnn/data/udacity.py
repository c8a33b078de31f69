"""Load Udacity self-driving-car simulator recordings (``driving_log.csv`` + ``IMG/``).

The simulator writes one CSV row per frame: ``center, left, right, steering,
throttle, brake, speed``, usually without a header and with the absolute image
paths of the recording machine (often Windows paths). Images are found by file
name in ``IMG/`` beside the CSV, so a recording can be moved freely.
"""

from __future__ import annotations

import csv
import datetime as dt
import os
import re
from pathlib import Path, PurePosixPath, PureWindowsPath

import numpy as np

from qdcnn.data.recording import Recording, parse_steering
from qdcnn.errors import InputError

COLUMNS: tuple[str, ...] = ("center", "left", "right", "steering", "throttle", "brake", "speed")
CSV_NAME = "driving_log.csv"
IMAGE_DIR = "IMG"

# center_YYYY_MM_DD_HH_MM_SS_mmm.jpg, the simulator's capture time
_STAMP = re.compile(r"^center_(\d{4})_(\d{2})_(\d{2})_(\d{2})_(\d{2})_(\d{2})_(\d{3})\.\w+$")


class _ImageIndex:
    """Resolve recorded image paths against one listing of ``IMG/``."""

    def __init__(self, csv_dir: Path) -> None:
        self.csv_dir = csv_dir
        self.img_dir = csv_dir / IMAGE_DIR
        try:
            names = [e.name for e in os.scandir(self.img_dir) if e.is_file()]
        except OSError:
            names = []
        self.exact = set(names)
        # Windows paths are case-insensitive: accept a case-only mismatch
        self.folded = {n.lower(): n for n in names}

    def resolve(self, raw: str) -> Path | None:
        text = raw.strip()
        if not text:
            return None
        windows = PureWindowsPath(text)
        name = windows.name  # splits on both "\" and "/"
        if name in self.exact:
            return self.img_dir / name
        if name.lower() in self.folded:
            return self.img_dir / self.folded[name.lower()]
        if windows.drive or text.startswith("\\"):
            return None  # an absolute Windows path cannot exist here
        given = Path(PurePosixPath(text.replace("\\", "/")))
        candidate = given if given.is_absolute() else self.csv_dir / given
        return candidate.resolve() if candidate.is_file() else None


def _timestamp(path: Path) -> float | None:
    m = _STAMP.match(path.name)
    if m is None:
        return None
    y, mo, d, h, mi, s, ms = (int(g) for g in m.groups())
    try:
        when = dt.datetime(y, mo, d, h, mi, s, ms * 1000, tzinfo=dt.UTC)
    except ValueError:
        return None
    return when.timestamp()


def _csv_path(path: str | os.PathLike[str]) -> Path:
    p = Path(path)
    csv_file = p / CSV_NAME if p.is_dir() else p
    if not csv_file.is_file():
        raise InputError(csv_file, "file not found")
    return csv_file


def _header_columns(fields: list[str]) -> dict[str, int] | None:
    """Column positions from a header row, or ``None`` when the row is data."""
    names = [f.strip().lower() for f in fields]
    if "center" not in names:
        return None
    return {name: names.index(name) for name in COLUMNS if name in names}


def load_udacity(path: str | os.PathLike[str], *, strict: bool = False) -> Recording:
    """Load a Udacity simulator recording.

    Parameters
    ----------
    path : str or path-like
        The recording folder (holding ``driving_log.csv`` and ``IMG/``) or the CSV itself.
    strict : bool
        Raise on the first unusable row instead of skipping it.

    Returns
    -------
    Recording
        ``kind="udacity"``. ``timestamps`` come from the centre image names
        (``center_YYYY_MM_DD_HH_MM_SS_mmm.jpg``, read as UTC: only differences
        matter) and are ``None`` when any name does not follow that pattern.
        ``left``/``right`` are ``None`` when no side-camera image exists at all.

    Raises
    ------
    InputError
        Missing or empty CSV, a header without ``center`` and ``steering``
        columns, or no usable row; with ``strict=True`` also the first unusable
        row (``"<csv>:row <n>: <reason>"``).

    Notes
    -----
    A row is skipped (and recorded in ``problems``) when it has the wrong number
    of columns, its steering is not a finite number in [-1, 1], or its centre
    image is not found. Image paths are resolved by file name in ``IMG/`` beside
    the CSV (absolute Windows or POSIX paths alike); a path that is not there is
    used as given when it exists (relative paths from the CSV's folder). Images
    are never opened: ``IMG/`` is listed once.
    """
    csv_file = _csv_path(path)
    csv_dir = csv_file.parent.resolve()
    index = _ImageIndex(csv_dir)
    problems: list[InputError] = []
    frames: list[Path] = []
    lefts: list[Path | None] = []
    rights: list[Path | None] = []
    steering: list[float] = []
    rows: list[int] = []
    columns = {name: i for i, name in enumerate(COLUMNS)}
    n_columns = len(COLUMNS)
    data_rows = 0
    first = True

    def skip(row: int, reason: str) -> None:
        err = InputError(f"{csv_file}:row {row}", reason)
        if strict:
            raise err
        problems.append(err)

    try:
        with open(csv_file, newline="", encoding="utf-8-sig", errors="replace") as fh:
            reader = csv.reader(fh, skipinitialspace=True)
            for fields in reader:
                if not fields or all(not f.strip() for f in fields):
                    continue  # blank line
                row = reader.line_num
                if first:
                    first = False
                    header = _header_columns(fields)
                    if header is not None:
                        if "steering" not in header:
                            raise InputError(csv_file, "header has no 'steering' column")
                        columns, n_columns = header, len(fields)
                        continue
                data_rows += 1
                if len(fields) != n_columns:
                    skip(row, f"expected {n_columns} columns, found {len(fields)}")
                    continue
                value, reason = parse_steering(fields[columns["steering"]])
                if reason is not None or value is None:
                    skip(row, reason or "no steering value")
                    continue
                centre_raw = fields[columns["center"]].strip()
                centre = index.resolve(centre_raw)
                if centre is None:
                    what = f"'{centre_raw}'" if centre_raw else "(empty)"
                    skip(row, f"centre image {what} not found in {index.img_dir}")
                    continue
                frames.append(centre)
                steering.append(value)
                rows.append(row)
                lefts.append(index.resolve(fields[columns["left"]]) if "left" in columns else None)
                rights.append(
                    index.resolve(fields[columns["right"]]) if "right" in columns else None
                )
    except csv.Error as exc:
        raise InputError(csv_file, f"not a readable CSV ({exc})") from None
    except OSError as exc:
        raise InputError(csv_file, f"cannot read: {exc.strerror or exc}") from None

    if data_rows == 0:
        raise InputError(csv_file, "empty file: no data rows")
    if not frames:
        raise InputError(
            csv_file, f"no usable rows: all {data_rows} rows were skipped (first: {problems[0]})"
        )
    stamps = [_timestamp(f) for f in frames]
    timestamps = None if any(t is None for t in stamps) else np.array(stamps, dtype=np.float64)
    return Recording(
        root=csv_dir,
        frames=frames,
        steering=np.array(steering, dtype=np.float64),
        timestamps=timestamps,
        rows=np.array(rows, dtype=np.int64),
        problems=problems,
        kind="udacity",
        left=lefts if any(p is not None for p in lefts) else None,
        right=rights if any(p is not None for p in rights) else None,
    )
