"""Load Udacity self-driving-car simulator recordings (``driving_log.csv`` + ``IMG/``).

The simulator writes one CSV row per frame: ``center, left, right, steering,
throttle, brake, speed``, usually without a header and with the absolute image
paths of the recording machine (often Windows paths). Images are found by file
name in ``IMG/`` beside the CSV, so a recording can be moved freely.
"""

from __future__ import annotations

import csv
import datetime as dt
import math
import os
import re
from collections.abc import Sequence
from pathlib import Path, PurePosixPath, PureWindowsPath

import numpy as np

from qdcnn.data.images import display_path, is_regular_file
from qdcnn.data.labels import check_steering_unit
from qdcnn.data.recording import LabelRow, LabelRows, Recording, parse_steering
from qdcnn.errors import InputError

_COLUMNS: tuple[str, ...] = ("center", "left", "right", "steering", "throttle", "brake", "speed")
_CSV_NAME = "driving_log.csv"
_IMAGE_DIR = "IMG"

# center_YYYY_MM_DD_HH_MM_SS_mmm.jpg, the simulator's capture time
_STAMP = re.compile(r"^center_(\d{4})_(\d{2})_(\d{2})_(\d{2})_(\d{2})_(\d{2})_(\d{3})\.\w+$")
# 1479425441182877835.jpg: capture time in nanoseconds since 1970 (Udacity's real-car data)
_NANOSECONDS = re.compile(r"^(\d{18,19})\.\w+$")


class _ImageIndex:
    """Resolve recorded image paths against one listing of ``IMG/``."""

    def __init__(self, csv_dir: Path) -> None:
        self.csv_dir = csv_dir
        self.img_dir = csv_dir / _IMAGE_DIR
        self.shown_dir = display_path(self.img_dir)
        try:
            names = [e.name for e in os.scandir(self.img_dir) if e.is_file()]
        except OSError:
            names = []
        self.exact = set(names)
        # Windows paths are case-insensitive: accept a case-only mismatch
        self.folded = {n.lower(): n for n in names}

    def resolve(self, raw: str) -> Path | None:
        """The image a row names, or ``None`` (missing, or outside the recording)."""
        return self.locate(raw)[0]

    def locate(self, raw: str) -> tuple[Path | None, str]:
        """The image a row names (by file name in ``IMG/`` first), or ``None`` and why.

        A path that is not found by name must lie inside the recording folder once links
        are resolved: a row never reads a file from elsewhere on the machine.
        """
        text = raw.strip()
        if not text:
            return None, "(empty)"
        windows = PureWindowsPath(text)
        name = windows.name  # splits on both "\\" and "/"
        if name in self.exact:
            return self.img_dir / name, ""
        if name.lower() in self.folded:
            return self.img_dir / self.folded[name.lower()], ""
        missing = f"'{text}' not found in {self.shown_dir}"
        if windows.drive or text.startswith("\\"):
            return None, missing  # an absolute Windows path cannot exist here
        given = Path(PurePosixPath(text.replace("\\", "/")))
        candidate = (given if given.is_absolute() else self.csv_dir / given).resolve()
        if not candidate.is_relative_to(self.csv_dir):
            where = display_path(self.csv_dir)
            return None, f"'{text}' lies outside the recording folder {where}"
        return (candidate, "") if is_regular_file(candidate) else (None, missing)


def _timestamp(path: Path) -> float | None:
    ns = _NANOSECONDS.match(path.name)
    if ns is not None:
        return int(ns.group(1)) / 1e9
    m = _STAMP.match(path.name)
    if m is None:
        return None
    y, mo, d, h, mi, s, ms = (int(g) for g in m.groups())
    try:
        when = dt.datetime(y, mo, d, h, mi, s, ms * 1000, tzinfo=dt.UTC)
    except ValueError:
        return None
    return when.timestamp()


def _simulator_names(frames: Sequence[Path]) -> bool:
    return all(_STAMP.match(f.name) for f in frames)


def _csv_path(path: str | os.PathLike[str]) -> Path:
    p = Path(path)
    if p.is_dir():
        csv_file = p / _CSV_NAME
        if not csv_file.exists():
            empty = not any(p.iterdir())
            what = "empty folder" if empty else f"no {_CSV_NAME} in this folder"
            raise InputError(
                display_path(p), f"{what} (a Udacity recording holds {_CSV_NAME} and {_IMAGE_DIR}/)"
            )
    else:
        csv_file = p
    if not csv_file.exists():
        raise InputError(display_path(csv_file), "file not found")
    if not csv_file.is_file():
        raise InputError(display_path(csv_file), "not a regular file (a CSV file is expected)")
    return csv_file


