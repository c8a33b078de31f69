"""The common result of every recording loader: frames, steering and where each came from."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn.errors import InputError, ParameterError


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
        Steering per frame in [-1, 1], negative = left.
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

    def __post_init__(self) -> None:
        n = len(self.frames)
        self.steering = np.asarray(self.steering, dtype=np.float64)
        self.rows = np.asarray(self.rows, dtype=np.int64)
        if self.timestamps is not None:
            self.timestamps = np.asarray(self.timestamps, dtype=np.float64)
        lengths = {
            "steering": len(self.steering),
            "rows": len(self.rows),
            "timestamps": n if self.timestamps is None else len(self.timestamps),
            "left": n if self.left is None else len(self.left),
            "right": n if self.right is None else len(self.right),
        }
        for name, length in lengths.items():
            if length != n:
                raise ParameterError(name, f"<{length} entries>", f"one entry per frame ({n})")

    def __len__(self) -> int:
        return len(self.frames)

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
        )


def parse_steering(text: str) -> tuple[float, None] | tuple[None, str]:
    """Parse one steering value; return ``(value, None)`` or ``(None, reason)``.

    A value must be a finite number in [-1, 1].
    """
    t = text.strip()
    try:
        value = float(t)
    except ValueError:
        return None, f"steering '{t}' is not a number"
    if not math.isfinite(value):
        return None, f"steering '{t}' is not finite"
    if not -1.0 <= value <= 1.0:
        return None, f"steering {t} is outside [-1, 1]"
    return value, None


_DIGITS = re.compile(r"(\d+)")


def natural_key(name: str) -> tuple[tuple[int, int | str], ...]:
    """Sort key that orders embedded numbers by value, so ``2.png`` < ``10.png``."""
    return tuple(
        (0, int(part)) if part.isdigit() else (1, part.lower())
        for part in _DIGITS.split(name)
        if part
    )
