"""Accuracy and shadow BER against noise strength: the paper's Fig. 7 (Sec. II-D; NOTES 7).

Direction methods (:func:`direction_sweep`)
    Lane features are split into contiguous cross-validation folds (scikit-learn ``KFold``
    without shuffling; frames within ``gap`` of a test block are left out of training, as
    in :mod:`qdcnn.experiments.evaluate`), so every frame is a test frame exactly once and
    no model sees its neighbours. Per fold, each method's estimator comes from
    :func:`qdcnn.experiments.evaluate.make_classifier`, its hyperparameters chosen by an
    inner contiguous cross-validation on the training folds. By default each fold's model is
    trained once **without noise** and its test frames are then classified under every
    (channel, p): all folds' test circuits for one noise setting are one batched
    density-matrix run. With ``train_under_noise`` every fold is retrained under the very
    noise it is tested with (same hyperparameters as the noiseless choice): the VQC through
    its ``train_noise``; the UU-dagger rule by choosing centroid and margin on noisy
    training probabilities (:func:`fit_uu_under_noise`).

    Probabilities are exact (density matrix) unless ``shots`` is given; then they are
    estimated from that many shots per circuit, from a generator seeded by ``seed`` and the
    noise setting, so a run is reproducible. Accuracy is pooled over all test frames
    (frames without two lane lines count, predicted as the training majority class).

Shadow detection (:func:`shadow_sweep`)
    The block-wise UU-dagger detector's centroid is trained on training images with masks
    (:func:`qdcnn.vision.shadows.train_shadow_model`, threshold chosen among the paper's
    0.75 and 0.97 by training BER); test images are then detected under each (channel, p)
    and scored by the balanced error rate summed over the test set
    (:func:`qdcnn.vision.metrics.shadow_scores`). With ``train_under_noise`` the threshold
    is re-chosen on the training blocks' noisy scores.

Noise acts after every gate on every qubit the gate touches (:mod:`qdcnn.quantum.noise`),
which equals a Qiskit Aer ``NoiseModel`` with that error on those gates.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import uniform_filter
from sklearn.base import clone
from sklearn.model_selection import GridSearchCV

from qdcnn._threads import single_thread
from qdcnn.config import PipelineConfig, ShadowConfig
from qdcnn.data.labels import LEFT, RIGHT, STRAIGHT
from qdcnn.errors import InputError, ParameterError
from qdcnn.experiments.methods import build_uu, build_vqc
from qdcnn.experiments.protocol import ContiguousKFold, fit_with_search, majority_baseline
from qdcnn.quantum.circuits import uu_dagger_circuit
from qdcnn.quantum.direction import UUDirectionClassifier, check_features, rule
from qdcnn.quantum.execute import run_probabilities
from qdcnn.quantum.noise import PAPER_CHANNELS, NoiseSpec, check_channel, check_probability
from qdcnn.quantum.uu_dagger import fidelity, value_to_angle
from qdcnn.quantum.vqc import VQCClassifier, basis_probabilities, interpret_matrix
from qdcnn.vision.metrics import ConfusionCounts, ShadowScores, confusion_counts, shadow_scores
from qdcnn.vision.shadow_training import block_shadow_fraction, train_shadow_model
from qdcnn.vision.shadows import (
    ShadowModel,
    block_grid,
    block_means,
    detect_shadows_uu,
    feature_input,
)

#: Direction methods of the sweep (the classifier kinds of ``make_classifier``).
DIRECTION_METHODS: tuple[str, ...] = ("uu", "vqc")
SHADOW_METHOD = "uu-shadow"
METHODS: tuple[str, ...] = (*DIRECTION_METHODS, SHADOW_METHOD)
PHASE_DAMPING_FORMS: tuple[str, ...] = ("textbook", "paper")
#: The paper's shadow thresholds (one per dataset), the candidates of the threshold choice.
SHADOW_THRESHOLDS: tuple[float, ...] = (0.75, 0.97)
MAX_STRENGTHS = 1000
#: most one-qubit density matrices simulated at once in the noisy UU-dagger search
_MAX_UU_BATCH = 1_000_000
_RANGE_HELP = "START:STOP:STEP (e.g. 0:0.99:0.11) or a comma list (e.g. 0,0.1,0.5)"


# ---------------------------------------------------------------- options


def parse_strengths(text: str) -> tuple[float, ...]:
    """Noise strengths from ``START:STOP:STEP`` or a comma list, sorted, each in [0, 1].

    A range includes ``STOP`` when it lies on the grid (to 1e-9 of a step); values are
    rounded to 12 decimals so that ``0:0.99:0.11`` gives exactly 0, 0.11, ..., 0.99.

    Examples
    --------
    >>> parse_strengths("0:0.99:0.11")[:4], len(parse_strengths("0:0.99:0.11"))
    ((0.0, 0.11, 0.22, 0.33), 10)
    >>> parse_strengths("0.5, 0, 0.1")
    (0.0, 0.1, 0.5)
    """
    s = str(text).strip()
    if not s:
        raise ParameterError("p", text, _RANGE_HELP)
    if ":" in s:
        parts = s.split(":")
        if len(parts) != 3:
            raise ParameterError("p", text, _RANGE_HELP)
        try:
            start, stop, step = (float(v) for v in parts)
        except ValueError:
            raise ParameterError("p", text, _RANGE_HELP) from None
        if not all(math.isfinite(v) for v in (start, stop, step)) or step <= 0 or stop < start:
            raise ParameterError("p", text, f"{_RANGE_HELP}, with STEP > 0 and START <= STOP")
        count = math.floor((stop - start) / step + 1e-9) + 1
        if count > MAX_STRENGTHS:
            raise ParameterError("p", text, f"at most {MAX_STRENGTHS} strengths")
        values = [start + i * step for i in range(count)]
    else:
        try:
            values = [float(v) for v in s.split(",")]
        except ValueError:
            raise ParameterError("p", text, _RANGE_HELP) from None
    rounded = [round(v, 12) + 0.0 for v in values]  # + 0.0 turns -0.0 into 0.0
    for v in rounded:
        check_probability("p", v)
    return tuple(sorted(set(rounded)))


def check_phase_damping_form(form: str) -> str:
    """Return ``form`` if it is ``"textbook"`` or ``"paper"``, else raise."""
    if form not in PHASE_DAMPING_FORMS:
        raise ParameterError("phase_damping", form, "'textbook' or 'paper'")
    return form


def parse_channels(text: str | Sequence[str], phase_damping: str = "textbook") -> tuple[str, ...]:
    """Channel names from a comma list; ``all`` is the six of the paper's Fig. 7.

    ``phase_damping`` says which form the name ``phase-damping`` (and ``all``) means:
    ``"textbook"`` (Qiskit's ``phase_damping_error``) or ``"paper"`` (the printed
    operators, channel ``phase-damping-paper``). Duplicates are dropped, order kept.

    Examples
    --------
    >>> parse_channels("bit-flip,phase-damping", phase_damping="paper")
    ('bit-flip', 'phase-damping-paper')
    """
    check_phase_damping_form(phase_damping)
    items = text.split(",") if isinstance(text, str) else list(text)
    names = [t.strip() for t in items if t.strip()]
    if not names:
        raise ParameterError("channels", text, "'all' or a comma list of channel names")
    out: list[str] = []
    for name in names:
        expanded = PAPER_CHANNELS if name == "all" else (check_channel(name),)
        for ch in expanded:
            ch = "phase-damping-paper" if ch == "phase-damping" and phase_damping == "paper" else ch
            if ch not in out:
                out.append(ch)
    return tuple(out)


def phase_damping_form(channels: Sequence[str]) -> str | None:
    """Which phase damping the channels use: "textbook", "paper", "textbook+paper" or None."""
    forms = [
        f
        for f, ch in zip(PHASE_DAMPING_FORMS, ("phase-damping", "phase-damping-paper"), strict=True)
        if ch in channels
    ]
    return "+".join(forms) or None


def parse_methods(text: str | Sequence[str]) -> tuple[str, ...]:
    """Methods from a comma list of ``uu``, ``vqc`` and ``uu-shadow`` (``all``: all three)."""
    items = text.split(",") if isinstance(text, str) else list(text)
    names = [t.strip() for t in items if t.strip()]
    out: list[str] = []
    for name in names:
        for m in METHODS if name == "all" else (name,):
            if m not in METHODS:
                raise ParameterError("methods", name, "a comma list of uu, vqc, uu-shadow or all")
            if m not in out:
                out.append(m)
    if not out:
        raise ParameterError("methods", text, "a comma list of uu, vqc, uu-shadow or all")
    return tuple(out)


#: 0, 0.11, ..., 0.99: the strengths of the paper's Fig. 7.
PAPER_STRENGTHS: tuple[float, ...] = parse_strengths("0:0.99:0.11")


def _rng(seed: int, *parts: object) -> np.random.Generator:
    """A generator determined by the seed and a noise setting's name (order-independent)."""
    key = zlib.crc32("|".join(map(str, parts)).encode())
    return np.random.default_rng([int(seed), key])


