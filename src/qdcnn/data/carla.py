"""Load CARLA-style recordings: a folder of images plus steering labels.

Two label layouts are read:

* ``steer_values.txt``: one steering value per line, matched by position to the
  images sorted in natural order of file name (``2.png`` before ``10.png``);
* a CSV with a header (``labels.csv``, or the only ``*.csv`` in the folder)
  naming an image column and a steering column, matched by file name.

Images live in ``images/`` inside the folder when it exists, else in the folder itself.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass
from pathlib import Path, PurePosixPath, PureWindowsPath

import numpy as np

from qdcnn.data.images import IMAGE_SUFFIXES, display_path, is_regular_file
from qdcnn.data.labels import check_steering_unit
from qdcnn.data.recording import LabelRow, LabelRows, Recording, natural_key, parse_steering
from qdcnn.errors import InputError

_STEER_TXT = "steer_values.txt"
_LABELS_CSV = "labels.csv"
_IMAGE_SUBDIR = "images"
# Accepted CSV header names (case-insensitive, surrounding spaces ignored); the first present wins.
_IMAGE_COLUMNS: tuple[str, ...] = (
    "image",
    "filename",
    "file_name",
    "file",
    "frame",
    "image_path",
    "img",
    "path",
    "center",
)
_STEERING_COLUMNS: tuple[str, ...] = ("steering", "steer", "angle", "steering_angle", "steer_value")
_TIMESTAMP_COLUMNS: tuple[str, ...] = ("timestamp",)


#: Any finite steering value is read; the unit decides the range afterwards.
_WIDEST = math.inf


def _image_dir(folder: Path) -> Path:
    sub = folder / _IMAGE_SUBDIR
    return sub if sub.is_dir() else folder


def _list_images(img_dir: Path) -> list[Path]:
    try:
        names = [
            e.name
            for e in os.scandir(img_dir)
            if e.is_file() and Path(e.name).suffix.lower() in IMAGE_SUFFIXES
        ]
    except OSError as exc:
        raise InputError(display_path(img_dir), f"cannot list: {exc.strerror or exc}") from None
    return [img_dir / n for n in sorted(names, key=lambda n: (natural_key(n), n))]


def _read_lines(path: Path) -> list[str]:
    if not path.is_file():
        raise InputError(display_path(path), "not a regular file (a label file is expected)")
    try:
        return path.read_text(encoding="utf-8-sig", errors="replace").splitlines()
    except OSError as exc:
        raise InputError(display_path(path), f"cannot read: {exc.strerror or exc}") from None


def _from_txt(folder: Path, txt: Path, strict: bool, steering_unit: str) -> Recording:
    img_dir = _image_dir(folder)
    images = _list_images(img_dir)
    lines = _read_lines(txt)
    shown = display_path(txt)
    while lines and not lines[-1].strip():
        lines.pop()
    if not lines:
        raise InputError(shown, "empty file: no steering values")
    if not images:
        raise InputError(display_path(img_dir), "no image files")
    if len(lines) != len(images):
        raise InputError(
            shown,
            f"{len(lines)} steering values but {len(images)} images in {display_path(img_dir)}",
        )
    table = LabelRows(shown, strict)
    for i, line in enumerate(lines):
        value, reason = parse_steering(line, _WIDEST)
        if value is None:
            table.skip(i + 1, reason or "no steering value")
        else:
            table.add(LabelRow(i + 1, images[i], value, line.strip()))
    kept, unit, problems = table.finish(steering_unit)
    if not kept:
        raise InputError(shown, f"no usable rows: all {len(lines)} values were skipped")
    return Recording(
        root=folder,
        frames=[e.frame for e in kept],
        steering=np.array([e.value for e in kept], dtype=np.float64),
        timestamps=None,
        rows=np.array([e.row for e in kept], dtype=np.int64),
        positions=np.array([e.position for e in kept], dtype=np.int64),
        problems=problems,
        kind="carla",
        unit=unit,
    )


def _pick(names: list[str], accepted: tuple[str, ...]) -> int | None:
    for want in accepted:
        if want in names:
            return names.index(want)
    return None


def _is_frame_number(text: str) -> bool:
    """ASCII digits only (``int`` refuses other Unicode digits and over 4300 of them)."""
    return text.isascii() and text.isdigit() and len(text) <= 40


class _OutsideRecording(Exception):
    """A row's image path leads out of the recording folder (the message is the folder)."""


