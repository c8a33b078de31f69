"""Scores of direction predictions, and how sure each number is.

:func:`score` gives accuracy, balanced accuracy (the main figure: mean recall over the
classes present in the test labels), macro-F1, per-class recall and the confusion
matrix of labels 0 left, 1 straight, 2 right (:data:`~qdcnn.data.labels.DIRECTIONS`).

Neighbouring frames of a recording are not independent evidence: a bend is many frames
long and a method that misreads it misreads all of them. :func:`block_bootstrap` gives a
95 % interval from a circular block bootstrap (Politis & Romano 1992; the moving-block
bootstrap of Künsch 1989 without its under-weighted ends): each resample concatenates
contiguous runs of test frames, wrapping at the end, to the original length.
:func:`paired_difference` compares two methods on the same resampled frames.
docs/uncertainty.md says how the block length is chosen and what coverage it gave.

Examples
--------
>>> s = score([0, 1, 1, 2], [0, 1, 2, 2])
>>> s.accuracy, s.balanced_accuracy
(0.75, 0.8333333333333334)
>>> format_with_interval(0.7134, Interval(0.6621, 0.7602, 1000, 25, "circular block"))
'0.71 [0.66, 0.76]'
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from qdcnn._validation import check_choice, check_direction_labels, check_int, check_seed
from qdcnn.config import LabelConfig
from qdcnn.data.labels import DIRECTIONS
from qdcnn.errors import InputError, ParameterError

__all__ = [
    "METRICS",
    "Difference",
    "Interval",
    "Scores",
    "block_bootstrap",
    "block_length",
    "collapsed",
    "format_metric",
    "format_value",
    "format_with_interval",
    "one_answer_share",
    "paired_difference",
    "politis_white_block",
    "score",
]

#: Metrics the bootstrap can resample.
METRICS: tuple[str, ...] = ("accuracy", "balanced_accuracy", "macro_f1")
N_CLASSES = len(DIRECTIONS)
_LABELS = list(range(N_CLASSES))
#: Blocks are at least the span of the label smoothing (2 * window + 1 frames).
DEFAULT_MIN_BLOCK = 2 * LabelConfig().window + 1
#: The automatic block length is this many times Politis & White's MSE-optimal length.
BLOCK_FACTOR = 2.0
_PW_RUN = 5  # Politis & White's K: small autocorrelations in a row that end the dependence
#: A test block where one answer covers more than this share of the frames while the truth
#: holds two classes with :data:`PRESENT_SHARE` each counts as a collapse (issue 20).
COLLAPSE_SHARE = 0.95
PRESENT_SHARE = 0.10
METHOD = "circular block bootstrap, percentile, widened by sqrt(n/(n-b)) and t(n/b-1)/z"


@dataclass(frozen=True)
class Scores:
    """Scores of one method on one set of test frames.

    Attributes
    ----------
    n : int
        Test frames.
    accuracy : float
        Correct predictions over test frames.
    balanced_accuracy : float or None
        Mean recall over the classes present in the test labels; ``None`` when only one
        class is present (then ``undefined`` says why).
    macro_f1 : float
        Mean F1 over the classes in the labels or the predictions.
    per_class : dict of str to float or None
        Recall per class name; ``None`` for a class absent from the test labels.
    confusion : tuple of tuple of int
        3x3 counts, rows true class, columns predicted class.
    undefined : str or None
        Why ``balanced_accuracy`` is ``None``.
    """

    n: int
    accuracy: float
    balanced_accuracy: float | None
    macro_f1: float
    per_class: dict[str, float | None]
    confusion: tuple[tuple[int, ...], ...]
    undefined: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain values for JSON output."""
        out: dict[str, Any] = {
            "n": self.n,
            "accuracy": self.accuracy,
            "balanced_accuracy": self.balanced_accuracy,
            "macro_f1": self.macro_f1,
            "per_class": dict(self.per_class),
            "confusion": [list(row) for row in self.confusion],
        }
        if self.undefined is not None:
            out["undefined"] = self.undefined
        return out