# ---------------------------------------------------------------- results


def _finite_or_none(value: Any) -> Any:
    """NaN (an undefined shadow error rate) becomes ``None``, which JSON can carry."""
    return None if isinstance(value, float) and math.isnan(value) else value


@dataclass
class SweepRow:
    """One point of a sweep: a method under one channel at one strength.

    Attributes
    ----------
    method : str
        ``"uu"``, ``"vqc"`` or ``"uu-shadow"``.
    grouping : str or None
        Lane grouping of the features (direction methods).
    channel : str
        Noise channel.
    p : float
        Channel strength.
    accuracy : float
        Direction accuracy over the test frames; pixel accuracy for ``uu-shadow``.
    n_test : int
        Test frames (test images for ``uu-shadow``).
    majority_baseline : float or None
        Accuracy of always predicting the training folds' majority class.
    ber, shadow_error, nonshadow_error : float or None
        Shadow scores in percent (``uu-shadow`` only).
    threshold : float or None
        Fidelity threshold of the shadow detector (``uu-shadow`` only).
    """

    method: str
    grouping: str | None
    channel: str
    p: float
    accuracy: float
    n_test: int
    majority_baseline: float | None = None
    ber: float | None = None
    shadow_error: float | None = None
    nonshadow_error: float | None = None
    threshold: float | None = None

    @property
    def label(self) -> str:
        """Legend name: ``image-split-uu``, ``vqc`` or ``uu-shadow``."""
        return self.method if self.grouping is None else f"{self.grouping}-{self.method}"