class _ImageLookup:
    """Match a CSV's image entry to a file: by name, by stem, by frame number, or as a path."""

    def __init__(self, img_dir: Path, csv_dir: Path) -> None:
        self.csv_dir = csv_dir
        images = _list_images(img_dir) if img_dir.is_dir() else []
        self.by_name = {p.name: p for p in images}
        self.by_stem = {p.stem: p for p in images}
        self.by_number = {int(p.stem): p for p in images if _is_frame_number(p.stem)}

    def find(self, raw: str) -> Path | None:
        text = raw.strip()
        if not text:
            return None
        name = PureWindowsPath(text).name
        found = self.by_name.get(name) or self.by_stem.get(name)
        if found is None and _is_frame_number(name):
            found = self.by_number.get(int(name))
        if found is not None:
            return found
        if PureWindowsPath(text).drive:
            return None
        given = Path(PurePosixPath(text.replace("\\", "/")))
        candidate = (given if given.is_absolute() else self.csv_dir / given).resolve()
        if not candidate.is_relative_to(self.csv_dir.resolve()):
            raise _OutsideRecording(display_path(self.csv_dir))
        return candidate if is_regular_file(candidate) else None


@dataclass
class _Columns:
    """Positions of the columns a labels CSV header names."""

    width: int
    image: int
    steering: int
    timestamp: int | None

    @classmethod
    def from_header(cls, fields: list[str], source: str) -> _Columns:
        names = [f.strip().lower() for f in fields]
        image = _pick(names, _IMAGE_COLUMNS)
        steering = _pick(names, _STEERING_COLUMNS)
        if image is None or steering is None:
            missing = "image" if image is None else "steering"
            raise InputError(
                source,
                f"header '{','.join(fields)}' has no {missing} column "
                f"(image: {', '.join(_IMAGE_COLUMNS)}; steering: {', '.join(_STEERING_COLUMNS)})",
            )
        return cls(len(names), image, steering, _pick(names, _TIMESTAMP_COLUMNS))


def _from_csv(folder: Path, csv_file: Path, strict: bool, steering_unit: str) -> Recording:
    lookup = _ImageLookup(_image_dir(folder), csv_file.parent)
    shown = display_path(csv_file)
    table = LabelRows(shown, strict)
    columns, data_rows = _read_csv_rows(csv_file, lookup, table)
    if columns is None or data_rows == 0:
        raise InputError(shown, "empty file: no data rows")
    kept, unit, problems = table.finish(steering_unit)
    if not kept:
        raise InputError(
            shown, f"no usable rows: all {data_rows} rows were skipped (first: {problems[0]})"
        )
    stamps = [e.stamp for e in kept]
    return Recording(
        root=folder,
        frames=[e.frame for e in kept],
        steering=np.array([e.value for e in kept], dtype=np.float64),
        timestamps=None if columns.timestamp is None else np.array(stamps, dtype=np.float64),
        rows=np.array([e.row for e in kept], dtype=np.int64),
        positions=np.array([e.position for e in kept], dtype=np.int64),
        problems=problems,
        kind="carla",
        unit=unit,
    )


def _read_csv_rows(
    csv_file: Path, lookup: _ImageLookup, table: LabelRows
) -> tuple[_Columns | None, int]:
    """Read the header and every row into ``table``; return the columns and the data-row count."""
    columns: _Columns | None = None
    data_rows = 0
    if not csv_file.is_file():
        raise InputError(table.source, "not a regular file (a labels CSV is expected)")
    try:
        with open(csv_file, newline="", encoding="utf-8-sig", errors="replace") as fh:
            reader = csv.reader(fh, skipinitialspace=True)
            for fields in reader:
                if not fields or all(not f.strip() for f in fields):
                    continue
                if columns is None:
                    columns = _Columns.from_header(fields, table.source)
                    continue
                data_rows += 1
                _read_csv_row(reader.line_num, fields, columns, lookup, table)
    except csv.Error as exc:
        raise InputError(table.source, f"not a readable CSV ({exc})") from None
    except OSError as exc:
        raise InputError(table.source, f"cannot read: {exc.strerror or exc}") from None
    return columns, data_rows