@dataclass(frozen=True)
class Interval:
    """A bootstrap interval of a score.

    Attributes
    ----------
    low, high : float
        The interval's ends.
    resamples : int
        Bootstrap resamples it was read from.
    block : int
        Frames per block.
    method : str
        How it was computed, for people.
    level : float
        Nominal coverage.
    """

    low: float
    high: float
    resamples: int
    block: int
    method: str
    level: float = 0.95

    def to_dict(self) -> dict[str, Any]:
        """Plain values for JSON output."""
        return {
            "low": self.low,
            "high": self.high,
            "level": self.level,
            "resamples": self.resamples,
            "block": self.block,
            "method": self.method,
        }


@dataclass(frozen=True)
class Difference:
    """Metric of method a minus metric of method b on the same frames, with its interval."""

    metric: str
    value: float
    interval: Interval

    def to_dict(self) -> dict[str, Any]:
        """Plain values for JSON output."""
        return {"metric": self.metric, "value": self.value, "interval": self.interval.to_dict()}


def score(y_true: ArrayLike, y_pred: ArrayLike) -> Scores:
    """All scores of predictions ``y_pred`` against labels ``y_true`` (0, 1, 2 each).

    Examples
    --------
    >>> s = score([1, 1, 1], [1, 0, 1])
    >>> s.balanced_accuracy is None, s.undefined
    (True, "all 3 test labels are 'straight'")
    >>> s.per_class
    {'left': None, 'straight': 0.6666666666666666, 'right': None}
    """
    from sklearn.metrics import (
        accuracy_score,
        confusion_matrix,
        f1_score,
        recall_score,
    )

    truth, pred = _check_pair(y_true, y_pred)
    if truth.size == 0:
        raise InputError("y_true", "no test frames to score")
    undefined = undefined_reason(truth)
    recall = recall_score(truth, pred, labels=_LABELS, average=None, zero_division=np.nan)
    present = np.bincount(truth, minlength=N_CLASSES) > 0
    return Scores(
        n=int(truth.size),
        accuracy=float(accuracy_score(truth, pred)),
        balanced_accuracy=None if undefined else _sklearn_balanced_accuracy(truth, pred),
        macro_f1=float(f1_score(truth, pred, average="macro", zero_division=0)),
        per_class={
            name: float(recall[i]) if present[i] else None for i, name in enumerate(DIRECTIONS)
        },
        confusion=tuple(map(tuple, confusion_matrix(truth, pred, labels=_LABELS).tolist())),
        undefined=undefined,
    )


def _sklearn_balanced_accuracy(truth: NDArray[np.int64], pred: NDArray[np.int64]) -> float:
    """sklearn's balanced accuracy, quiet about predicted classes absent from the labels."""
    from sklearn.metrics import balanced_accuracy_score

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "y_pred contains classes not in y_true")
        return float(balanced_accuracy_score(truth, pred))


def undefined_reason(y_true: NDArray[np.int64]) -> str | None:
    """Why balanced accuracy of labels ``y_true`` is undefined (one class only), else ``None``."""
    classes = np.unique(y_true)
    if classes.size != 1:
        return None
    return f"all {y_true.size} test labels are {DIRECTIONS[int(classes[0])]!r}"


def one_answer_share(y_true: ArrayLike, y_pred: ArrayLike) -> tuple[float, bool]:
    """The share of the most frequent answer in ``y_pred``, and whether ``y_true`` holds two
    classes or more with at least :data:`PRESENT_SHARE` of the frames each.

    A method *collapsed* on a test block when the share exceeds :data:`COLLAPSE_SHARE` on a
    block where the truth is mixed (:func:`collapsed`).

    Examples
    --------
    >>> one_answer_share([0, 1, 1, 2], [1, 1, 1, 1])
    (1.0, True)
    >>> one_answer_share([1] * 19 + [2], [1] * 20)
    (1.0, False)
    """
    truth, pred = _check_pair(y_true, y_pred)
    present = np.bincount(truth, minlength=len(DIRECTIONS)) / truth.size
    top = np.bincount(pred, minlength=len(DIRECTIONS)).max() / pred.size
    return float(top), int((present >= PRESENT_SHARE).sum()) >= 2


