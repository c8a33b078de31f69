"""Shadow-mask scores: balanced error rate, per-class errors and shadow IoU.

Shadow-detection benchmarks (SBU, UCF, ISTD) report the balanced error rate

    BER = 100 * (1 - (TP / (TP + FN) + TN / (TN + FP)) / 2)

in percent, with the shadow error ``100 * FN / (TP + FN)`` and the non-shadow
error ``100 * FP / (TN + FP)``; the counts are summed over all pixels of the
whole test set, not averaged per image [1]_ [2]_. Lower is better; a detector
that marks everything shadow (or nothing) has BER 50.

Masks are ``bool`` arrays used as they are, or ``uint8`` arrays binarised at
:data:`qdcnn.data.images.MASK_LEVEL` (shadow if ``>= 128``), as ground-truth
files are read.

Where one class is absent from the ground truth (for example a road frame with
no shadow), its error rate is undefined (``nan``) and the BER is the error rate
of the class that is present: the mean over the classes present. The shadow
IoU is ``nan`` when there is no shadow in either mask.

References
----------
.. [1] T. F. Y. Vicente, L. Hou, C.-P. Yu, M. Hoai, D. Samaras, "Large-scale
   training of shadow detectors with noisily-annotated shadow examples",
   Proc. ECCV, 2016.
.. [2] X. Hu, L. Zhu, C.-W. Fu, J. Qin, P.-A. Heng, "Direction-aware spatial
   context features for shadow detection", Proc. IEEE CVPR, 2018.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._validation import check_input_shape
from qdcnn.data.images import MASK_LEVEL
from qdcnn.errors import InputError, ParameterError

__all__ = [
    "ConfusionCounts",
    "ShadowScores",
    "as_shadow_mask",
    "confusion_counts",
    "score_mask_pairs",
    "shadow_scores",
]


@dataclass(frozen=True)
class ConfusionCounts:
    """Pixel counts of one mask pair or of a set; ``+`` sums them over a set.

    Examples
    --------
    >>> ConfusionCounts(1, 2, 3, 4) + ConfusionCounts(10, 20, 30, 40)
    ConfusionCounts(tp=11, tn=22, fp=33, fn=44)
    """

    tp: int
    tn: int
    fp: int
    fn: int

    def __post_init__(self) -> None:
        for name in ("tp", "tn", "fp", "fn"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise ParameterError(name, value, "a non-negative integer pixel count")
            object.__setattr__(self, name, int(value))

    def __add__(self, other: ConfusionCounts) -> ConfusionCounts:
        if not isinstance(other, ConfusionCounts):
            return NotImplemented
        return ConfusionCounts(
            self.tp + other.tp, self.tn + other.tn, self.fp + other.fp, self.fn + other.fn
        )

    @property
    def total(self) -> int:
        """Number of pixels counted."""
        return self.tp + self.tn + self.fp + self.fn


def as_shadow_mask(mask: NDArray[Any], *, source: str = "mask") -> NDArray[np.bool_]:
    """A 2-D ``bool`` mask from a ``bool`` one (as is) or a ``uint8`` one (``>= 128``)."""
    arr = np.asarray(mask)
    check_input_shape(source, arr, "H,W", "a 2-D mask (H, W)")
    if arr.dtype == np.bool_:
        return arr
    if arr.dtype == np.uint8:
        return np.asarray(arr >= MASK_LEVEL)
    raise InputError(source, f"expected a bool or uint8 mask, got {arr.dtype}")


def confusion_counts(
    pred: NDArray[Any], gt: NDArray[Any], *, source: str = "mask"
) -> ConfusionCounts:
    """Count true/false shadow and non-shadow pixels of a predicted mask against ground truth.

    Parameters
    ----------
    pred, gt : ndarray of bool or uint8, shape (H, W)
        Predicted and ground-truth shadow masks (``uint8`` binarised at 128).
    source : str
        Name for error messages (a file name, a frame id).

    Raises
    ------
    InputError
        Masks of different shapes (both shapes named), not 2-D, or of another dtype.
    """
    p = as_shadow_mask(pred, source=source)
    g = as_shadow_mask(gt, source=source)
    if p.shape != g.shape:
        raise InputError(
            source, f"predicted mask shape {p.shape} differs from ground-truth shape {g.shape}"
        )
    tp = int(np.count_nonzero(p & g))
    fp = int(np.count_nonzero(p)) - tp
    fn = int(np.count_nonzero(g)) - tp
    return ConfusionCounts(tp=tp, tn=p.size - tp - fp - fn, fp=fp, fn=fn)


@dataclass(frozen=True)
class ShadowScores:
    """Scores of a set of masks, all in percent except ``n``.

    Attributes
    ----------
    ber : float
        Balanced error rate (mean of the two class error rates present).
    shadow_error : float
        Share of ground-truth shadow pixels missed; ``nan`` without shadow pixels.
    nonshadow_error : float
        Share of ground-truth non-shadow pixels marked shadow; ``nan`` without any.
    iou : float
        Intersection over union of the shadow class, ``100 * TP / (TP + FP + FN)``;
        ``nan`` when neither mask has a shadow pixel.
    n : int
        Number of mask pairs scored.
    """

    ber: float
    shadow_error: float
    nonshadow_error: float
    iou: float
    n: int

    def to_dict(self) -> dict[str, float | int]:
        """Plain dictionary, for JSON/CSV results."""
        return asdict(self)


def _rate(num: int, den: int) -> float:
    return 100.0 * num / den if den else math.nan


def shadow_scores(
    counts: ConfusionCounts | Iterable[ConfusionCounts], n: int | None = None
) -> ShadowScores:
    """Scores from pixel counts summed over a set.

    Parameters
    ----------
    counts : ConfusionCounts or iterable of ConfusionCounts
        One (already summed) count, or the counts of each image, which are summed.
    n : int or None
        Number of images to report; default 1 for a single count, else the
        number of counts given.

    Returns
    -------
    ShadowScores

    Raises
    ------
    ParameterError
        No counts, or counts of zero pixels.

    Examples
    --------
    >>> s = shadow_scores(ConfusionCounts(tp=30, tn=60, fp=0, fn=10))
    >>> s.ber, s.shadow_error, s.nonshadow_error, s.iou
    (12.5, 25.0, 0.0, 75.0)
    """
    if isinstance(counts, ConfusionCounts):
        total, items = counts, 1
    else:
        total, items = ConfusionCounts(0, 0, 0, 0), 0
        for c in counts:
            total, items = total + c, items + 1
        if items == 0:
            raise ParameterError("counts", [], "at least one ConfusionCounts")
    if n is not None and (isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0):
        raise ParameterError("n", n, "None or a non-negative integer")
    if total.total == 0:
        raise ParameterError("counts", total, "counts of at least one pixel")
    shadow_error = _rate(total.fn, total.tp + total.fn)
    nonshadow_error = _rate(total.fp, total.tn + total.fp)
    present = [e for e in (shadow_error, nonshadow_error) if not math.isnan(e)]
    return ShadowScores(
        ber=sum(present) / len(present),
        shadow_error=shadow_error,
        nonshadow_error=nonshadow_error,
        iou=_rate(total.tp, total.tp + total.fp + total.fn),
        n=items if n is None else int(n),
    )


def score_mask_pairs(
    pairs: Iterable[tuple[NDArray[Any], NDArray[Any]]],
) -> ShadowScores:
    """Score ``(predicted, ground_truth)`` mask pairs with counts summed over the set.

    Errors name the pair by its position, ``"pair <i>"`` (from 0).
    """
    counts = [confusion_counts(p, g, source=f"pair {i}") for i, (p, g) in enumerate(pairs)]
    return shadow_scores(counts)
