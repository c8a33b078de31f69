"""Direction accuracy against noise strength: the paper's Fig. 7 (Sec. II-D; NOTES 7).

The frames are split by the one protocol of :mod:`qdcnn.direction.protocol`: contiguous
folds (:class:`~qdcnn.direction.protocol.ContiguousKFold`, frames within ``gap`` of a test
block left out of training), so every frame is a test frame exactly once and no model sees
its neighbours. Per fold, each method's estimator comes from the method registry
(:mod:`qdcnn.direction.methods`), its hyperparameters chosen by the inner contiguous
search with the gap (:func:`~qdcnn.direction.protocol.fit_with_search`).

By default each fold's model is trained once **without noise** and its test frames are
then classified under every (channel, p): all folds' test circuits for one noise setting
are one batched density-matrix run through the estimator class's ``predict_many``
(:meth:`qdcnn.quantum.direction.UUDirectionClassifier.predict_many`,
:meth:`qdcnn.quantum.vqc.VQCClassifier.predict_many`). With ``train_under_noise`` every
fold is retrained under the very noise it is tested with, with the hyperparameters of the
noiseless choice: ``clone(estimator).set_params(train_noise=noise).fit(...)``.

Probabilities are exact (density matrix) unless ``shots`` is given; then they are estimated
from that many shots per circuit, from a generator seeded by ``seed`` and the noise setting,
so a run is reproducible. Accuracy is pooled over all test frames (frames without two lane
lines count, predicted as the training majority class); the majority baseline is
:func:`~qdcnn.direction.protocol.majority_baseline`.

The estimator protocol. Any registered method with ``quantum=True`` can be swept: its
estimator's ``predict`` takes ``noise=`` (a :class:`~qdcnn.quantum.noise.NoiseSpec`), and for
``train_under_noise`` it has a ``train_noise`` parameter. A class method ``predict_many(models,
X, noise=, shots=, rng=)`` batches the folds into one run; without it each fold's model is
called on its own (exact probabilities only). Lane methods read the lane features of their
grouping; frame methods read ``features["frames"]`` (the RGB frames, :data:`FRAMES`).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from sklearn.base import clone

from qdcnn._threads import single_thread
from qdcnn._validation import check_optional_shots, has_shape
from qdcnn.config import PipelineConfig
from qdcnn.direction.methods import DirectionMethod, TrainingOptions, get_method, method_names
from qdcnn.direction.protocol import (
    ContiguousKFold,
    cross_validate,
    fit_with_search,
    majority_baseline,
)
from qdcnn.errors import InputError, ParameterError
from qdcnn.experiments.noise._rng import point_rng
from qdcnn.experiments.noise.options import (
    DIRECTION_METHODS,
    PAPER_STRENGTHS,
    SHADOW_METHOD,
    check_grid,
)
from qdcnn.experiments.noise.results import SweepRow
from qdcnn.quantum.noise import PAPER_CHANNELS, NoiseSpec

__all__ = [
    "FRAMES",
    "SweepTarget",
    "direction_sweep",
    "fit_direction_model",
    "predict_folds",
    "sweep_targets",
]

#: Key of the RGB frames ``(N, H, W, 3)`` in the inputs of frame methods.
FRAMES = "frames"


@dataclass(frozen=True)
class SweepTarget:
    """One series of a direction sweep: a registered method and what it reads.

    Attributes
    ----------
    method : DirectionMethod
        The registered method.
    row_method : str
        ``method`` of its rows: the classifier kind for lane methods (``"uu"``), else the
        registered name.
    grouping : str or None
        Lane grouping (lane methods).
    """

    method: DirectionMethod
    row_method: str
    grouping: str | None

    @property
    def inputs(self) -> str:
        """Key of the inputs it reads: its grouping, or :data:`FRAMES`."""
        return self.grouping if self.grouping is not None else FRAMES

    @property
    def label(self) -> str:
        """Legend name of its rows (the registered name)."""
        return self.row_method if self.grouping is None else f"{self.grouping}-{self.row_method}"


def _target(method: DirectionMethod) -> SweepTarget:
    if method.inputs == "lanes":
        return SweepTarget(method, method.kind, method.grouping)
    return SweepTarget(method, method.name, None)


def _kind_method(kind: str, grouping: str) -> DirectionMethod:
    name = f"{grouping}-{kind}"
    if name not in method_names():
        raise ParameterError("grouping", grouping, f"a grouping with a registered {kind} method")
    return get_method(name)


def sweep_targets(methods: Sequence[str], groupings: Sequence[str]) -> list[SweepTarget]:
    """The series of ``methods``: each kind shorthand (``uu``, ``vqc``) on every grouping,
    each registered name on its own inputs; order kept, duplicates dropped.

    Examples
    --------
    >>> [t.label for t in sweep_targets(["uu", "kmeans-vqc"], ["image-split", "kmeans"])]
    ['image-split-uu', 'kmeans-uu', 'kmeans-vqc']
    """
    out: list[SweepTarget] = []
    for name in methods:
        if name == SHADOW_METHOD:
            raise ParameterError("methods", name, "'uu', 'vqc' or a registered quantum method")
        if name in DIRECTION_METHODS:
            found = [_target(_kind_method(name, g)) for g in groupings]
        elif name in method_names():
            found = [_target(get_method(name))]
        else:
            raise ParameterError("methods", name, "'uu', 'vqc' or a registered quantum method")
        for t in found:
            if not t.method.quantum:
                raise ParameterError("methods", name, "a quantum method (it has no circuit)")
            if t not in out:
                out.append(t)
    return out


def _noise_aware_build(
    target: SweepTarget,
    config: PipelineConfig,
    training: TrainingOptions | None,
    train_under_noise: bool,
) -> _Fresh:
    """The target's estimator and grid (as fresh clones for the folds), refused when the
    estimator cannot be evaluated (or trained) under noise."""
    estimator, grid = target.method.estimator(config, training)
    _check_noise_aware(target, estimator, train_under_noise)
    return _Fresh(estimator, grid)


def _check_noise_aware(target: SweepTarget, estimator: Any, train_under_noise: bool) -> None:
    """Refuse an estimator that cannot be evaluated (or trained) under noise."""
    if "noise" not in inspect.signature(estimator.predict).parameters:
        raise ParameterError(
            "methods", target.method.name, "a method whose estimator predicts with noise="
        )
    if train_under_noise and "train_noise" not in estimator.get_params():
        raise ParameterError(
            "train_under_noise",
            True,
            f"methods whose estimator has a train_noise parameter ({target.method.name} has none)",
        )


def fit_direction_model(
    method: str | DirectionMethod,
    X: ArrayLike,
    y: NDArray[np.int64],
    config: PipelineConfig,
    *,
    seed: int = 0,
    inner_folds: int = 3,
    gap: int = 0,
) -> Any:
    """The fitted estimator of ``method``, hyperparameters chosen by the inner contiguous CV.

    ``method`` is a registered name or a kind (``"uu"``, ``"vqc"``: the estimator does not
    depend on the grouping). The estimator and grid come from the registry with
    ``config.seed = seed``; :func:`~qdcnn.direction.protocol.fit_with_search` chooses and
    refits on all of ``X``.
    """
    if isinstance(method, DirectionMethod):
        m = method
    elif method in DIRECTION_METHODS:
        m = next(get_method(n) for n in method_names() if get_method(n).kind == method)
    else:
        m = get_method(method)
    estimator, grid = m.estimator(replace(config, seed=seed))
    fitted, _ = fit_with_search(estimator, grid, X, y, inner_folds=inner_folds, gap=gap)
    return fitted


def predict_folds(
    models: Sequence[tuple[NDArray[np.intp], Any]],
    X: ArrayLike,
    noise: NoiseSpec | None,
    *,
    shots: int | None = None,
    rng: int | np.random.Generator | None = None,
) -> NDArray[np.int64]:
    """Predictions of several fitted models, each on its own rows, under one noise setting.

    Models of one class with a ``predict_many`` class method are run through it (one
    batched circuit run); others are called one by one as ``predict(X[rows], noise=noise)``,
    which needs exact probabilities (``shots=None``).

    Returns
    -------
    ndarray of int64
        Predictions of all models' rows, concatenated in the order of ``models``.
    """
    if not models:
        return np.empty(0, dtype=np.int64)
    cls = type(models[0][1])
    many = getattr(cls, "predict_many", None)
    if many is not None and all(type(est) is cls for _, est in models):
        out: NDArray[np.int64] = many(models, X, noise=noise, shots=shots, rng=rng)
        return out
    if shots is not None:
        raise ParameterError(
            "shots",
            shots,
            f"{cls.__name__} models run on exact probabilities only; leave shots unset",
        )
    x = np.asarray(X)
    return np.concatenate(
        [np.asarray(est.predict(x[rows], noise=noise), dtype=np.int64) for rows, est in models]
    )


def direction_sweep(
    features: Mapping[str, ArrayLike],
    y: ArrayLike,
    *,
    methods: Sequence[str] = DIRECTION_METHODS,
    groupings: Sequence[str] | None = None,
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
    training: TrainingOptions | None = None,
    executor: Any = None,
) -> list[SweepRow]:
    """Direction accuracy of each method under each (channel, p).

    Parameters
    ----------
    features : mapping of str to array
        The inputs, one row per frame: lane features ``(N, F)`` per grouping name (NaN
        where a line is missing), and the frames ``(N, H, W, 3)`` under :data:`FRAMES` for
        frame methods.
    y : array_like of int, shape (N,)
        Direction labels.
    methods : sequence of str
        ``"uu"`` and ``"vqc"`` (on every grouping of ``groupings``) and registered quantum
        method names (module docstring).
    groupings : sequence of str, optional
        Groupings the kinds ``"uu"`` and ``"vqc"`` run on (default: every lane table of
        ``features``, in its order).
    channels, strengths : sequences
        The noise grid.
    config : PipelineConfig, optional
        Classifier settings (``direction`` and ``vqc`` sections).
    folds, gap, inner_folds : int
        The protocol (module docstring).
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
    training : TrainingOptions, optional
        Settings of frame methods (epochs, threads, context).
    executor : Executor, optional
        Where the folds and the (channel, p) points run
        (:class:`qdcnn.runtime.scheduler.Executor`); the rows are the same either way.

    Returns
    -------
    list of SweepRow
        Ordered by method (kinds expanded over the groupings), channel, then p.
    """
    cfg = replace(config or PipelineConfig(), seed=seed)
    check_grid(channels, strengths, readout)
    check_optional_shots(shots)
    data = _SweepData.of(features, y, methods, groupings, folds, gap)
    labels, truth, majority = data.labels, data.truth, data.majority
    grid_points = [(channel, float(p)) for channel in channels for p in strengths]
    rows: list[SweepRow] = []
    with single_thread():
        for target in data.targets:
            X = data.inputs[target.inputs]
            build = _noise_aware_build(target, cfg, training, train_under_noise)
            fitted = _fit_folds(build, X, data, gap, inner_folds, executor)
            point = _SweepPoint(
                target, X, labels, truth, majority, readout, shots, seed, train_under_noise
            )
            rows += _run_points(point, grid_points, fitted, executor, on_step)
    return rows


@dataclass(frozen=True)
class _SweepData:
    """What every method of a sweep shares: labels, targets and their inputs, outer folds."""

    labels: NDArray[np.int64]
    targets: list[SweepTarget]
    inputs: dict[str, NDArray[Any]]
    splits: list[tuple[NDArray[np.intp], NDArray[np.intp]]]
    truth: NDArray[np.int64]  # the test labels of the folds, concatenated
    majority: float

    @classmethod
    def of(
        cls,
        features: Mapping[str, ArrayLike],
        y: ArrayLike,
        methods: Sequence[str],
        groupings: Sequence[str] | None,
        folds: int,
        gap: int,
    ) -> _SweepData:
        labels = np.asarray(y, dtype=np.int64)
        if groupings is None:
            groupings = [g for g in features if g != FRAMES]
        targets = sweep_targets(methods, groupings)
        inputs = _target_inputs(features, targets, labels.size)
        splits = list(ContiguousKFold(folds, gap).split(labels))
        truth = np.concatenate([labels[test] for _, test in splits])
        return cls(labels, targets, inputs, splits, truth, majority_baseline(labels, splits))


def _fit_folds(
    build: _Fresh, X: NDArray[Any], data: _SweepData, gap: int, inner_folds: int, executor: Any
) -> list[tuple[NDArray[np.intp], NDArray[np.intp], Any]]:
    """``(train rows, test rows, fitted estimator)`` of every outer fold (noise-free)."""
    cv = cross_validate(
        build,
        X,
        data.labels,
        folds=len(data.splits),
        gap=gap,
        inner_folds=inner_folds,
        keep_estimators=True,
        executor=executor,
    )
    return [(tr, te, est) for (tr, te), est in zip(data.splits, cv.estimators, strict=True)]


def _target_inputs(
    features: Mapping[str, ArrayLike], targets: Sequence[SweepTarget], n_labels: int
) -> dict[str, NDArray[Any]]:
    """The arrays the targets read (by input name), each checked to have one row per label."""
    inputs = {}
    for t in targets:
        if t.inputs not in features:
            raise ParameterError("features", sorted(features), f"inputs '{t.inputs}' for {t.label}")
        inputs[t.inputs] = np.asarray(features[t.inputs])
    for key, X in inputs.items():
        if not has_shape(X, f"{n_labels},F,*"):
            raise InputError(
                f"features[{key}]", f"shape {X.shape} does not match {n_labels} labels"
            )
    return inputs


def _run_points(
    point: _SweepPoint,
    grid_points: list[tuple[str, float]],
    fitted: Sequence[tuple[NDArray[np.intp], NDArray[np.intp], Any]],
    executor: Any,
    on_step: Callable[[], None] | None,
) -> list[SweepRow]:
    """``point`` at every (channel, p) of the grid, here or on ``executor``, in grid order."""
    results: dict[tuple[str, float], SweepRow] = {}
    if executor is None:
        for task in grid_points:
            results[task] = point(task, fitted)
            if on_step:
                on_step()
    else:
        for task, row in executor.map_unordered(point, grid_points, fitted):
            if isinstance(row, SweepRow):
                results[task] = row
            else:
                raise ParameterError("noise point", task, f"one that runs ({row})")
            if on_step:
                on_step()
    return [results[task] for task in grid_points]


@dataclass(frozen=True)
class _Fresh:
    """A picklable ``build()`` for the folds: a fresh clone of one estimator and its grid."""

    estimator: Any
    grid: Mapping[str, Sequence[Any]]

    def __call__(self) -> tuple[Any, Mapping[str, Sequence[Any]]]:
        return clone(self.estimator), self.grid


@dataclass(frozen=True)
class _SweepPoint:
    """One (channel, p) point of one method: the folds' models under that noise."""

    target: SweepTarget
    X: NDArray[Any]
    labels: NDArray[np.int64]
    truth: NDArray[np.int64]
    majority: float
    readout: float
    shots: int | None
    seed: int
    train_under_noise: bool

    def __call__(
        self,
        task: tuple[str, float],
        fitted: Sequence[tuple[NDArray[np.intp], NDArray[np.intp], Any]],
    ) -> SweepRow:
        channel, p = task
        noise = NoiseSpec(channel, p, self.readout)
        models = [
            (
                test,
                clone(est).set_params(train_noise=noise).fit(self.X[train], self.labels[train])
                if self.train_under_noise
                else est,
            )
            for train, test, est in fitted
        ]
        t = self.target
        gen = point_rng(self.seed, t.row_method, t.grouping, channel, p)
        pred = predict_folds(models, self.X, noise, shots=self.shots, rng=gen)
        accuracy = float(np.mean(pred == self.truth))
        return SweepRow(
            t.row_method, t.grouping, channel, p, accuracy, int(self.truth.size), self.majority
        )