def collapsed(y_true: ArrayLike, y_pred: ArrayLike) -> bool:
    """One answer for more than :data:`COLLAPSE_SHARE` of a block whose truth is mixed."""
    top, mixed = one_answer_share(y_true, y_pred)
    return mixed and top > COLLAPSE_SHARE


def format_with_interval(value: float, interval: Interval, digits: int = 2) -> str:
    """``value [low, high]`` rounded to ``digits`` decimals, e.g. ``0.71 [0.66, 0.76]``."""
    return format_value(value, interval.to_dict(), digits)


def format_value(
    value: float | None, interval: Mapping[str, Any] | None, digits: int = 2
) -> str:
    """``value [low, high]`` from an interval's JSON form; the value alone without an
    interval, ``undefined`` for ``None`` (balanced accuracy of a one-class test set)."""
    if value is None:
        return "undefined"
    if not interval:
        return f"{value:.{digits}f}"
    return f"{value:.{digits}f} [{interval['low']:.{digits}f}, {interval['high']:.{digits}f}]"


def format_metric(result: Mapping[str, Any], metric: str, digits: int = 2) -> str:
    """``result[metric]`` with its ``result[metric + "_ci"]`` interval, as a table prints it
    (:func:`format_value`); ``—`` when ``result`` has no such metric.

    ``result`` is a result's JSON form (``MethodResult.to_dict()``, a ``score`` object).
    """
    if metric not in result:
        return "—"
    return format_value(result[metric], result.get(f"{metric}_ci"), digits)


def block_bootstrap(
    y_true: ArrayLike,
    y_pred: ArrayLike,
    metric: str = "balanced_accuracy",
    *,
    block: int | None = None,
    min_block: int = DEFAULT_MIN_BLOCK,
    resamples: int = 1000,
    seed: int = 0,
    level: float = 0.95,
) -> Interval:
    """Interval of ``metric`` over test frames in recording order, by circular block bootstrap.

    Parameters
    ----------
    y_true, y_pred : array_like of int, shape (N,) and (N,) or (K, N)
        Labels and predictions, frames in recording order (pooled contiguous folds);
        ``K`` rows are ``K`` runs (seeds) of one method: each resample averages the metric
        over the runs on the same resampled frames.
    metric : {"accuracy", "balanced_accuracy", "macro_f1"}
        The score.
    block : int, optional
        Frames per block; ``None`` chooses it with :func:`block_length`.
    min_block : int
        Shortest block allowed: the label smoothing span (11 frames for +-5 frames).
    resamples : int
        Bootstrap resamples.
    seed : int
        Seed of the resampling: the same inputs and seed give the same interval.
    level : float
        Nominal coverage, in (0, 1).

    Examples
    --------
    Bends of 15 frames, errors in runs of 5 frames:

    >>> rng = np.random.default_rng(0)
    >>> y = np.repeat(rng.integers(0, 3, 40), 15)
    >>> p = np.where(np.repeat(rng.random(120) < 0.75, 5), y, (y + 1) % 3)
    >>> iv = block_bootstrap(y, p, seed=1)
    >>> format_with_interval(score(y, p).balanced_accuracy, iv), iv.block
    ('0.70 [0.62, 0.78]', 25)
    """
    truth, pred = _check_runs(y_true, y_pred)
    return _bootstrap(truth, (pred,), metric, block, min_block, resamples, seed, level)[1]


