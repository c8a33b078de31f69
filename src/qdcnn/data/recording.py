"""The common result of every recording loader: frames, steering and where each came from."""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn.config import LabelConfig
from qdcnn.data.images import display_path
from qdcnn.data.labels import DirectionLabels, SteeringUnit, label_directions, resolve_steering_unit
from qdcnn.errors import InputError, ParameterError

_LABELS = LabelConfig()


class RowError(InputError):
    """A row of a label file that was skipped: ``"<file>:row <n>: <reason>"``.

    ``row`` is its 1-based line number; ``position`` its 0-based place among the file's
    data rows (the frame number it would have had), so runs can keep it as a frame.
    """

    def __init__(self, source: str, row: int, position: int, reason: str) -> None:
        super().__init__(f"{source}:row {row}", reason)
        self.row = row
        self.position = position


@dataclass
class Recording:
    """Frames of a driving recording with one steering value each.

    Attributes
    ----------
    root : Path
        The recording folder.
    frames : list of Path
        Resolved centre-camera image paths; every one existed when loaded.
    steering : ndarray of float64, shape (N,)
        Steering per frame in ``unit``, as recorded; negative = left.
    timestamps : ndarray of float64, shape (N,), or None
        Capture time per frame in seconds, ``None`` when the source has none.
    rows : ndarray of int64, shape (N,)
        1-based line number in the label file (CSV or txt) each frame came from.
    problems : list of InputError
        Rows or files that were skipped, each naming ``file:row n`` and the reason.
    kind : str
        ``"udacity"`` or ``"carla"``.
    left, right : list of (Path or None), or None
        Side-camera images per frame (``None`` entries where missing), or ``None``
        when the recording has no side-camera image at all.
    unit : SteeringUnit
        The unit of ``steering`` and how it was decided (``norm`` by default).
    positions : ndarray of int64, shape (N,), or None
        Each frame's 0-based place among the label file's data rows, skipped rows
        included (a skipped row's place is its :class:`RowError`'s ``position``);
        ``None``: ``0 .. N-1``.
    """

    root: Path
    frames: list[Path]
    steering: NDArray[np.float64]
    timestamps: NDArray[np.float64] | None
    rows: NDArray[np.int64]
    problems: list[InputError]
    kind: str
    left: list[Path | None] | None = None
    right: list[Path | None] | None = None
    unit: SteeringUnit = field(default_factory=SteeringUnit)
    positions: NDArray[np.int64] | None = None

    def __post_init__(self) -> None:
        n = len(self.frames)
        self.steering = np.asarray(self.steering, dtype=np.float64)
        self.rows = np.asarray(self.rows, dtype=np.int64)
        if self.positions is not None:
            self.positions = np.asarray(self.positions, dtype=np.int64)
        if self.timestamps is not None:
            self.timestamps = np.asarray(self.timestamps, dtype=np.float64)
        lengths = {
            "steering": len(self.steering),
            "rows": len(self.rows),
            "timestamps": n if self.timestamps is None else len(self.timestamps),
            "left": n if self.left is None else len(self.left),
            "right": n if self.right is None else len(self.right),
            "positions": n if self.positions is None else len(self.positions),
        }
        for name, length in lengths.items():
            if length != n:
                raise ParameterError(name, f"<{length} entries>", f"one entry per frame ({n})")

    def __len__(self) -> int:
        return len(self.frames)

    def labels(
        self,
        threshold: float | None = None,
        *,
        window: int = _LABELS.window,
        max_gap_s: float = _LABELS.max_gap_s,
    ) -> DirectionLabels:
        """Direction labels in this recording's unit (:func:`~qdcnn.data.labels.label_directions`).

        ``threshold`` is in ``unit.unit``; ``None`` is that unit's default.
        """
        return label_directions(
            self.steering,
            self.timestamps,
            unit=self.unit,
            threshold=threshold,
            window=window,
            max_gap_s=max_gap_s,
        )

    def subset(self, idx: Any) -> Recording:
        """Return the frames selected by ``idx`` (a slice, integer indices or a boolean mask).

        ``problems`` is kept unchanged: it describes the source, not the selection.
        """
        try:
            take = np.arange(len(self))[idx]
        except IndexError as exc:
            raise ParameterError(
                "idx", f"<{type(idx).__name__}>", f"valid indices ({exc})"
            ) from None
        take = np.atleast_1d(np.asarray(take, dtype=np.int64))

        def pick(items: list[Path | None] | None) -> list[Path | None] | None:
            return None if items is None else [items[i] for i in take]

        return Recording(
            root=self.root,
            frames=[self.frames[i] for i in take],
            steering=self.steering[take],
            timestamps=None if self.timestamps is None else self.timestamps[take],
            rows=self.rows[take],
            problems=list(self.problems),
            kind=self.kind,
            left=pick(self.left),
            right=pick(self.right),
            unit=self.unit,
            positions=None if self.positions is None else self.positions[take],
        )


