"""The paper's UU-dagger direction rule on two lane slopes, as a scikit-learn classifier.

Paper Sec. II-B and III-A (NOTES 6): each of the two lane-line slopes of a frame is
compared with one centroid by a one-qubit UU-dagger circuit (:mod:`qdcnn.quantum.uu_dagger`),
giving ``P1`` (left line) and ``P2`` (right line), ``P_i = cos^2((theta_c - theta_i) / 2)``.
The decision, as printed::

    |P1 - P2| < straight_margin  ->  straight
    P1 > P2                      ->  right
    otherwise                    ->  left

Orientation. ``theta_c`` and ``theta_c + pi`` give ``P -> 1 - P``, hence the mirrored
rule (left and right swapped, straight unchanged). The centroid is therefore searched on
the whole circle ``[0, 2 pi)`` and the orientation is part of it; no separate swap flag is
needed. On road geometry (left slope < 0 < right slope on a straight road, both slopes
shifting positive in a left bend) with the default angle map, a centroid at the
straight-ahead angle ``pi/2`` makes ``P1 > P2`` mean *left*; the printed rule holds with the
antipodal centroid ``3 pi / 2``, where ``P_i = sin^2(arctan(s_i / scale) / 2)`` grows with
how far line ``i`` leans from vertical.

Angle maps (both slopes share one map, so the two circuits stay comparable):

``"arctan"`` (default)
    ``theta = pi/2 + arctan(s / scale)`` in ``(0, pi)``; ``scale`` is ``slope_scale`` or,
    when that is ``None``, the median ``|s|`` of the training slopes (both columns).
``"minmax"``
    ``theta = pi * clip((s - lo) / (hi - lo), 0, 1)``; ``lo`` and ``hi`` are the 1st and
    99th percentiles of the training slopes (both columns).
``"identity"``
    ``theta = s``: the slopes are used as angles as given.

Training (:meth:`UUDirectionClassifier.fit`): a grid search that maximises training
accuracy over ``n_centroids`` centroids on ``[0, 2 pi)`` and ``n_margins`` margins on
``[0, 1]``, on exact probabilities of all centroids x all slopes in one batched circuit run
(:func:`grid_search`), then (``refine=True``) on a 41 x 41 grid spanning one coarse step
either side of the chosen cell. Accuracy is piecewise constant, so ties are broken towards
the middle of the widest optimal plateau (highest accuracy averaged over a 5 x 5 grid
neighbourhood). The probabilities are noiseless unless ``train_noise`` is set; then the
same search runs on the density-matrix probabilities under that noise (training under
noise: ``clone(clf).set_params(train_noise=noise).fit(X, y)``).

Batched prediction (:meth:`UUDirectionClassifier.predict_many`): several fitted models,
each on its own rows (the folds of a cross-validation), in one circuit run.

Missing lines. A row with a non-finite value in either slope cannot be encoded; it is
predicted as the majority class of the training labels (ties: lowest class index), with
the training class frequencies as its probabilities. Such rows take no part in training
the centroid and margin but count in the class frequencies.

References
----------
.. [1] QDCNN paper, ``shared/paper/qdcnn-paper.tex``, Sec. II-B, III-A; NOTES 2 and 6.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import uniform_filter
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.validation import check_is_fitted

from qdcnn._validation import (
    check_bool,
    check_choice,
    check_direction_labels,
    check_feature_pairs,
    check_float,
    check_int,
    check_optional_shots,
    check_seed,
)
from qdcnn.classes import DIRECTIONS, LEFT, RIGHT, STRAIGHT
from qdcnn.config import DirectionConfig
from qdcnn.errors import InputError
from qdcnn.quantum._checks import check_fitted_models, check_noise, shared_noise
from qdcnn.quantum.circuits import uu_dagger_circuit
from qdcnn.quantum.execute import check_backend, run_probabilities
from qdcnn.quantum.noise import NoiseSpec
from qdcnn.quantum.sampling import sample_probabilities

_ANGLE_MAPS: tuple[str, ...] = ("arctan", "minmax", "identity")
N_CLASSES = len(DIRECTIONS)
_DEFAULTS = DirectionConfig()
#: Most one-qubit circuits simulated in one call of the grid search, with or without noise
#: (under noise a circuit is a 2 x 2 density matrix: about 0.3 GB of work arrays per call).
_MAX_SEARCH_BATCH = 1_000_000


# ---------------------------------------------------------------- shared helpers


def class_prior(y: NDArray[np.int64]) -> NDArray[np.float64]:
    """Training class frequencies over the three directions."""
    counts = np.bincount(y, minlength=N_CLASSES).astype(np.float64)
    return counts / max(counts.sum(), 1.0)


# ---------------------------------------------------------------- the rule


def rule(p1: ArrayLike, p2: ArrayLike, straight_margin: float) -> NDArray[np.int64]:
    """The paper's decision from the two circuits' probabilities (Sec. III-A).

    ``|P1 - P2| < straight_margin`` -> straight (1); ``P1 > P2`` -> right (2); else left (0).

    Examples
    --------
    >>> rule([0.9, 0.2, 0.5], [0.2, 0.9, 0.45], 0.2).tolist()
    [2, 0, 1]
    """
    d = np.asarray(p1, dtype=np.float64) - np.asarray(p2, dtype=np.float64)
    out = np.where(d > 0, RIGHT, LEFT).astype(np.int64)
    out[np.abs(d) < straight_margin] = STRAIGHT
    return out


def soft_scores(d: ArrayLike, straight_margin: float, temperature: float) -> NDArray[np.float64]:
    """Soft 3-class scores from ``d = P1 - P2``: ``softmax([-d - m, 0, d - m] / T)``.

    The logits are each class's signed distance past its decision boundary, so the
    argmax reproduces :func:`rule` (except exactly on a boundary, where the rule says
    left/right and the argmax straight).
    """
    dd = np.asarray(d, dtype=np.float64)
    z = np.stack([-dd - straight_margin, np.zeros_like(dd), dd - straight_margin], axis=-1)
    z = z / temperature
    z -= z.max(axis=-1, keepdims=True)
    e = np.exp(z)
    out: NDArray[np.float64] = e / e.sum(axis=-1, keepdims=True)
    return out


def grid_search(
    theta1: NDArray[np.float64],
    theta2: NDArray[np.float64],
    y: NDArray[np.int64],
    centroids: NDArray[np.float64],
    margins: NDArray[np.float64],
    *,
    periodic: bool = True,
    noise: NoiseSpec | None = None,
) -> tuple[int, int, NDArray[np.float64]]:
    """Training accuracy of the rule for every centroid x margin, and the chosen cell.

    The probabilities of all centroids x all slopes come from batched exact UU-dagger
    circuit runs (one run unless it would exceed :data:`_MAX_SEARCH_BATCH` circuits),
    noiseless or under ``noise``. For each centroid the accuracy of every margin follows
    from one sort-free pass: sample ``i`` is predicted straight exactly for the margins
    ``> |d_i|``.

    Parameters
    ----------
    theta1, theta2 : ndarray, shape (N,)
        Angles of the left and right slopes.
    y : ndarray of int, shape (N,)
        Direction classes.
    centroids : ndarray, shape (C,)
        Candidate centroid angles.
    margins : ndarray, shape (M,)
        Candidate margins, ascending.
    periodic : bool
        Whether ``centroids`` cover the whole circle (the tie-break smoothing then wraps).
    noise : NoiseSpec or None
        Noise of the circuits (density-matrix probabilities); ``None`` for none.

    Returns
    -------
    ic, im : int
        Indices of the chosen centroid and margin.
    accuracy : ndarray, shape (C, M)
    """
    n, c, m = theta1.size, centroids.size, margins.size
    thetas = np.concatenate([theta1, theta2])
    noise = check_noise(noise)
    per_run = max(1, _MAX_SEARCH_BATCH // max(2 * n, 1))
    d_rows = []
    for start in range(0, c, per_run):
        cs = centroids[start : start + per_run]
        circuit = uu_dagger_circuit(np.repeat(cs, 2 * n), np.tile(thetas, cs.size))
        p0 = run_probabilities(circuit, noise=noise)[:, 0].reshape(cs.size, 2, n)
        d_rows.append(p0[:, 0] - p0[:, 1])
    d = np.concatenate(d_rows)  # (C, N)
    sign_class = np.where(d > 0, RIGHT, LEFT)
    sign_ok = (sign_class == y).astype(np.float64)
    straight_ok = np.broadcast_to((y == STRAIGHT).astype(np.float64), d.shape)
    # margins[j] <= |d_i| for j < k_i: not straight there; straight for j >= k_i
    k = np.searchsorted(margins, np.abs(d), side="right")  # (C, N) in [0, M]
    flat = (np.arange(c)[:, None] * (m + 1) + k).ravel()
    sc = np.bincount(flat, sign_ok.ravel(), c * (m + 1)).reshape(c, m + 1)
    st = np.bincount(flat, straight_ok.ravel(), c * (m + 1)).reshape(c, m + 1)
    correct = (sc.sum(axis=1, keepdims=True) - np.cumsum(sc, axis=1)) + np.cumsum(st, axis=1)
    accuracy = correct[:, :m] / max(n, 1)
    modes = ("wrap" if periodic else "nearest", "nearest")
    smooth = uniform_filter(accuracy, size=(min(5, c), min(5, m)), mode=modes)
    best = accuracy >= accuracy.max() - 1e-12
    flat_best = int(np.argmax(np.where(best, smooth, -np.inf)))
    ic, im = divmod(flat_best, m)
    return ic, im, accuracy


class UUDirectionClassifier(ClassifierMixin, BaseEstimator):
    """The paper's UU-dagger direction rule on ``[slope_left, slope_right]``.

    Classes are fixed: 0 left, 1 straight, 2 right (:mod:`qdcnn.data.labels`).

    Parameters
    ----------
    straight_margin : float
        The rule's straight band on ``|P1 - P2|`` (paper: 0.2); the starting value, or the
        value used when ``train_margin`` is False.
    centroid : float or None
        Centroid angle ``theta_c`` in radians; ``None`` trains it in :meth:`fit`.
    train_margin : bool
        Whether :meth:`fit` also chooses the margin (grid on ``[0, 1]``).
    shots : int or None
        Shots per circuit at prediction (paper: 1024); ``None`` for exact probabilities.
        Training always uses exact probabilities.
    backend : {"numpy", "aer"}
        Simulator used at prediction.
    noise : NoiseSpec or None
        Gate/readout noise at prediction (a per-call ``noise`` argument overrides it).
    train_noise : NoiseSpec or None
        Noise of the circuits whose exact probabilities training scores (``None``: none).
    seed : int
        Seed of the shot sampling; every prediction call re-seeds, so repeated calls agree.
    angle_map : {"arctan", "minmax", "identity"}
        How slopes become angles (module docstring).
    slope_scale : float or None
        Scale of the ``"arctan"`` map; ``None`` learns the median ``|slope|``.
    feature_columns : pair of int or None
        Two columns of a wider ``X`` to use; ``None`` requires exactly two columns.
    n_centroids, n_margins : int
        Grid sizes of the search (default: 1 degree steps, margin steps of 0.01).
    temperature : float
        Softness of :meth:`predict_proba` (see :func:`soft_scores`).
    refine : bool
        After the grid search, search a 41 x 41 grid spanning one coarse step either side
        of the chosen cell.

    Attributes
    ----------
    centroid_ : float
        The centroid used, in ``[0, 2 pi)`` when trained.
    margin_ : float
        The straight margin used.
    angle_params_ : tuple of float
        ``(scale,)`` for "arctan", ``(lo, hi)`` for "minmax", ``()`` for "identity".
    class_prior_ : ndarray, shape (3,)
        Training class frequencies (the probabilities given to rows with a missing slope).
    majority_class_ : int
        Prediction for rows with a missing slope.
    train_accuracy_ : float
        Exact-probability accuracy (under ``train_noise``) on the training rows with both
        slopes.
    accuracy_grid_ : ndarray, shape (n_centroids, n_margins) or None
        The coarse search's accuracy surface (``None`` when nothing was searched).
    classes_ : ndarray
        ``[0, 1, 2]``.
    n_features_in_ : int

    Examples
    --------
    >>> import numpy as np
    >>> X = np.array([[-1.0, 1.0], [0.0, 2.0], [-2.0, 0.0]])
    >>> clf = UUDirectionClassifier(centroid=3 * np.pi / 2, train_margin=False,
    ...                             slope_scale=1.0, shots=None).fit(X, [1, 0, 2])
    >>> clf.predict(X).tolist()
    [1, 0, 2]
    """

    #: What a fitted classifier learned (saved in model files, :mod:`qdcnn.persistence`).
    fitted_attributes: tuple[str, ...] = (
        "centroid_",
        "margin_",
        "angle_params_",
        "class_prior_",
        "majority_class_",
        "train_accuracy_",
        "accuracy_grid_",
        "classes_",
        "n_features_in_",
    )

    def __init__(
        self,
        straight_margin: float = _DEFAULTS.straight_margin,
        centroid: float | None = None,
        train_margin: bool = True,
        shots: int | None = _DEFAULTS.shots,
        backend: str = "numpy",
        noise: NoiseSpec | None = None,
        train_noise: NoiseSpec | None = None,
        seed: int = 0,
        angle_map: str = "arctan",
        slope_scale: float | None = None,
        feature_columns: tuple[int, int] | None = None,
        n_centroids: int = 360,
        n_margins: int = 101,
        temperature: float = 0.05,
        refine: bool = True,
    ) -> None:
        self.straight_margin = straight_margin
        self.centroid = centroid
        self.train_margin = train_margin
        self.shots = shots
        self.backend = backend
        self.noise = noise
        self.train_noise = train_noise
        self.seed = seed
        self.angle_map = angle_map
        self.slope_scale = slope_scale
        self.feature_columns = feature_columns
        self.n_centroids = n_centroids
        self.n_margins = n_margins
        self.temperature = temperature
        self.refine = refine

    def __sklearn_tags__(self) -> Any:
        tags = super().__sklearn_tags__()
        tags.input_tags.allow_nan = True
        return tags

    # ------------------------------------------------------------ parameters

    def _check_params(self) -> None:
        check_float("straight_margin", self.straight_margin, 0.0, 1.0)
        if self.centroid is not None:
            check_float("centroid", self.centroid, -1e6, 1e6)
        check_bool("train_margin", self.train_margin)
        check_bool("refine", self.refine)
        check_optional_shots(self.shots)
        check_backend(self.backend)
        check_noise(self.noise)
        check_noise(self.train_noise, "train_noise")
        check_choice("angle_map", self.angle_map, _ANGLE_MAPS)
        if self.slope_scale is not None:
            check_float("slope_scale", self.slope_scale, 0.0, open_lo=True)
        check_seed("seed", self.seed)
        check_int("n_centroids", self.n_centroids, 1)
        check_int("n_margins", self.n_margins, 1)
        check_float("temperature", self.temperature, 1e-6)

    # ------------------------------------------------------------ angles

    def _fit_angle_map(self, slopes: NDArray[np.float64]) -> tuple[float, ...]:
        finite = slopes[np.isfinite(slopes)]
        if self.angle_map == "arctan":
            if self.slope_scale is not None:
                return (float(self.slope_scale),)
            scale = float(np.median(np.abs(finite))) if finite.size else 1.0
            return (scale if scale > 0 else 1.0,)
        if self.angle_map == "minmax":
            lo, hi = np.percentile(finite, [1, 99]) if finite.size else (0.0, 1.0)
            return (float(lo), float(hi) if hi > lo else float(lo) + 1.0)
        return ()

    def slope_angles(self, slopes: ArrayLike) -> NDArray[np.float64]:
        """Angles of slopes under the fitted angle map (NaN stays NaN)."""
        check_is_fitted(self, "angle_params_")
        s = np.asarray(slopes, dtype=np.float64)
        if self.angle_map == "arctan":
            (scale,) = self.angle_params_
            return np.pi / 2 + np.arctan(s / scale)
        if self.angle_map == "minmax":
            lo, hi = self.angle_params_
            return np.pi * np.clip((s - lo) / (hi - lo), 0.0, 1.0)
        return s.copy()

    # ------------------------------------------------------------ fit

    def fit(self, X: ArrayLike, y: ArrayLike) -> UUDirectionClassifier:
        """Learn the angle map, then the centroid and margin that maximise training accuracy.

        Parameters
        ----------
        X : array_like, shape (N, 2)
            ``[slope_left, slope_right]`` per frame (NaN for a missing line).
        y : array_like of int, shape (N,)
            Direction classes 0 (left), 1 (straight), 2 (right).
        """
        self._check_params()
        feats = check_feature_pairs(X, self.feature_columns)
        labels = check_direction_labels(y, feats.shape[0])
        if feats.shape[0] == 0:
            raise InputError("X", "no samples to fit")
        self.n_features_in_ = int(np.asarray(X).shape[1])
        self.classes_ = np.arange(N_CLASSES)
        self.class_prior_ = class_prior(labels)
        self.majority_class_ = int(np.argmax(self.class_prior_))
        self.angle_params_ = self._fit_angle_map(feats)

        ok = np.all(np.isfinite(feats), axis=1)
        theta = self.slope_angles(feats[ok])
        yk = labels[ok]
        must_search = self.centroid is None or bool(self.train_margin)
        if must_search and not ok.any():
            raise InputError(
                "training data",
                "no frame has both lane lines (two finite slopes): nothing to train on",
            )
        self.accuracy_grid_: NDArray[np.float64] | None = None
        if must_search:
            self.centroid_, self.margin_, self.accuracy_grid_ = self._search(theta, yk)
        else:
            assert self.centroid is not None
            self.centroid_, self.margin_ = float(self.centroid), float(self.straight_margin)
        self.train_accuracy_ = float("nan")
        if ok.any():
            circuit = uu_dagger_circuit(self.centroid_, theta.T.ravel())
            p = run_probabilities(circuit, noise=self.train_noise)[:, 0]
            n = theta.shape[0]
            self.train_accuracy_ = float(np.mean(rule(p[:n], p[n:], self.margin_) == yk))
        return self

    def _search(
        self, theta: NDArray[np.float64], y: NDArray[np.int64]
    ) -> tuple[float, float, NDArray[np.float64]]:
        """Grid search (then the optional refinement) of centroid and/or margin."""
        trained_centroid = self.centroid is None
        cgrid = np.asarray(
            np.arange(self.n_centroids) * (2 * np.pi / self.n_centroids)
            if trained_centroid
            else [self.centroid],
            dtype=np.float64,
        )
        mgrid = np.asarray(
            np.linspace(0.0, 1.0, self.n_margins) if self.train_margin else [self.straight_margin],
            dtype=np.float64,
        )
        noise = self.train_noise
        ic, im, accuracy = grid_search(theta[:, 0], theta[:, 1], y, cgrid, mgrid, noise=noise)
        centroid, margin = float(cgrid[ic]), float(mgrid[im])
        if self.refine:
            # a 41 x 41 grid spanning one coarse step either side of the chosen cell
            cstep = 2 * np.pi / self.n_centroids if trained_centroid else 0.0
            mstep = 1.0 / max(self.n_margins - 1, 1) if self.train_margin else 0.0
            cfine = np.linspace(centroid - cstep, centroid + cstep, 41 if cstep else 1)
            mfine = np.unique(np.clip(np.linspace(margin - mstep, margin + mstep, 41), 0, 1))
            mfine = mfine if mstep else np.array([margin])
            ic, im, _ = grid_search(
                theta[:, 0], theta[:, 1], y, cfine, mfine, periodic=False, noise=noise
            )
            centroid = float(np.mod(cfine[ic], 2 * np.pi)) if cstep else centroid
            margin = float(mfine[im])
        return centroid, margin, accuracy

    # ------------------------------------------------------------ predict

    def circuit_probabilities(
        self, X: ArrayLike, noise: NoiseSpec | None = None
    ) -> NDArray[np.float64]:
        """``(P1, P2)`` per row, shape ``(N, 2)``: one UU-dagger circuit per slope.

        Rows with a missing slope give NaN. ``noise`` overrides the estimator's ``noise``
        (pass ``NoiseSpec()`` for an ideal run).
        """
        check_is_fitted(self, "centroid_")
        feats = check_feature_pairs(X, self.feature_columns, self.n_features_in_)
        noise = self.noise if noise is None else check_noise(noise)
        out = np.full(feats.shape, np.nan)
        ok = np.all(np.isfinite(feats), axis=1)
        if ok.any():
            theta = self.slope_angles(feats[ok])
            n = theta.shape[0]
            p0 = run_probabilities(
                uu_dagger_circuit(self.centroid_, theta.T.ravel()),  # all left, then all right
                shots=self.shots,
                noise=noise,
                backend=self.backend,
                rng=np.random.default_rng(self.seed),
            )[:, 0]
            out[ok] = np.stack([p0[:n], p0[n:]], axis=1)
        return out

    def circuit_probabilities_each(self, X: ArrayLike) -> NDArray[np.float64]:
        """:meth:`circuit_probabilities` of every row as if it were called with that row
        alone: one exact simulation of all the rows' circuits, then (with shots) each row's
        two circuits sampled from a generator seeded afresh with ``seed``, as a one-row
        call samples them. The NumPy simulator computes each circuit on its own, so the
        result equals the row-by-row calls; with another backend the rows are run one
        call each.
        """
        check_is_fitted(self, "centroid_")
        feats = check_feature_pairs(X, self.feature_columns, self.n_features_in_)
        if self.backend != "numpy":
            rows = [self.circuit_probabilities(feats[i : i + 1]) for i in range(len(feats))]
            return np.concatenate(rows) if rows else np.full(feats.shape, np.nan)
        out = np.full(feats.shape, np.nan)
        ok = np.all(np.isfinite(feats), axis=1)
        if ok.any():
            theta = self.slope_angles(feats[ok])
            n = theta.shape[0]
            circuit = uu_dagger_circuit(self.centroid_, theta.T.ravel())
            exact = run_probabilities(circuit, noise=self.noise)
            pairs = np.stack([exact[:n], exact[n:]], axis=1)  # (n, 2 circuits, outcomes)
            if self.shots is not None:
                pairs = self._sample_each(pairs, self.shots)
            out[ok] = pairs[:, :, 0]
        return out

    def _sample_each(self, pairs: NDArray[np.float64], shots: int) -> NDArray[np.float64]:
        """Shot estimates of each row's circuits, every row from the state a generator
        seeded with ``seed`` starts in (the state is put back per row: a tenth of the cost
        of seeding a new generator, and the same draws)."""
        gen = np.random.default_rng(self.seed)
        start = gen.bit_generator.state
        sampled = []
        for pair in pairs:
            gen.bit_generator.state = start
            sampled.append(sample_probabilities(pair, shots, gen))
        return np.stack(sampled)

    def predict_with_proba_each(
        self, X: ArrayLike
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """:meth:`predict_with_proba` of every row as if called with that row alone
        (:meth:`circuit_probabilities_each`), for a batch of frames decided in one call."""
        p = self.circuit_probabilities_each(X)
        d = p[:, 0] - p[:, 1]
        return self._labels(d), self._scores(d)

    def decision_function(
        self, X: ArrayLike, noise: NoiseSpec | None = None
    ) -> NDArray[np.float64]:
        """``d = P1 - P2`` per row (NaN for rows with a missing slope)."""
        p = self.circuit_probabilities(X, noise)
        out: NDArray[np.float64] = p[:, 0] - p[:, 1]
        return out

    def predict(self, X: ArrayLike, noise: NoiseSpec | None = None) -> NDArray[np.int64]:
        """Direction per row by the paper's rule; majority training class for missing slopes."""
        return self._labels(self.decision_function(X, noise))

    def predict_proba(self, X: ArrayLike, noise: NoiseSpec | None = None) -> NDArray[np.float64]:
        """Soft scores ``softmax([-d - m, 0, d - m] / temperature)`` with ``d = P1 - P2``.

        Columns are left, straight, right; the argmax agrees with :meth:`predict`. Rows with
        a missing slope get the training class frequencies.
        """
        return self._scores(self.decision_function(X, noise))

    def predict_with_proba(
        self, X: ArrayLike, noise: NoiseSpec | None = None
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """:meth:`predict` and :meth:`predict_proba` from one run of the circuits (a video
        frame needs both; with shots both calls sample the same seeded stream anyway)."""
        d = self.decision_function(X, noise)
        return self._labels(d), self._scores(d)

    def _labels(self, d: NDArray[np.float64]) -> NDArray[np.int64]:
        out = np.full(d.shape, self.majority_class_, dtype=np.int64)
        ok = np.isfinite(d)
        out[ok] = rule(d[ok], 0.0, self.margin_)
        return out

    def _scores(self, d: NDArray[np.float64]) -> NDArray[np.float64]:
        out = np.tile(self.class_prior_, (d.size, 1))
        ok = np.isfinite(d)
        out[ok] = soft_scores(d[ok], self.margin_, float(self.temperature))
        return out

    @classmethod
    def predict_many(
        cls,
        models: Sequence[tuple[ArrayLike, UUDirectionClassifier]],
        X: ArrayLike,
        *,
        noise: NoiseSpec | None = None,
        shots: int | None = None,
        rng: int | np.random.Generator | None = None,
        backend: str = "numpy",
    ) -> NDArray[np.int64]:
        """Predictions of several fitted classifiers, each on its own rows, in one circuit run.

        All models' UU-dagger circuits (each with its own centroid) are one batch, so a
        cross-validation's folds are classified under a noise setting in one simulation.

        Parameters
        ----------
        models : sequence of (rows, UUDirectionClassifier)
            Fitted classifiers and the row indices of ``X`` each one predicts.
        X : array_like, shape (N, F)
            Features.
        noise : NoiseSpec or None
            Noise of the run; ``None`` uses the models' own ``noise`` (the same for all).
        shots : int or None
            Shots per circuit; ``None`` (default) for exact probabilities. The models' own
            ``shots`` and ``seed`` are not used: one run has one setting.
        rng : int, Generator or None
            Seed or generator of the shots.
        backend : {"numpy", "aer"}
            Simulator of the run.

        Returns
        -------
        ndarray of int64
            All models' predictions, concatenated in the order of ``models``. With exact
            probabilities they equal each model's ``predict(X[rows], noise=noise)``.
        """
        pairs = check_fitted_models(cls, models)
        run_noise = shared_noise([est for _, est in pairs], noise)
        check_optional_shots(shots)
        x = np.asarray(X, dtype=np.float64)
        parts, centroids, angles = [], [], []
        for rows, est in pairs:
            feats = check_feature_pairs(x[rows], est.feature_columns, est.n_features_in_)
            ok = np.all(np.isfinite(feats), axis=1)
            theta = est.slope_angles(feats[ok])
            parts.append((est, ok))
            angles.append(theta.T.ravel())  # this model's left slopes, then its right slopes
            centroids.append(np.full(theta.size, est.centroid_))
        tx = np.concatenate(angles) if angles else np.empty(0)
        p0 = np.empty(0)
        if tx.size:
            circuit = uu_dagger_circuit(np.concatenate(centroids), tx)
            p0 = run_probabilities(circuit, shots=shots, noise=run_noise, backend=backend, rng=rng)[
                :, 0
            ]
        out, start = [], 0
        for est, ok in parts:
            n = int(ok.sum())
            pred = np.full(ok.size, est.majority_class_, dtype=np.int64)
            pred[ok] = rule(p0[start : start + n], p0[start + n : start + 2 * n], est.margin_)
            out.append(pred)
            start += 2 * n
        return np.concatenate(out) if out else np.empty(0, dtype=np.int64)