def paired_difference(
    y_true: ArrayLike,
    pred_a: ArrayLike,
    pred_b: ArrayLike,
    metric: str = "balanced_accuracy",
    *,
    block: int | None = None,
    min_block: int = DEFAULT_MIN_BLOCK,
    resamples: int = 1000,
    seed: int = 0,
    level: float = 0.95,
) -> Difference:
    """``metric`` of ``pred_a`` minus that of ``pred_b``, with a paired block-bootstrap interval.

    Both methods are scored on the same resampled frames, so what they share (hard
    bends, easy straights) cancels. Parameters are those of :func:`block_bootstrap`; the
    automatic block length follows the per-frame difference of the two methods. Each
    prediction may be ``(K, N)``: ``K`` runs (seeds), the metric averaged over them.

    Examples
    --------
    ``p`` of :func:`block_bootstrap`'s example against ``q``, which says straight on 5
    frames in every 30: ``p`` is ahead, but not clearly.

    >>> rng = np.random.default_rng(0)
    >>> y = np.repeat(rng.integers(0, 3, 40), 15)
    >>> p = np.where(np.repeat(rng.random(120) < 0.75, 5), y, (y + 1) % 3)
    >>> q = np.where(np.arange(600) % 30 < 5, 1, p)
    >>> d = paired_difference(y, p, q, "accuracy")
    >>> format_with_interval(d.value, d.interval)
    '0.04 [-0.01, 0.10]'
    """
    truth, a = _check_runs(y_true, pred_a, "pred_a")
    _, b = _check_runs(y_true, pred_b, "pred_b")
    value, interval = _bootstrap(truth, (a, b), metric, block, min_block, resamples, seed, level)
    return Difference(metric, value, interval)


def _bootstrap(
    truth: NDArray[np.int64],
    preds: tuple[NDArray[np.int64], ...],
    metric: str,
    block: int | None,
    min_block: int,
    resamples: int,
    seed: int,
    level: float,
) -> tuple[float, Interval]:
    """Point value and interval of ``metric`` of ``preds[0]`` (minus that of ``preds[1]``)."""
    check_choice("metric", metric, METRICS)
    _check_defined(truth, metric)
    series = _first_minus_second([_run_mean(_influence, truth, p, metric) for p in preds])
    block = _resolve_block(block, min_block, truth.size, series)
    rng = np.random.default_rng(check_seed("seed", seed))
    resamples = check_int("resamples", resamples, 10, 10**6)
    idx = _resample_indices(rng, truth.size, block, resamples)
    point = float(
        _first_minus_second([_run_mean(_metric_values, truth, p, metric, None) for p in preds])[0]
    )
    values = _first_minus_second([_run_mean(_metric_values, truth, p, metric, idx) for p in preds])
    bounds = (0.0, 1.0) if len(preds) == 1 else (-1.0, 1.0)
    low, high = _widened_percentile(point, values, truth.size, block, level, bounds)
    return point, Interval(low, high, resamples, block, METHOD, level)


def _run_mean(
    f: Any, truth: NDArray[np.int64], runs: NDArray[np.int64], *args: Any
) -> NDArray[np.float64]:
    """``f(truth, run, *args)`` averaged over the runs (rows) of ``runs`` ``(K, N)``."""
    return np.mean([f(truth, run, *args) for run in runs], axis=0)


def _first_minus_second(arrays: list[NDArray[np.float64]]) -> NDArray[np.float64]:
    """``arrays[0]``, or ``arrays[0] - arrays[1]`` for a pair."""
    return arrays[0] - arrays[1] if len(arrays) == 2 else arrays[0]


def block_length(
    y_true: ArrayLike,
    y_pred: ArrayLike,
    metric: str = "balanced_accuracy",
    *,
    min_block: int = DEFAULT_MIN_BLOCK,
) -> int:
    """The automatic block length of :func:`block_bootstrap`.

    ``BLOCK_FACTOR`` (2) times :func:`politis_white_block` of the metric's per-frame
    contribution (correct or not, for balanced accuracy weighted by class), at least
    ``min_block`` and at most a third of the frames.
    """
    truth, pred = _check_pair(y_true, y_pred)
    check_choice("metric", metric, METRICS)
    return _resolve_block(None, min_block, truth.size, _influence(truth, pred, metric))