def parse_steering(text: str, limit: float = 1.0) -> tuple[float, None] | tuple[None, str]:
    """Parse one steering value; return ``(value, None)`` or ``(None, reason)``.

    A value must be a finite number in ``[-limit, limit]``.
    """
    t = text.strip()
    if len(t) > 64:
        return None, f"steering of {len(t)} characters is not a number"
    try:
        value = float(t)
    except ValueError:
        return None, f"steering '{t}' is not a number"
    if not math.isfinite(value):
        return None, f"steering '{t}' is not finite"
    if not -limit <= value <= limit:
        return None, f"steering {t} is outside [{-limit:g}, {limit:g}]"
    return value, None


@dataclass
class LabelRow:
    """One usable row of a label file, before duplicates and the unit are settled."""

    row: int
    frame: Path
    value: float
    text: str
    left: Path | None = None
    right: Path | None = None
    stamp: float = math.nan
    position: int = -1


@dataclass
class LabelRows:
    """The rows of one label file: the usable ones and the skipped ones with reasons.

    Loaders :meth:`add` each usable row and :meth:`skip` each unusable one while
    reading, then :meth:`finish` settles the steering unit, refuses values outside
    it and drops repeated images.
    """

    source: str
    strict: bool = False
    entries: list[LabelRow] = field(default_factory=list)
    skipped: list[tuple[int, str]] = field(default_factory=list)

    def add(self, entry: LabelRow) -> None:
        self.entries.append(entry)

    def skip(self, row: int, reason: str) -> None:
        self.skipped.append((row, reason))

    def finish(
        self,
        steering_unit: str,
        simulator_names: Callable[[Sequence[Path]], bool] | None = None,
    ) -> tuple[list[LabelRow], SteeringUnit, list[InputError]]:
        """Kept rows (file order), the steering unit, and every skipped row as an error.

        The unit is ``steering_unit`` or, for ``"auto"``, inferred from the usable
        rows (:func:`~qdcnn.data.labels.infer_steering_unit`); rows with values
        beyond the unit's range are reported, then an image listed again is dropped
        (the first row that is still usable keeps it) and reported. Errors are
        sorted by row; with ``strict`` the first is raised.
        """
        frames = [e.frame for e in self.entries]
        sim = bool(frames) and simulator_names is not None and simulator_names(frames)
        values = [e.value for e in self.entries]
        unit = resolve_steering_unit(steering_unit, values, simulator_names=sim)
        in_range = []
        for e in self.entries:
            if abs(e.value) <= unit.limit:
                in_range.append(e)
            else:
                suffix = "" if unit.unit == "norm" else f" ({unit.unit})"
                self.skip(e.row, f"steering {e.text} is outside {_interval(unit.limit)}{suffix}")
        kept = self._unique(in_range)
        # a row's place among the data rows: line numbers grow down the file
        place = {row: k for k, row in enumerate(sorted(self.data_rows()))}
        for e in kept:
            e.position = place[e.row]
        errors: list[InputError] = [
            RowError(self.source, row, place[row], reason)
            for row, reason in sorted(self.skipped, key=lambda item: item[0])
        ]
        if self.strict and errors:
            raise errors[0]
        return kept, unit, errors

    def data_rows(self) -> set[int]:
        """Line numbers of every data row read, usable or not."""
        return {e.row for e in self.entries} | {row for row, _ in self.skipped}

    def _unique(self, entries: list[LabelRow]) -> list[LabelRow]:
        first: dict[Path, LabelRow] = {}
        kept = []
        for e in entries:
            seen = first.get(e.frame)
            if seen is None:
                first[e.frame] = e
                kept.append(e)
                continue
            differs = "" if seen.value == e.value else f" (steering {e.text}, not {seen.text})"
            name = display_path(e.frame.name)
            self.skip(
                e.row,
                f"image '{name}' listed again (first at row {seen.row}){differs}: dropped",
            )
        return kept


def _interval(limit: float) -> str:
    return f"[{-limit:g}, {limit:g}]"


_DIGITS = re.compile(r"(\d+)")


def natural_key(name: str) -> tuple[tuple[int, int | str], ...]:
    """Sort key that orders embedded numbers by value, so ``2.png`` < ``10.png``."""
    return tuple(
        (0, int(part)) if part.isdigit() else (1, part.lower())
        for part in _DIGITS.split(name)
        if part
    )
