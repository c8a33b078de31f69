"""Contiguous splits of a recording: the one splitter every fold, search and validation uses.

Frames of a recording are a video: neighbours are near duplicates, and direction labels
come from steering smoothed over neighbouring frames. So every split is made of
contiguous blocks with ``gap`` frames on each side of a held-out block left out of
training (:class:`ContiguousKFold`); a validation split for early stopping takes some of
those blocks (:func:`validation_split`).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import ArrayLike, NDArray
from sklearn.model_selection import BaseCrossValidator

from qdcnn._validation import check_float, check_int
from qdcnn.errors import InputError, ParameterError

__all__ = ["ContiguousKFold", "Split", "validation_split"]

Split = tuple[NDArray[np.intp], NDArray[np.intp]]


class ContiguousKFold(BaseCrossValidator):
    """K contiguous test blocks; training leaves out ``gap`` frames on each side of a block.

    Blocks are those of scikit-learn's ``KFold(n_splits, shuffle=False)``: sizes differ by
    at most one frame and they cover every frame once, in order.

    Parameters
    ----------
    n_splits : int
        Number of folds, at least 2.
    gap : int
        Frames on each side of a test block that neither train nor test, at least 0 and
        smaller than the shortest test block (so that training keeps most frames).

    Examples
    --------
    >>> cv = ContiguousKFold(3, gap=1)
    >>> [(train.tolist(), test.tolist()) for train, test in cv.split(range(9))]
    [([4, 5, 6, 7, 8], [0, 1, 2]), ([0, 1, 7, 8], [3, 4, 5]), ([0, 1, 2, 3, 4], [6, 7, 8])]
    """

    def __init__(self, n_splits: int = 5, gap: int = 0) -> None:
        self.n_splits = n_splits
        self.gap = gap

    def get_n_splits(self, X: object = None, y: object = None, groups: object = None) -> int:
        return int(self.n_splits)

    def check(self, n: int) -> None:
        """Refuse a protocol that cannot be run honestly on ``n`` frames."""
        check_int("folds", self.n_splits, 2, max(2, n))
        gap = check_int("gap", self.gap, 0)
        shortest = n // int(self.n_splits)
        if gap >= shortest:
            raise ParameterError(
                "gap",
                gap,
                f"smaller than the shortest test block ({shortest} frames: {n} frames in "
                f"{self.n_splits} folds)",
            )

    def split(
        self, X: ArrayLike, y: ArrayLike | None = None, groups: ArrayLike | None = None
    ) -> Iterator[Split]:
        n = len(X)  # type: ignore[arg-type]
        self.check(n)
        sizes = np.full(int(self.n_splits), n // int(self.n_splits))
        sizes[: n % int(self.n_splits)] += 1
        starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        idx = np.arange(n)
        for start, size in zip(starts, sizes, strict=True):
            lo, hi = start - int(self.gap), start + size - 1 + int(self.gap)
            train = idx[(idx < lo) | (idx > hi)]
            yield train, idx[start : start + size]


def validation_split(
    n: int, fraction: float, *, blocks: int = 1, gap: int = 0
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Training and validation frames of ``n`` frames in recording order, by contiguous blocks.

    The recording is cut into ``blocks`` equal stretches and each stretch into
    ``round(1 / fraction)`` folds of :class:`ContiguousKFold`; the last fold of every
    stretch validates (so the last block ends at the last frame), and the ``gap``
    frames on each side of a validation block neither train nor validate. Several blocks
    sample several stretches of road: one block at the end of a short recording can
    miss a class altogether (a left bend, say). On short inputs the split degrades
    gracefully: fewer blocks when a block would be shorter than ``2 * gap`` frames,
    and shorter gaps so that they take at most half of the frames that do not validate.
    ``fraction=0`` validates nothing.

    Examples
    --------
    >>> train, val = validation_split(10, 0.2)
    >>> train.tolist(), val.tolist()
    ([0, 1, 2, 3, 4, 5, 6, 7], [8, 9])
    >>> train, val = validation_split(20, 0.2, blocks=2, gap=1)
    >>> train.tolist(), val.tolist()
    ([0, 1, 2, 3, 4, 5, 6, 11, 12, 13, 14, 15, 16], [8, 9, 18, 19])
    """
    check_int("frames", n, 0)
    check_float("val_fraction", fraction, 0.0, 1.0, open_hi=True)
    check_int("val_blocks", blocks, 1)
    check_int("val_gap", gap, 0)
    if fraction == 0 or n == 0:
        return _checked_training(np.arange(n, dtype=np.int64), n), np.zeros(0, dtype=np.int64)
    per_block = max(2, round(1 / fraction))
    blocks = max(1, min(blocks, round(n * fraction) // max(1, 2 * gap)))
    folds = min(blocks * per_block, n)
    tests = [test for _, test in ContiguousKFold(folds).split(np.arange(n))]
    picked = [tests[min((b + 1) * per_block, folds) - 1] for b in range(blocks)]
    val = np.concatenate(picked).astype(np.int64)
    gap = min(gap, (n - val.size) // (4 * blocks))
    near = np.zeros(n, dtype=bool)
    for block in picked:
        near[max(int(block[0]) - gap, 0) : int(block[-1]) + gap + 1] = True
    return _checked_training(np.flatnonzero(~near).astype(np.int64), n), val


def _checked_training(train: NDArray[np.int64], n: int) -> NDArray[np.int64]:
    if len(train) < 2:
        raise InputError("images", f"{n} frames leave {len(train)} for training; need at least 2")
    return train