def politis_white_block(series: ArrayLike) -> float:
    """MSE-optimal circular-block length of a series' mean (Politis & White 2004).

    With the correction of Patton, Politis & White (2009): autocovariances up to the
    lag ``m`` after which ``K = 5`` autocorrelations in a row are below
    ``2 sqrt(log10 n / n)`` (their ``K = max(5, sqrt(log10 n))`` is 5 below 1e25 frames),
    weighted by a flat-top window over ``2 m`` lags. A constant or very short series gives 1.
    """
    x = np.asarray(series, dtype=np.float64)
    n = x.size
    if n < 3:
        return 1.0
    eps = x - x.mean()
    max_lag = min(n - 1, math.ceil(math.sqrt(n)) + _PW_RUN)
    acv = np.array([eps[k:] @ eps[: n - k] for k in range(max_lag + 1)]) / n
    if acv[0] <= 1e-12 * max(1.0, float(np.mean(x**2))):
        return 1.0
    lags = 2 * _last_correlated_lag(acv[1:] / acv[0], n)
    lags = max(1, min(lags, max_lag))
    k = np.arange(1, lags + 1)
    window = np.where(k / lags <= 0.5, 1.0, 2.0 * (1.0 - k / lags))
    g = 2.0 * np.sum(window * k * acv[k])
    long_run = acv[0] + 2.0 * np.sum(window * acv[k])
    if long_run <= 0:
        return 1.0
    return float((2.0 * g**2 / (4.0 / 3.0 * long_run**2)) ** (1 / 3) * n ** (1 / 3))


def _last_correlated_lag(acf: NDArray[np.float64], n: int) -> int:
    """Smallest ``m >= 1`` with ``|acf|`` below the threshold at lags ``m + 1 .. m + K``."""
    small = np.abs(acf) < 2.0 * math.sqrt(math.log10(n) / n)
    for m in range(1, acf.size - _PW_RUN + 1):
        if small[m : m + _PW_RUN].all():  # acf[j] is lag j + 1
            return m
    return acf.size


