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
from pathlib import Path, PurePosixPath, PureWindowsPath

import numpy as np

from qdcnn.data.images import IMAGE_SUFFIXES
from qdcnn.data.recording import Recording, natural_key, parse_steering
from qdcnn.errors import InputError

STEER_TXT = "steer_values.txt"
LABELS_CSV = "labels.csv"
IMAGE_SUBDIR = "images"
# Accepted CSV header names (case-insensitive, surrounding spaces ignored); the first present wins.
IMAGE_COLUMNS: tuple[str, ...] = (
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
STEERING_COLUMNS: tuple[str, ...] = ("steering", "steer", "angle", "steering_angle", "steer_value")
TIMESTAMP_COLUMNS: tuple[str, ...] = ("timestamp",)


class _Problems:
    def __init__(self, source: Path, strict: bool) -> None:
        self.source = source
        self.strict = strict
        self.items: list[InputError] = []

    def add(self, row: int, reason: str) -> None:
        err = InputError(f"{self.source}:row {row}", reason)
        if self.strict:
            raise err
        self.items.append(err)


def _image_dir(folder: Path) -> Path:
    sub = folder / IMAGE_SUBDIR
    return sub if sub.is_dir() else folder


def _list_images(img_dir: Path) -> list[Path]:
    names = [
        e.name
        for e in os.scandir(img_dir)
        if e.is_file() and Path(e.name).suffix.lower() in IMAGE_SUFFIXES
    ]
    return [img_dir / n for n in sorted(names, key=lambda n: (natural_key(n), n))]


def _read_lines(path: Path) -> list[str]:
    try:
        return path.read_text(encoding="utf-8-sig", errors="replace").splitlines()
    except OSError as exc:
        raise InputError(path, f"cannot read: {exc.strerror or exc}") from None


def _from_txt(folder: Path, txt: Path, strict: bool) -> Recording:
    img_dir = _image_dir(folder)
    images = _list_images(img_dir)
    lines = _read_lines(txt)
    while lines and not lines[-1].strip():
        lines.pop()
    if not lines:
        raise InputError(txt, "empty file: no steering values")
    if not images:
        raise InputError(img_dir, "no image files")
    if len(lines) != len(images):
        raise InputError(txt, f"{len(lines)} steering values but {len(images)} images in {img_dir}")
    problems = _Problems(txt, strict)
    keep: list[int] = []
    values: list[float] = []
    for i, line in enumerate(lines):
        value, reason = parse_steering(line)
        if value is None:
            problems.add(i + 1, reason or "no steering value")
            continue
        keep.append(i)
        values.append(value)
    if not keep:
        raise InputError(txt, f"no usable rows: all {len(lines)} values were skipped")
    return Recording(
        root=folder,
        frames=[images[i] for i in keep],
        steering=np.array(values, dtype=np.float64),
        timestamps=None,
        rows=np.array(keep, dtype=np.int64) + 1,
        problems=problems.items,
        kind="carla",
    )


def _pick(names: list[str], accepted: tuple[str, ...]) -> int | None:
    for want in accepted:
        if want in names:
            return names.index(want)
    return None


class _ImageLookup:
    """Match a CSV's image entry to a file: by name, by stem, by frame number, or as a path."""

    def __init__(self, img_dir: Path, csv_dir: Path) -> None:
        self.csv_dir = csv_dir
        images = _list_images(img_dir) if img_dir.is_dir() else []
        self.by_name = {p.name: p for p in images}
        self.by_stem = {p.stem: p for p in images}
        self.by_number = {int(p.stem): p for p in images if p.stem.isdigit()}

    def find(self, raw: str) -> Path | None:
        text = raw.strip()
        if not text:
            return None
        name = PureWindowsPath(text).name
        found = self.by_name.get(name) or self.by_stem.get(name)
        if found is None and name.isdigit():
            found = self.by_number.get(int(name))
        if found is not None:
            return found
        if PureWindowsPath(text).drive:
            return None
        given = Path(PurePosixPath(text.replace("\\", "/")))
        candidate = given if given.is_absolute() else self.csv_dir / given
        return candidate.resolve() if candidate.is_file() else None


def _from_csv(folder: Path, csv_file: Path, strict: bool) -> Recording:
    lookup = _ImageLookup(_image_dir(folder), csv_file.parent)
    problems = _Problems(csv_file, strict)
    frames: list[Path] = []
    values: list[float] = []
    stamps: list[float] = []
    rows: list[int] = []
    header: list[str] | None = None
    image_col = steer_col = 0
    time_col: int | None = None
    data_rows = 0
    try:
        with open(csv_file, newline="", encoding="utf-8-sig", errors="replace") as fh:
            reader = csv.reader(fh, skipinitialspace=True)
            for fields in reader:
                if not fields or all(not f.strip() for f in fields):
                    continue
                row = reader.line_num
                if header is None:
                    header = [f.strip().lower() for f in fields]
                    found_image = _pick(header, IMAGE_COLUMNS)
                    found_steer = _pick(header, STEERING_COLUMNS)
                    if found_image is None or found_steer is None:
                        missing = "image" if found_image is None else "steering"
                        raise InputError(
                            csv_file,
                            f"header '{','.join(fields)}' has no {missing} column "
                            f"(image: {', '.join(IMAGE_COLUMNS)}; "
                            f"steering: {', '.join(STEERING_COLUMNS)})",
                        )
                    image_col, steer_col = found_image, found_steer
                    time_col = _pick(header, TIMESTAMP_COLUMNS)
                    continue
                data_rows += 1
                if len(fields) != len(header):
                    problems.add(row, f"expected {len(header)} columns, found {len(fields)}")
                    continue
                value, reason = parse_steering(fields[steer_col])
                if value is None:
                    problems.add(row, reason or "no steering value")
                    continue
                stamp = math.nan
                if time_col is not None:
                    try:
                        stamp = float(fields[time_col])
                    except ValueError:
                        stamp = math.nan
                    if not math.isfinite(stamp):
                        problems.add(row, f"timestamp '{fields[time_col].strip()}' is not a number")
                        continue
                image = lookup.find(fields[image_col])
                if image is None:
                    problems.add(row, f"image '{fields[image_col].strip()}' not found")
                    continue
                frames.append(image)
                values.append(value)
                stamps.append(stamp)
                rows.append(row)
    except csv.Error as exc:
        raise InputError(csv_file, f"not a readable CSV ({exc})") from None
    except OSError as exc:
        raise InputError(csv_file, f"cannot read: {exc.strerror or exc}") from None
    if header is None or data_rows == 0:
        raise InputError(csv_file, "empty file: no data rows")
    if not frames:
        raise InputError(
            csv_file,
            f"no usable rows: all {data_rows} rows were skipped (first: {problems.items[0]})",
        )
    return Recording(
        root=folder,
        frames=frames,
        steering=np.array(values, dtype=np.float64),
        timestamps=None if time_col is None else np.array(stamps, dtype=np.float64),
        rows=np.array(rows, dtype=np.int64),
        problems=problems.items,
        kind="carla",
    )


def _find_labels(folder: Path) -> Path:
    txt = folder / STEER_TXT
    if txt.is_file():
        return txt
    if (folder / LABELS_CSV).is_file():
        return folder / LABELS_CSV
    csvs = sorted(p for p in folder.glob("*.csv") if p.is_file())
    if len(csvs) == 1:
        return csvs[0]
    if csvs:
        names = ", ".join(p.name for p in csvs)
        raise InputError(
            folder,
            f"several CSV files ({names}): name the labels file {LABELS_CSV} or pass its path",
        )
    raise InputError(folder, f"no {STEER_TXT} or labels CSV found")


def load_carla(path: str | os.PathLike[str], *, strict: bool = False) -> Recording:
    """Load a folder of images with steering labels (CARLA-style datasets).

    Parameters
    ----------
    path : str or path-like
        The recording folder, or its label file (``steer_values.txt`` or a CSV).
    strict : bool
        Raise on the first unusable row instead of skipping it.

    Returns
    -------
    Recording
        ``kind="carla"``, in label-file order. ``timestamps`` come from a
        ``timestamp`` CSV column (seconds) and are ``None`` otherwise.

    Raises
    ------
    InputError
        Missing folder or labels, an empty label file, no images, a count
        mismatch between ``steer_values.txt`` and the images (naming both
        counts), a CSV header without the needed columns, or no usable row; with
        ``strict=True`` also the first unusable row (``"<file>:row <n>: <reason>"``).

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
    columns, a steering value that is not a finite number in [-1, 1], a
    non-numeric timestamp or no matching image are skipped into ``problems``.
    A ``steer_values.txt`` line that is not a valid value skips its image.
    """
    p = Path(path)
    if not p.exists():
        raise InputError(p, "not found")
    if p.is_dir():
        folder, labels = p.resolve(), _find_labels(p.resolve())
    else:
        folder, labels = p.parent.resolve(), p.resolve()
    if labels.suffix.lower() == ".csv":
        return _from_csv(folder, labels, strict)
    return _from_txt(folder, labels, strict)
