"""Two classical, non-deep reference methods, so every accuracy table has a floor to beat.

Both are a multinomial logistic regression (``class_weight="balanced"``, features
standardised on the training rows) on a fixed description of each frame:

:class:`HOGLogisticClassifier` (``hog-logreg``, reads frames)
    A histogram of oriented gradients (:func:`skimage.feature.hog`) of the grey lower road
    band (rows ``band`` of the height), resized to ``size`` first so any frame size works:
    how much of the label one frame carries for a plain image classifier.
:class:`LinesLogisticClassifier` (``lines-logreg``, reads lane features)
    The fitted lines' geometry as the lane pipeline gives it (every column of the feature
    table: the two slopes, then any extras such as intercepts or the road centre), a
    missing line's values replaced by the training mean and flagged by a 0/1 column: what
    a classical classifier makes of the same inputs the quantum methods get.

The benchmarks computed both ad hoc (``benchmarks/direction_study.py``,
``benchmarks/lane_study.py``). Here they are estimators whose fitted state is a few
plain arrays (:attr:`LogisticReference.fitted_attributes`), so they are saved in the
data-only model format (:mod:`qdcnn.persistence`) and load back without pickle; their
predictions equal those of scikit-learn's ``StandardScaler`` + ``LogisticRegression``
pipeline they were fitted with.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.validation import check_is_fitted

from qdcnn._validation import check_direction_labels, check_float, check_int
from qdcnn.errors import InputError, ParameterError

__all__ = ["HOGLogisticClassifier", "LinesLogisticClassifier", "LogisticReference", "hog_rows"]

#: The inverse regularisation strengths the inner contiguous CV chooses from.
C_GRID: tuple[float, ...] = (0.01, 0.1, 1.0)
#: HOG rows remembered by :func:`hog_rows` (least recently used first out; 5 KiB each
#: at the default size, so about 50 MiB at most).
HOG_CACHE_SIZE = 10_000
_HOG_CACHE: dict[tuple[Any, ...], NDArray[np.float64]] = {}


class LogisticReference(ClassifierMixin, BaseEstimator):
    """Standardised multinomial logistic regression on the rows :meth:`features` makes.

    Subclasses define :meth:`features` (inputs -> a float table) and its parameters.

    Parameters
    ----------
    C : float
        Inverse L2 regularisation strength (the registry's grid: :data:`C_GRID`).
    max_iter : int
        Iterations of the solver.

    Attributes
    ----------
    fill_ : ndarray, shape (F,)
        Training mean of each feature column (0 where a column had no finite value);
        it replaces NaN.
    mean_, scale_ : ndarray, shape (F,)
        The standardisation (``StandardScaler``'s ``mean_`` and ``scale_``).
    coef_, intercept_ : ndarray
        The logistic regression's ``(K, F)`` weights and ``(K,)`` offsets (``K = 1`` when
        training saw two classes).
    classes_ : ndarray of int
        The classes seen in training (0 left, 1 straight, 2 right); training rows of one
        class give a classifier that always predicts it.
    """

    #: What a fitted classifier learned (saved in model files, :mod:`qdcnn.persistence`).
    fitted_attributes: tuple[str, ...] = (
        "fill_",
        "mean_",
        "scale_",
        "coef_",
        "intercept_",
        "classes_",
    )

    def __init__(self, C: float = 0.1, max_iter: int = 3000) -> None:
        self.C = C
        self.max_iter = max_iter

    def features(self, X: ArrayLike) -> NDArray[np.float64]:
        """The feature table ``(N, F)`` of the inputs ``X`` (NaN allowed)."""
        raise NotImplementedError

    def fit(self, X: ArrayLike, y: ArrayLike) -> LogisticReference:
        """Fit the standardisation and the logistic regression on ``features(X)``."""
        from sklearn.linear_model import LogisticRegression
        from sklearn.preprocessing import StandardScaler

        check_float("C", self.C, 0.0, open_lo=True)
        check_int("max_iter", self.max_iter, 1)
        table = self.features(X)
        labels = check_direction_labels(y, table.shape[0])
        if table.shape[0] == 0:
            raise InputError("X", "no samples to fit")
        with np.errstate(all="ignore"):
            fill = np.nanmean(np.where(np.isfinite(table), table, np.nan), axis=0)
        self.fill_ = np.where(np.isfinite(fill), fill, 0.0)
        scaler = StandardScaler().fit(self._filled(table))
        self.mean_, self.scale_ = scaler.mean_, scaler.scale_
        self.classes_ = np.unique(labels)
        if self.classes_.size == 1:  # a training block of one direction: always predict it
            self.coef_, self.intercept_ = np.zeros((1, table.shape[1])), np.zeros(1)
            return self
        model = LogisticRegression(C=self.C, class_weight="balanced", max_iter=self.max_iter)
        model.fit(self._standardised(table), labels)
        self.coef_, self.intercept_ = model.coef_, model.intercept_
        return self

    def _filled(self, table: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.where(np.isfinite(table), table, self.fill_)

    def _standardised(self, table: NDArray[np.float64]) -> NDArray[np.float64]:
        return (self._filled(table) - self.mean_) / self.scale_

    def _fitted_features(self, X: ArrayLike) -> NDArray[np.float64]:
        """:meth:`features` of ``X``, as many as in fit."""
        table = self.features(X)
        if table.shape[1] != self.coef_.shape[1]:
            raise ParameterError(
                "X", f"<{table.shape[1]} features>", f"{self.coef_.shape[1]} features, as in fit"
            )
        return table

    def decision_function(self, X: ArrayLike) -> NDArray[np.float64]:
        """``LogisticRegression.decision_function`` of the standardised features."""
        check_is_fitted(self, "coef_")
        table = self._fitted_features(X)
        scores = self._standardised(table) @ self.coef_.T + self.intercept_
        return np.asarray(scores[:, 0] if scores.shape[1] == 1 else scores, dtype=np.float64)

    def predict_proba(self, X: ArrayLike) -> NDArray[np.float64]:
        """Probabilities ``(N, 3)`` of left, straight, right (0 for classes not trained on)."""
        scores = self.decision_function(X)
        if self.classes_.size == 1:
            seen = np.ones((scores.shape[0], 1))
        elif scores.ndim == 1:  # two classes: the logistic of one score
            p1 = 1.0 / (1.0 + np.exp(-scores))
            seen = np.stack([1.0 - p1, p1], axis=1)
        else:
            z = np.exp(scores - scores.max(axis=1, keepdims=True))
            seen = z / z.sum(axis=1, keepdims=True)
        out = np.zeros((seen.shape[0], 3))
        out[:, self.classes_] = seen
        return out

    def predict(self, X: ArrayLike) -> NDArray[np.int64]:
        """Directions 0 (left), 1 (straight), 2 (right): ``LogisticRegression.predict``."""
        scores = self.decision_function(X)
        if self.classes_.size == 1:
            return np.full(scores.shape[0], self.classes_[0], dtype=np.int64)
        best = scores.argmax(axis=1) if scores.ndim == 2 else (scores > 0).astype(np.int64)
        return np.asarray(self.classes_[best], dtype=np.int64)


def hog_rows(
    frames: ArrayLike,
    band: tuple[float, float] = (0.375, 0.875),
    size: tuple[int, int] = (128, 40),
    orientations: int = 8,
    cell: int = 8,
) -> NDArray[np.float64]:
    """HOG of each frame's grey band ``band`` (fractions of the height), resized to ``size``.

    Parameters
    ----------
    frames : array_like, shape (N, H, W, 3) or (N, H, W)
        RGB or grey ``uint8`` frames.
    band : pair of float
        Top and bottom of the road band, as fractions of the height (the default is rows
        60-139 of a 160-row Udacity frame: the road ahead without the car's bonnet).
    size : pair of int
        ``(width, height)`` the band is resized to.
    orientations, cell : int
        HOG orientation bins and the cell size in pixels (one cell per block).

    Returns
    -------
    ndarray, shape (N, orientations * (width // cell) * (height // cell))
    """
    import cv2

    arr = _checked_frames(frames)
    h = arr.shape[1]
    top, bottom = int(band[0] * h), max(int(band[0] * h) + 1, int(np.ceil(band[1] * h)))
    rows = []
    for frame in arr:
        grey = cv2.cvtColor(frame, cv2.COLOR_RGB2GRAY) if frame.ndim == 3 else frame
        small = cv2.resize(grey[top:bottom], size, interpolation=cv2.INTER_AREA)
        rows.append(_band_hog(small, orientations, cell))
    width = orientations * (size[0] // cell) * (size[1] // cell)
    return np.asarray(rows, dtype=np.float64).reshape(len(rows), width)


def _band_hog(small: NDArray[np.uint8], orientations: int, cell: int) -> NDArray[np.float64]:
    """``skimage.feature.hog`` of one resized band, remembered by its pixels.

    The protocol computes the features of a frame once per inner fit (3 inner folds x
    the grid, then the refit, in each outer fold) and skimage's HOG is the slow step
    (milliseconds a frame), so the last :data:`HOG_CACHE_SIZE` results are kept under
    the band's exact bytes and settings: the same pixels give the same row.
    """
    from skimage.feature import hog

    key = (small.tobytes(), small.shape, orientations, cell)
    row = _HOG_CACHE.pop(key, None)
    if row is None:
        cells = (cell, cell)
        row = hog(small, orientations, pixels_per_cell=cells, cells_per_block=(1, 1))
    _HOG_CACHE[key] = row
    if len(_HOG_CACHE) > HOG_CACHE_SIZE:
        _HOG_CACHE.pop(next(iter(_HOG_CACHE)))
    return np.asarray(row, dtype=np.float64)


def _checked_frames(frames: ArrayLike) -> NDArray[np.uint8]:
    arr = np.asarray(frames)
    shape_ok = arr.ndim == 3 or (arr.ndim == 4 and arr.shape[3] == 3)
    if not shape_ok or min(arr.shape[1:3], default=0) < 1:
        raise ParameterError(
            "X", f"<array of shape {arr.shape}>", "frames (N, H, W, 3) or grey frames (N, H, W)"
        )
    if arr.dtype != np.uint8:
        raise ParameterError("X", f"<{arr.dtype} frames>", "uint8 pixels")
    return np.ascontiguousarray(arr)


class HOGLogisticClassifier(LogisticReference):
    """``hog-logreg``: logistic regression on the HOG of each frame's road band (:func:`hog_rows`).

    Parameters
    ----------
    C, max_iter
        As for :class:`LogisticReference`.
    band, size, orientations, cell
        As for :func:`hog_rows`.

    Examples
    --------
    >>> import numpy as np
    >>> frames = np.zeros((6, 32, 48, 3), np.uint8)
    >>> for i, x in enumerate([4, 4, 20, 20, 36, 36]):
    ...     frames[i, 16:, x : x + 8] = 255
    >>> clf = HOGLogisticClassifier(C=1.0).fit(frames, [0, 0, 1, 1, 2, 2])
    >>> clf.predict(frames).tolist()
    [0, 0, 1, 1, 2, 2]
    """

    def __init__(
        self,
        C: float = 0.1,
        max_iter: int = 3000,
        band: tuple[float, float] = (0.375, 0.875),
        size: tuple[int, int] = (128, 40),
        orientations: int = 8,
        cell: int = 8,
    ) -> None:
        super().__init__(C, max_iter)
        self.band = band
        self.size = size
        self.orientations = orientations
        self.cell = cell

    def features(self, X: ArrayLike) -> NDArray[np.float64]:
        for name, pair in (("band", self.band), ("size", self.size)):
            if not isinstance(pair, tuple | list) or len(pair) != 2:
                raise ParameterError(name, pair, "a pair of numbers")
        lo, hi = (check_float(f"band[{i}]", v, 0.0, 1.0) for i, v in enumerate(self.band))
        if hi <= lo:
            raise ParameterError("band", self.band, "(top, bottom) fractions with top < bottom")
        cell = check_int("cell", self.cell, 1, 256)
        width, height = (check_int("size", v, cell, 4096) for v in self.size)
        orientations = check_int("orientations", self.orientations, 1, 64)
        return hog_rows(X, (lo, hi), (width, height), orientations, cell)


class LinesLogisticClassifier(LogisticReference):
    """``lines-logreg``: logistic regression on the fitted lines' features and missing flags.

    Parameters: ``C`` and ``max_iter``, as for :class:`LogisticReference`.

    Examples
    --------
    >>> import numpy as np
    >>> X = [[-1.0, 1.0], [-1.1, 0.9], [0.0, 2.0], [0.1, 2.1], [-2.0, 0.0], [np.nan, 0.1]]
    >>> LinesLogisticClassifier(C=1.0).fit(X, [1, 1, 2, 2, 0, 0]).predict(X).tolist()
    [1, 1, 2, 2, 0, 0]
    """

    def __sklearn_tags__(self) -> Any:
        tags = super().__sklearn_tags__()
        tags.input_tags.allow_nan = True
        return tags

    def features(self, X: ArrayLike) -> NDArray[np.float64]:
        try:
            table = np.asarray(X, dtype=np.float64)
        except (TypeError, ValueError):
            raise ParameterError("X", f"<{type(X).__name__}>", "a numeric table (N, F)") from None
        if table.ndim != 2 or table.shape[1] < 1:
            raise ParameterError("X", f"<array of shape {table.shape}>", "a 2-D table (N, F)")
        missing = ~np.isfinite(table)
        return np.hstack([np.where(missing, np.nan, table), missing.astype(np.float64)])

    def _fitted_features(self, X: ArrayLike) -> NDArray[np.float64]:
        table = self.features(X)
        columns = self.coef_.shape[1] // 2
        if table.shape[1] != 2 * columns:
            raise ParameterError(
                "X", f"<{table.shape[1] // 2} columns>", f"{columns} columns, as in fit"
            )
        return table