def _check_pair(
    y_true: ArrayLike, y_pred: ArrayLike, pred_name: str = "y_pred"
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    truth = _labels("y_true", y_true, int(np.size(y_true)))
    return truth, _labels(pred_name, y_pred, truth.size)


def _check_runs(
    y_true: ArrayLike, y_pred: ArrayLike, pred_name: str = "y_pred"
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Labels ``(N,)`` and predictions as runs ``(K, N)`` (one row for ``(N,)``)."""
    truth = _labels("y_true", y_true, int(np.size(y_true)))
    pred = np.asarray(y_pred)
    if pred.ndim == 2 and pred.shape[0] >= 1:
        return truth, np.stack([_labels(pred_name, row, truth.size) for row in pred])
    return truth, _labels(pred_name, pred, truth.size)[None, :]


def _labels(name: str, values: ArrayLike, n: int) -> NDArray[np.int64]:
    """:func:`check_direction_labels` with errors that name ``name``."""
    try:
        return check_direction_labels(values, n)
    except ParameterError as err:
        allowed = str(err).split(" is invalid: ", 1)[-1]
        raise ParameterError(name, err.value, allowed) from None


def _check_defined(truth: NDArray[np.int64], metric: str) -> None:
    reason = undefined_reason(truth) if metric == "balanced_accuracy" else None
    if reason:
        raise InputError("y_true", f"balanced accuracy is undefined: {reason}")


def _resolve_block(block: int | None, min_block: int, n: int, series: NDArray[np.float64]) -> int:
    """The given block, or the automatic one, checked against ``min_block`` and ``n``."""
    min_block = check_int("min_block", min_block, 1)
    if n < 2 * min_block:
        raise InputError(
            "y_true",
            f"{n} test frames are too few for blocks of {min_block} frames (need "
            f"{2 * min_block}: two blocks at least)",
        )
    if block is not None:
        return check_int("block", block, min_block, n // 2)
    automatic = math.ceil(BLOCK_FACTOR * politis_white_block(series))
    return max(min_block, min(automatic, n // 3))


def _influence(
    truth: NDArray[np.int64], pred: NDArray[np.int64], metric: str
) -> NDArray[np.float64]:
    """Each frame's first-order contribution to ``metric`` (what the blocks must keep together).

    Accuracy: correct or not. Balanced accuracy (and macro-F1, approximately): correct
    or not minus the class's recall, over the class's frequency.
    """
    correct = (truth == pred).astype(np.float64)
    if metric == "accuracy":
        return correct
    counts = np.bincount(truth, minlength=N_CLASSES).astype(np.float64)
    hits = np.bincount(truth, weights=correct, minlength=N_CLASSES)
    recall = np.divide(hits, counts, out=np.zeros(N_CLASSES), where=counts > 0)
    return (correct - recall[truth]) * truth.size / counts[truth]


def _resample_indices(
    rng: np.random.Generator, n: int, block: int, resamples: int
) -> NDArray[np.intp]:
    """Frame indices ``(resamples, n)``: random circular blocks concatenated, cut to ``n``."""
    per_row = -(-n // block)
    starts = rng.integers(0, n, size=(resamples, per_row, 1))
    idx = (starts + np.arange(block)) % n
    return idx.reshape(resamples, per_row * block)[:, :n]


def _metric_values(
    truth: NDArray[np.int64],
    pred: NDArray[np.int64],
    metric: str,
    idx: NDArray[np.intp] | None,
) -> NDArray[np.float64]:
    """``metric`` of each resample row of ``idx`` (or of all frames once, for ``None``)."""
    if idx is None:
        idx = np.arange(truth.size)[None, :]
    if metric == "accuracy":
        return (truth == pred)[idx].mean(axis=1)
    codes = truth * N_CLASSES + pred
    rows = np.arange(idx.shape[0])[:, None] * N_CLASSES**2
    cells = np.bincount((codes[idx] + rows).ravel(), minlength=idx.shape[0] * N_CLASSES**2)
    confusion = cells.reshape(idx.shape[0], N_CLASSES, N_CLASSES).astype(np.float64)
    if metric == "balanced_accuracy":
        return _balanced_accuracy(confusion)
    return _macro_f1(confusion)


def _balanced_accuracy(confusion: NDArray[np.float64]) -> NDArray[np.float64]:
    """Mean recall over the classes present in each row's labels, from confusions (R, 3, 3)."""
    support = confusion.sum(axis=2)
    hits = np.diagonal(confusion, axis1=1, axis2=2)
    recall = np.divide(hits, support, out=np.zeros_like(hits), where=support > 0)
    return recall.sum(axis=1) / np.count_nonzero(support, axis=1)


def _macro_f1(confusion: NDArray[np.float64]) -> NDArray[np.float64]:
    """Mean F1 over the classes in each row's labels or predictions (sklearn's macro-F1)."""
    hits = np.diagonal(confusion, axis1=1, axis2=2)
    seen = confusion.sum(axis=2) + confusion.sum(axis=1)
    f1 = np.divide(2 * hits, seen, out=np.zeros_like(hits), where=seen > 0)
    return f1.sum(axis=1) / np.count_nonzero(seen, axis=1)


def _widened_percentile(
    point: float,
    values: NDArray[np.float64],
    n: int,
    block: int,
    level: float,
    bounds: tuple[float, float],
) -> tuple[float, float]:
    """Percentile interval of ``values`` with their spread about ``point`` widened.

    Two small-sample corrections: the circular block bootstrap's variance of a mean is
    low by the factor ``1 - b/n``, and it rests on only ``n / b`` blocks, so the spread
    is scaled by ``sqrt(n / (n - b)) * t(n/b - 1) / z`` at the interval's quantile.
    """
    from scipy.special import ndtri, stdtrit

    if not (isinstance(level, float | int) and 0 < level < 1):
        raise ParameterError("level", level, "a coverage in (0, 1), e.g. 0.95")
    upper = 0.5 + level / 2
    widen = math.sqrt(n / (n - block)) * float(stdtrit(n / block - 1, upper) / ndtri(upper))
    spread = point + widen * (values - point)
    low, high = np.quantile(spread, [1 - upper, upper])
    return float(max(bounds[0], low)), float(min(bounds[1], high))