@dataclass
class NoiseSweepResult:
    """All points of a sweep and what produced them.

    Attributes
    ----------
    dataset : str
        Name of the direction data (``None`` when only shadows were swept).
    rows : list of SweepRow
    channels, strengths : tuple
        The grid.
    trained_under_noise : bool
        Whether models were retrained under each noise setting.
    shots : int or None
        Shots per circuit; ``None`` for exact probabilities.
    readout : float
        Readout error added at every point.
    seed : int
    shadow_set : str or None
        Name of the shadow images (``uu-shadow`` rows).
    protocol : dict
        Folds, gap, inner folds, shadow train/test sizes.
    """

    dataset: str | None
    rows: list[SweepRow]
    channels: tuple[str, ...]
    strengths: tuple[float, ...]
    trained_under_noise: bool = False
    shots: int | None = None
    readout: float = 0.0
    seed: int = 0
    shadow_set: str | None = None
    protocol: dict[str, Any] = field(default_factory=dict)

    @property
    def phase_damping_form(self) -> str | None:
        return phase_damping_form(self.channels)

    @property
    def evaluation(self) -> str:
        """``"exact probabilities"`` or ``"N shots"``."""
        return "exact probabilities" if self.shots is None else f"{self.shots} shots"

    def to_dicts(self) -> list[dict[str, Any]]:
        """One JSON object per row, with the sweep's settings repeated in each."""
        out = []
        for row in self.rows:
            d = {
                k: _finite_or_none(v)
                for k, v in asdict(row).items()
                if v is not None or k == "grouping"
            }
            d.update(
                dataset=self.shadow_set if row.method == SHADOW_METHOD else self.dataset,
                trained_under_noise=self.trained_under_noise,
                phase_damping_form=self.phase_damping_form,
                shots=self.shots,
                readout=self.readout,
                seed=self.seed,
            )
            out.append(d)
        return out

    def labels(self, method: str | None = None) -> list[str]:
        """Legend names of the series, in order of first appearance."""
        seen: dict[str, None] = {}
        for r in self.rows:
            if method is None or r.method == method:
                seen.setdefault(r.label, None)
        return list(seen)

    def series(
        self, label: str, channel: str, key: str = "accuracy"
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(p, value)`` of one series under one channel, sorted by ``p``."""
        pts = sorted(
            (r.p, getattr(r, key)) for r in self.rows if r.label == label and r.channel == channel
        )
        return np.array([p for p, _ in pts]), np.array([v for _, v in pts], dtype=np.float64)


# ---------------------------------------------------------------- direction models


def _final_estimator(model: Any) -> Any:
    return model.best_estimator_ if isinstance(model, GridSearchCV) else model


def fit_direction_model(
    kind: str,
    X: NDArray[np.float64],
    y: NDArray[np.int64],
    config: PipelineConfig,
    *,
    seed: int = 0,
    inner_folds: int = 3,
    gap: int = 0,
) -> Any:
    """The fitted estimator of ``kind`` (``"uu"`` or ``"vqc"``), hyperparameters chosen by CV.

    As :func:`qdcnn.experiments.evaluate.evaluate_features` does for one fold: the estimator
    and grid of :func:`~qdcnn.experiments.evaluate.make_classifier`, an inner contiguous
    ``GridSearchCV`` when ``inner_folds >= 2``, refitted on all of ``X``.
    """
    from qdcnn.experiments.methods import TrainingOptions

    build = build_uu if kind == "uu" else build_vqc
    estimator, grid = build(replace(config, seed=seed), TrainingOptions())
    fitted, _ = fit_with_search(estimator, grid, X, y, inner_folds=inner_folds, gap=gap)
    return fitted


def fit_uu_under_noise(
    estimator: UUDirectionClassifier,
    X: NDArray[np.float64],
    y: NDArray[np.int64],
    noise: NoiseSpec,
) -> UUDirectionClassifier:
    """The UU-dagger rule with centroid and margin chosen on noisy training probabilities.

    The angle map is learned as in :meth:`UUDirectionClassifier.fit`. Then, as its grid
    search does on exact noiseless probabilities, every centroid of an ``n_centroids`` grid on
    ``[0, 2 pi)`` and margin of an ``n_margins`` grid on ``[0, 1]`` is scored by training
    accuracy, here with the probabilities of the circuits under ``noise`` (one batched
    density-matrix run); ties go to the middle of the widest optimal plateau. The result is a
    plain classifier with that centroid and margin fixed (no refinement step).
    """
    base = clone(estimator).set_params(noise=None).fit(X, y)
    feats = check_features(X, base.feature_columns)
    ok = np.all(np.isfinite(feats), axis=1)
    if not ok.any():
        return base
    theta = base.slope_angles(feats[ok])
    yk = np.asarray(y)[ok]
    n = theta.shape[0]
    c, m = int(base.n_centroids), int(base.n_margins)
    centroids = np.arange(c) * (2 * np.pi / c)
    margins = np.linspace(0.0, 1.0, m)
    per_run = max(1, _MAX_UU_BATCH // (2 * n))
    d_rows = []
    for start in range(0, c, per_run):
        cs = centroids[start : start + per_run]
        circuit = uu_dagger_circuit(np.repeat(cs, 2 * n), np.tile(theta.T.ravel(), cs.size))
        p0 = run_probabilities(circuit, noise=noise)[:, 0].reshape(cs.size, 2, n)
        d_rows.append(p0[:, 0] - p0[:, 1])
    d = np.concatenate(d_rows)  # (C, N)
    sign_ok = (np.where(d > 0, RIGHT, LEFT) == yk).astype(np.float64)
    straight_ok = np.broadcast_to((yk == STRAIGHT).astype(np.float64), d.shape)
    # margin j predicts straight exactly where margins[j] > |d|, i.e. where j >= k
    k = np.searchsorted(margins, np.abs(d), side="right")
    flat = (np.arange(c)[:, None] * (m + 1) + k).ravel()
    sc = np.bincount(flat, sign_ok.ravel(), c * (m + 1)).reshape(c, m + 1)
    st = np.bincount(flat, straight_ok.ravel(), c * (m + 1)).reshape(c, m + 1)
    correct = (sc.sum(axis=1, keepdims=True) - np.cumsum(sc, axis=1) + np.cumsum(st, axis=1))[:, :m]
    accuracy = correct / n
    smooth = uniform_filter(accuracy, size=(min(5, c), min(5, m)), mode=("wrap", "nearest"))
    best = accuracy >= accuracy.max() - 1e-12
    ic, im = divmod(int(np.argmax(np.where(best, smooth, -np.inf))), m)
    fixed = clone(estimator).set_params(
        centroid=float(centroids[ic]), straight_margin=float(margins[im]), train_margin=False
    )
    return fixed.fit(X, y)


def _fit_under_noise(
    kind: str, model: Any, X: NDArray[np.float64], y: NDArray[np.int64], noise: NoiseSpec
) -> Any:
    if isinstance(model, UUDirectionClassifier):
        return fit_uu_under_noise(model, X, y, noise)
    if isinstance(model, VQCClassifier):
        return clone(model).set_params(train_noise=noise).fit(X, y)
    raise ParameterError(
        f"{kind} estimator", type(model).__name__, "a UUDirectionClassifier or VQCClassifier"
    )


# ---------------------------------------------------------------- batched prediction


def predict_folds(
    models: Sequence[tuple[NDArray[np.intp], Any]],
    X: NDArray[np.float64],
    noise: NoiseSpec | None,
    *,
    shots: int | None = None,
    rng: int | np.random.Generator | None = None,
) -> NDArray[np.int64]:
    """Predictions of several fitted models, each on its own rows, in one batched run.

    Parameters
    ----------
    models : sequence of (rows, estimator)
        Fitted :class:`UUDirectionClassifier` or :class:`VQCClassifier` (all of one kind)
        and the row indices of ``X`` each one predicts.
    X : ndarray, shape (N, F)
        Features.
    noise : NoiseSpec or None
        Noise of the run.
    shots : int or None
        Shots per circuit; ``None`` for exact probabilities.
    rng : int, Generator or None
        Seed of the shots.

    Returns
    -------
    ndarray of int64
        Predictions of all models' rows, concatenated in the order of ``models``. With
        exact probabilities they equal each estimator's ``predict(X[rows], noise=noise)``.
    """
    ests = [est for _, est in models]
    if all(isinstance(e, UUDirectionClassifier) for e in ests):
        return _predict_uu(models, X, noise, shots, rng)
    if all(isinstance(e, VQCClassifier) for e in ests):
        return _predict_vqc(models, X, noise, shots, rng)
    # any other estimator: one call per model
    return np.concatenate(
        [np.asarray(est.predict(X[rows], noise=noise), dtype=np.int64) for rows, est in models]
    )


def _predict_uu(
    models: Sequence[tuple[NDArray[np.intp], Any]],
    X: NDArray[np.float64],
    noise: NoiseSpec | None,
    shots: int | None,
    rng: int | np.random.Generator | None,
) -> NDArray[np.int64]:
    parts, centroids, angles = [], [], []
    for rows, est in models:
        feats = check_features(X[rows], est.feature_columns, est.n_features_in_)
        ok = np.all(np.isfinite(feats), axis=1)
        theta = est.slope_angles(feats[ok])
        parts.append((est, ok))
        angles.append(theta.T.ravel())  # this fold's left slopes, then its right slopes
        centroids.append(np.full(theta.size, est.centroid_))
    tx = np.concatenate(angles)
    p0 = np.empty(0)
    if tx.size:
        circuit = uu_dagger_circuit(np.concatenate(centroids), tx)
        p0 = run_probabilities(circuit, shots=shots, noise=noise, rng=rng)[:, 0]
    out, start = [], 0
    for est, ok in parts:
        n = int(ok.sum())
        pred = np.full(ok.size, est.majority_class_, dtype=np.int64)
        pred[ok] = rule(p0[start : start + n], p0[start + n : start + 2 * n], est.margin_)
        out.append(pred)
        start += 2 * n
    return np.concatenate(out) if out else np.empty(0, dtype=np.int64)


def _predict_vqc(
    models: Sequence[tuple[NDArray[np.intp], Any]],
    X: NDArray[np.float64],
    noise: NoiseSpec | None,
    shots: int | None,
    rng: int | np.random.Generator | None,
) -> NDArray[np.int64]:
    reps = {(int(e.feature_map_reps), int(e.ansatz_reps)) for _, e in models}
    if len(reps) > 1:  # different circuits cannot share a batch
        return np.concatenate([_predict_vqc([m], X, noise, shots, rng) for m in models])
    parts, angles, weights = [], [], []
    for rows, est in models:
        a = est.scale_features(X[rows])
        ok = np.all(np.isfinite(a), axis=1)
        parts.append((est, ok))
        angles.append(a[ok])
        weights.append(np.broadcast_to(est.weights_, (int(ok.sum()), est.weights_.size)))
    a_all = np.concatenate(angles)
    basis = np.empty((0, 4))
    if a_all.shape[0]:
        fm, ar = reps.pop()
        basis = basis_probabilities(
            a_all,
            np.concatenate(weights),
            feature_map_reps=fm,
            ansatz_reps=ar,
            shots=shots,
            noise=noise,
            rng=rng,
        )
    out, start = [], 0
    for est, ok in parts:
        n = int(ok.sum())
        pred = np.full(ok.size, est.majority_class_, dtype=np.int64)
        classes = basis[start : start + n] @ interpret_matrix(est.interpret)
        pred[ok] = np.argmax(classes, axis=1)
        out.append(pred)
        start += n
    return np.concatenate(out) if out else np.empty(0, dtype=np.int64)


# ---------------------------------------------------------------- direction sweep


def _check_grid(channels: Sequence[str], strengths: Sequence[float]) -> None:
    if not channels:
        raise ParameterError("channels", list(channels), "at least one channel")
    if not strengths:
        raise ParameterError("p", list(strengths), "at least one strength")
    for ch in channels:
        check_channel(ch)
    for p in strengths:
        check_probability("p", p)


def direction_sweep(
    features: Mapping[str, NDArray[np.float64]],
    y: NDArray[np.int64],
    *,
    methods: Sequence[str] = DIRECTION_METHODS,
    channels: Sequence[str] = PAPER_CHANNELS,
    strengths: Sequence[float] = PAPER_STRENGTHS,
    config: PipelineConfig | None = None,
    folds: int = 5,
    gap: int = 5,
    inner_folds: int = 3,
    train_under_noise: bool = False,
    shots: int | None = None,
    readout: float = 0.0,
    seed: int = 0,
    on_step: Callable[[], None] | None = None,
) -> list[SweepRow]:
    """Direction accuracy of each method and grouping under each (channel, p).

    Parameters
    ----------
    features : mapping of grouping name to ndarray, shape (N, F)
        Lane features per frame (NaN where a line is missing), one table per grouping.
    y : ndarray of int, shape (N,)
        Direction labels.
    methods : sequence of {"uu", "vqc"}
        Classifier kinds.
    channels, strengths : sequences
        The noise grid.
    config : PipelineConfig, optional
        Classifier settings (``direction`` and ``vqc`` sections).
    folds, gap, inner_folds : int
        Contiguous cross-validation (module docstring).
    train_under_noise : bool
        Retrain every fold under each noise setting instead of once without noise.
    shots : int or None
        Shots per circuit at evaluation; ``None`` for exact probabilities.
    readout : float
        Readout error added at every point.
    seed : int
        Seed of the classifiers and of shot sampling.
    on_step : callable, optional
        Called after every (method, grouping, channel, p) point.

    Returns
    -------
    list of SweepRow
        Ordered by method, grouping, channel, then p.
    """
    cfg = config or PipelineConfig()
    _check_grid(channels, strengths)
    check_probability("readout", readout)
    for m in methods:
        if m not in DIRECTION_METHODS:
            raise ParameterError("methods", m, "'uu' or 'vqc'")
    y = np.asarray(y, dtype=np.int64)
    n = len(y)
    for g, X in features.items():
        if X.ndim != 2 or X.shape[0] != n:
            raise InputError(f"features[{g}]", f"shape {X.shape} does not match {n} labels")
    splits = list(ContiguousKFold(folds, gap).split(y))
    truth = np.concatenate([y[test] for _, test in splits])
    majority = majority_baseline(y, splits)
    rows: list[SweepRow] = []
    with single_thread():
        for method in methods:
            for grouping, X in features.items():
                fitted = [
                    (
                        train,
                        test,
                        fit_direction_model(
                            method,
                            X[train],
                            y[train],
                            cfg,
                            seed=seed,
                            inner_folds=inner_folds,
                            gap=gap,
                        ),
                    )
                    for train, test in splits
                ]
                for channel in channels:
                    for p in strengths:
                        noise = NoiseSpec(channel, float(p), readout)
                        models = [
                            (
                                test,
                                _fit_under_noise(method, est, X[train], y[train], noise)
                                if train_under_noise
                                else est,
                            )
                            for train, test, est in fitted
                        ]
                        gen = _rng(seed, method, grouping, channel, p)
                        pred = predict_folds(models, X, noise, shots=shots, rng=gen)
                        accuracy = float(np.mean(pred == truth))
                        rows.append(
                            SweepRow(
                                method,
                                grouping,
                                channel,
                                float(p),
                                accuracy,
                                int(truth.size),
                                majority,
                            )
                        )
                        if on_step:
                            on_step()
    return rows


# ---------------------------------------------------------------- shadow sweep


def synthetic_shadow_set(
    n: int = 24, *, preset: str = "track2", seed: int = 0
) -> tuple[list[NDArray[np.uint8]], list[NDArray[np.bool_]]]:
    """``n`` independent synthetic road scenes and their exact shadow masks."""
    from qdcnn.data.synthetic import generate_scenes

    if isinstance(n, bool) or not isinstance(n, int) or n < 2:
        raise ParameterError("shadow_frames", n, "an integer >= 2 (half train, half test)")
    scenes = generate_scenes(preset, n, seed=seed)
    return [s.image for s in scenes], [s.shadow_mask for s in scenes]


def split_train_test(n: int, train_fraction: float = 0.5) -> tuple[slice, slice]:
    """The first ``ceil(n * train_fraction)`` items train (at least 1, leaving at least 1 test)."""
    if not 0.0 < train_fraction < 1.0:
        raise ParameterError("train_fraction", train_fraction, "a number in (0, 1)")
    if n < 2:
        raise ParameterError("images", n, "at least 2 images with masks (train and test)")
    k = min(max(math.ceil(n * train_fraction), 1), n - 1)
    return slice(0, k), slice(k, n)


def _noisy_threshold(
    model: ShadowModel,
    images: Sequence[NDArray[np.uint8]],
    masks: Sequence[NDArray[np.bool_]],
    config: ShadowConfig,
    noise: NoiseSpec,
    thresholds: Sequence[float],
) -> float:
    """The candidate threshold with the lowest block-level training BER under ``noise``."""
    values, truth = [], []
    for image, mask in zip(images, masks, strict=True):
        geometry = block_grid(image.shape[:2], config.downsample, config.grid)
        feats = feature_input(image, model.feature)
        values.append(block_means(feats, geometry, config.downsample).ravel())
        truth.append(block_shadow_fraction(mask, config).ravel() >= 0.5)
    v, gt = np.concatenate(values), np.concatenate(truth)
    scores = fidelity(value_to_angle(model.centroid), value_to_angle(v), shots=None, noise=noise)
    bers = [shadow_scores(confusion_counts((scores >= t)[None], gt[None])).ber for t in thresholds]
    return float(thresholds[int(np.argmin(bers))])


def shadow_sweep(
    train_images: Sequence[NDArray[np.uint8]],
    train_masks: Sequence[NDArray[np.bool_]],
    test_images: Sequence[NDArray[np.uint8]],
    test_masks: Sequence[NDArray[np.bool_]],
    *,
    channels: Sequence[str] = PAPER_CHANNELS,
    strengths: Sequence[float] = PAPER_STRENGTHS,
    config: ShadowConfig | None = None,
    thresholds: Sequence[float] = SHADOW_THRESHOLDS,
    train_under_noise: bool = False,
    shots: int | None = None,
    readout: float = 0.0,
    seed: int = 0,
    on_step: Callable[[], None] | None = None,
) -> tuple[list[SweepRow], ShadowModel]:
    """Balanced error rate of UU-dagger shadow detection under each (channel, p).

    Parameters
    ----------
    train_images, train_masks : sequences
        RGB images and bool shadow masks the centroid (and threshold) is trained on.
    test_images, test_masks : sequences
        The images scored at every noise setting.
    channels, strengths : sequences
        The noise grid.
    config : ShadowConfig, optional
        Detector settings (its ``shots`` is replaced by ``shots``).
    thresholds : sequence of float
        Candidate fidelity thresholds (default: the paper's 0.75 and 0.97).
    train_under_noise : bool
        Re-choose the threshold on the training blocks' scores under each noise setting.
    shots : int or None
        Shots per block circuit; ``None`` for exact probabilities.
    readout : float
        Readout error added at every point.
    seed : int
        Seed of shot sampling.
    on_step : callable, optional
        Called after every (channel, p) point.

    Returns
    -------
    rows : list of SweepRow
        ``method="uu-shadow"``; ``ber``, ``shadow_error`` and ``nonshadow_error`` in percent,
        ``accuracy`` the share of correctly classified pixels.
    model : ShadowModel
        The noiseless model.
    """
    cfg = replace(config or ShadowConfig(), shots=shots)
    _check_grid(channels, strengths)
    check_probability("readout", readout)
    if not test_images or len(test_images) != len(test_masks):
        raise ParameterError(
            "test images/masks", f"{len(test_images)}/{len(test_masks)}", "equal, non-zero counts"
        )
    model = train_shadow_model(list(train_images), list(train_masks), cfg, tuple(thresholds))
    rows = []
    with single_thread():
        for channel in channels:
            for p in strengths:
                noise = NoiseSpec(channel, float(p), readout)
                used = model
                if train_under_noise:
                    t = _noisy_threshold(model, train_images, train_masks, cfg, noise, thresholds)
                    used = replace(model, threshold=t)
                gen = _rng(seed, SHADOW_METHOD, channel, p)
                scores, counts = _score_detections(used, test_images, test_masks, cfg, noise, gen)
                rows.append(
                    SweepRow(
                        SHADOW_METHOD,
                        None,
                        channel,
                        float(p),
                        (counts.tp + counts.tn) / counts.total,
                        len(test_images),
                        ber=scores.ber,
                        shadow_error=scores.shadow_error,
                        nonshadow_error=scores.nonshadow_error,
                        threshold=used.threshold,
                    )
                )
                if on_step:
                    on_step()
    return rows, model


def _score_detections(
    model: ShadowModel,
    images: Sequence[NDArray[np.uint8]],
    masks: Sequence[NDArray[np.bool_]],
    cfg: ShadowConfig,
    noise: NoiseSpec,
    rng: np.random.Generator,
) -> tuple[ShadowScores, ConfusionCounts]:
    """Detect shadows in every image under ``noise``; scores of the pixel counts summed."""
    counts = ConfusionCounts(0, 0, 0, 0)
    for i, (image, mask) in enumerate(zip(images, masks, strict=True)):
        det = detect_shadows_uu(image, cfg, model=model, noise=noise, rng=rng)
        counts = counts + confusion_counts(det.mask, mask, source=f"test image {i}")
    return shadow_scores(counts), counts