def _header_columns(fields: list[str]) -> dict[str, int] | None:
    """Column positions from a header row, or ``None`` when the row is data."""
    names = [f.strip().lower() for f in fields]
    if "center" not in names:
        return None
    return {name: names.index(name) for name in _COLUMNS if name in names}


def load_udacity(
    path: str | os.PathLike[str], *, strict: bool = False, steering_unit: str = "auto"
) -> Recording:
    """Load a Udacity simulator recording (or a real-car log in the same layout).

    Parameters
    ----------
    path : str or path-like
        The recording folder (holding ``driving_log.csv`` and ``IMG/``) or the CSV itself.
    strict : bool
        Raise on the first unusable row instead of skipping it.
    steering_unit : {"auto", "norm", "rad", "deg"}
        Unit of the steering column; ``"auto"`` decides from the image names and
        values (:func:`~qdcnn.data.labels.infer_steering_unit`; simulator names mean
        ``norm``). The decision is ``Recording.unit``.

    Returns
    -------
    Recording
        ``kind="udacity"``. ``timestamps`` come from the centre image names
        (``center_YYYY_MM_DD_HH_MM_SS_mmm.jpg``, read as UTC: only differences
        matter, or ``<nanoseconds>.jpg`` of 18-19 digits) and are ``None`` when
        any name follows neither pattern. ``left``/``right`` are ``None`` when no
        side-camera image exists at all.

    Raises
    ------
    InputError
        A missing or empty folder or CSV, a header without ``center`` and
        ``steering`` columns, or no usable row; with ``strict=True`` also the first
        unusable row (``"<csv>:row <n>: <reason>"``).

    Notes
    -----
    A row is skipped (and recorded in ``problems`` with its line number) when it
    has the wrong number of columns, its steering is not a finite number in the
    unit's range ([-1, 1] for ``norm``), its centre image is not found, or it
    lists an image an earlier row already listed (the first row keeps it). Image
    paths are resolved by file name in ``IMG/`` beside the CSV (absolute Windows
    or POSIX paths alike); a path that is not there is used as given when it
    exists (relative paths from the CSV's folder). Images are never opened:
    ``IMG/`` is listed once.
    """
    check_steering_unit(steering_unit)
    csv_file = _csv_path(path)
    csv_dir = csv_file.parent.resolve()
    index = _ImageIndex(csv_dir)
    shown = display_path(csv_file)
    table = LabelRows(shown, strict)
    data_rows = _read_rows(csv_file, index, table)
    if data_rows == 0:
        raise InputError(shown, "empty file: no data rows")
    kept, unit, problems = table.finish(steering_unit, _simulator_names)
    if not kept:
        raise InputError(
            shown, f"no usable rows: all {data_rows} rows were skipped (first: {problems[0]})"
        )
    frames = [e.frame for e in kept]
    lefts = [e.left for e in kept]
    rights = [e.right for e in kept]
    stamps = [_timestamp(f) for f in frames]
    timestamps = None if any(t is None for t in stamps) else np.array(stamps, dtype=np.float64)
    return Recording(
        root=csv_dir,
        frames=frames,
        steering=np.array([e.value for e in kept], dtype=np.float64),
        timestamps=timestamps,
        rows=np.array([e.row for e in kept], dtype=np.int64),
        positions=np.array([e.position for e in kept], dtype=np.int64),
        problems=problems,
        kind="udacity",
        left=lefts if any(p is not None for p in lefts) else None,
        right=rights if any(p is not None for p in rights) else None,
        unit=unit,
    )


def _read_rows(csv_file: Path, index: _ImageIndex, table: LabelRows) -> int:
    """Read every row into ``table``; return the number of data rows."""
    columns = {name: i for i, name in enumerate(_COLUMNS)}
    n_columns = len(_COLUMNS)
    data_rows = 0
    first = True
    widest = math.inf  # the unit is settled after reading, and with it the range
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
                            raise InputError(table.source, "header has no 'steering' column")
                        columns, n_columns = header, len(fields)
                        continue
                data_rows += 1
                if len(fields) != n_columns:
                    table.skip(row, f"expected {n_columns} columns, found {len(fields)}")
                    continue
                text = fields[columns["steering"]].strip()
                value, reason = parse_steering(text, widest)
                if value is None:
                    table.skip(row, reason or "no steering value")
                    continue
                centre, why = index.locate(fields[columns["center"]])
                if centre is None:
                    table.skip(row, f"centre image {why}")
                    continue
                left = index.resolve(fields[columns["left"]]) if "left" in columns else None
                right = index.resolve(fields[columns["right"]]) if "right" in columns else None
                table.add(LabelRow(row, centre, value, text, left, right))
    except csv.Error as exc:
        raise InputError(table.source, f"not a readable CSV ({exc})") from None
    except OSError as exc:
        raise InputError(table.source, f"cannot read: {exc.strerror or exc}") from None
    return data_rows