def _read_csv_row(
    row: int, fields: list[str], columns: _Columns, lookup: _ImageLookup, table: LabelRows
) -> None:
    if len(fields) != columns.width:
        table.skip(row, f"expected {columns.width} columns, found {len(fields)}")
        return
    text = fields[columns.steering].strip()
    value, reason = parse_steering(text, _WIDEST)
    if value is None:
        table.skip(row, reason or "no steering value")
        return
    stamp = math.nan
    if columns.timestamp is not None:
        stamp_text = fields[columns.timestamp].strip()
        try:
            stamp = float(stamp_text) if len(stamp_text) <= 64 else math.nan
        except ValueError:
            stamp = math.nan
        if not math.isfinite(stamp):
            table.skip(row, f"timestamp '{stamp_text[:64]}' is not a number")
            return
    shown = fields[columns.image].strip()
    try:
        image = lookup.find(fields[columns.image])
    except _OutsideRecording as exc:
        table.skip(row, f"image '{shown}' lies outside the recording folder {exc}")
        return
    if image is None:
        table.skip(row, f"image '{shown}' not found")
        return
    table.add(LabelRow(row, image, value, text, stamp=stamp))


def _find_labels(folder: Path) -> Path:
    txt = folder / _STEER_TXT
    if txt.exists():
        return txt
    if (folder / _LABELS_CSV).exists():
        return folder / _LABELS_CSV
    csvs = sorted(p for p in folder.glob("*.csv") if p.is_file())
    if len(csvs) == 1:
        return csvs[0]
    shown = display_path(folder)
    if csvs:
        names = ", ".join(display_path(p.name) for p in csvs)
        raise InputError(
            shown,
            f"several CSV files ({names}): name the labels file {_LABELS_CSV} or pass its path",
        )
    if not any(folder.iterdir()):
        raise InputError(shown, f"empty folder (expected images with {_STEER_TXT} or a labels CSV)")
    raise InputError(shown, f"no {_STEER_TXT} or labels CSV found")


def load_carla(
    path: str | os.PathLike[str], *, strict: bool = False, steering_unit: str = "auto"
) -> Recording:
    """Load a folder of images with steering labels (CARLA-style datasets).

    Parameters
    ----------
    path : str or path-like
        The recording folder, or its label file (``steer_values.txt`` or a CSV).
    strict : bool
        Raise on the first unusable row instead of skipping it.
    steering_unit : {"auto", "norm", "rad", "deg"}
        Unit of the steering values; ``"auto"`` decides from the values
        (:func:`~qdcnn.data.labels.infer_steering_unit`). The decision is
        ``Recording.unit``.

    Returns
    -------
    Recording
        ``kind="carla"``, in label-file order. ``timestamps`` come from a
        ``timestamp`` CSV column (seconds) and are ``None`` otherwise.

    Raises
    ------
    InputError
        A missing or empty folder, missing labels, an empty label file, no
        images, a count mismatch between ``steer_values.txt`` and the images
        (naming both counts), a CSV header without the needed columns, or no
        usable row; with ``strict=True`` also the first unusable row
        (``"<file>:row <n>: <reason>"``).

    Notes
    -----
    The label file is ``steer_values.txt`` when present, else ``labels.csv``,
    else the only ``*.csv`` in the folder. Accepted CSV header names
    (case-insensitive): image column ``image``, ``filename``, ``file_name``,
    ``file``, ``frame``, ``image_path``, ``img``, ``path`` or ``center``;
    steering column ``steering``, ``steer``, ``angle``, ``steering_angle`` or
    ``steer_value``; optional ``timestamp``. An image entry is matched by file
    name, by name without suffix, by frame number (``7`` matches ``000007.png``)
    or as a path relative to the CSV's folder. Rows with the wrong number of
    columns, a steering value that is not a finite number in the unit's range
    ([-1, 1] for ``norm``), a non-numeric timestamp, no matching image, or an
    image an earlier row already listed are skipped into ``problems`` with their
    line numbers. A ``steer_values.txt`` line that is not a valid value skips its
    image. Image names that are not UTF-8 are listed and matched like others.
    """
    check_steering_unit(steering_unit)
    p = Path(path)
    if not p.exists():
        raise InputError(display_path(p), "not found")
    if p.is_dir():
        folder, labels = p.resolve(), _find_labels(p.resolve())
    else:
        folder, labels = p.parent.resolve(), p.resolve()
    if labels.suffix.lower() == ".csv":
        return _from_csv(folder, labels, strict, steering_unit)
    return _from_txt(folder, labels, strict, steering_unit)
