"""The paper's two-qubit variational quantum classifier (VQC) as a scikit-learn classifier.

Paper Sec. II-C and Alg. 3 (NOTES 6): the two lane slopes enter a ZZ feature map
(Qiskit's ``zz_feature_map(2)``, two repetitions) followed by ``real_amplitudes(2, reps=1)``
(four trainable angles), trained with COBYLA (``maxiter=30``) on the mean squared error,
with a callback that records the objective at every evaluation.

Circuit and simulation. :func:`qdcnn.quantum.circuits.vqc_circuit` builds all samples'
circuits as one batch (for Aer, noise and export). Noise-free NumPy runs split the circuit
at the feature map: its states follow in closed form (:func:`feature_map_states`, two
Hadamard layers and diagonal phases per repetition) and the data-free ansatz is one 4x4
unitary (:func:`_ansatz_unitary`), so training computes the feature-map states once and
every objective evaluation is one ``(N, 4) x (4, 4)`` product; both are tested against
the gate-by-gate simulator, Aer and qiskit-machine-learning.

Classes from four basis states (``interpret``). The measured basis index ``k`` (qubit 0
the least significant bit, as in Qiskit) maps to a class; a class's probability is the
sum over its basis states:

``"min2"`` (default)
    ``min(k, 2)``: ``|00> -> left``, ``|01> -> straight``, ``|10> -> right``, ``|11> -> right``.
``"mod3"`` (qiskit-machine-learning's own default for three classes)
    ``k % 3``: as ``"min2"`` but ``|11> -> left``.
a tuple of four class indices
    any table in which every class appears at least once.

``"min2"`` is the default because it trained better on synthetic slope data (held-out
accuracy 0.69 against 0.58 for ``"mod3"``, mean of 48 fits: 6 data sets x 8 seeds, 30
COBYLA evaluations each); nothing in the paper fixes the map.

Losses (what is averaged). With one-hot labels ``y_i`` and class probabilities
``p_i`` (3-vectors):

``"mse"`` (the paper's Eq. 10)
    ``(1/N) sum_i sum_k (y_ik - p_ik)^2``: the squared Euclidean distance between label
    and probability vectors, averaged over the ``N`` samples. This equals
    qiskit-machine-learning's ``"squared_error"`` objective with one-hot targets.
``"cross_entropy"``
    ``-(1/N) sum_i log2(max(p_i,y_i, 1e-10))``, in bits with the clipping of
    qiskit-machine-learning's ``CrossEntropyLoss``.

Feature scaling (learned in :meth:`VQCClassifier.fit`, per feature, on the training rows
with both features finite):

``"minmax"`` (default)
    ``pi * clip((x - lo) / (hi - lo), 0, 1)`` with ``lo``, ``hi`` the 1st and 99th
    percentiles, so the data fill ``[0, pi]`` and outliers are clipped.
``"arctan"``
    ``pi/2 + arctan((x - median) / MAD)`` (MAD: median absolute deviation), in ``(0, pi)``.
``"none"``
    the features are used as angles.

``angle_span`` (default 1, not the paper's when below 1) shrinks the "minmax" and "arctan"
angles towards ``pi/2``: ``pi/2 + angle_span * (angle - pi/2)``, so 0.5 uses
``[pi/4, 3 pi/4]``. The ZZ feature map's entangling phase is ``2 (pi - x1)(pi - x2)``, up
to ``2 pi^2`` (about 20 rad) on ``[0, pi]``: the class probabilities then oscillate
several times across the data range, which four angles and 30 COBYLA steps rarely fit.
A narrower span gives a smoother map.

Initial weights are ``uniform(0, 2 pi)`` from ``numpy.random.default_rng(seed)``; with
``restarts=k > 1`` (not the paper's) training also runs from ``default_rng([seed, 2, r])``,
``r = 1 .. k-1``, and keeps the run of lowest final training objective (COBYLA on four
angles lands in different local minima from different starts).
Training uses ``train_noise`` and ``shots`` (``None``, the default, is exact); shot
estimates draw from ``default_rng(seed)``. Prediction uses ``noise`` (or a per-call
override) and the same ``shots``, re-seeded with ``default_rng([seed, 1])`` on every call.

Missing features. Rows with a non-finite feature are left out of training and are
predicted as the majority training class (ties: lowest index), with the training class
frequencies as probabilities.

References
----------
.. [1] QDCNN paper, ``shared/paper/qdcnn-paper.tex``, Sec. II-C, Alg. 3, Eq. 10; NOTES 6.
.. [2] V. Havlicek et al., "Supervised learning with quantum-enhanced feature spaces",
   Nature 567, 209-212 (2019).
.. [3] M. J. D. Powell, "A direct search optimization method that models the objective and
   constraint functions by linear interpolation", 1994 (COBYLA).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache
from itertools import groupby
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import minimize
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.validation import check_is_fitted

from qdcnn._optional import require
from qdcnn._validation import (
    check_direction_labels,
    check_feature_pairs,
    check_float,
    check_int,
    check_optional_shots,
    check_seed,
    check_shots,
)
from qdcnn.config import VQCConfig
from qdcnn.errors import InputError, ParameterError
from qdcnn.quantum._checks import check_fitted_models, check_noise, shared_noise
from qdcnn.quantum.circuits import CircuitBuilder, feature_pairs, real_amplitudes, vqc_circuit
from qdcnn.quantum.direction import N_CLASSES, class_prior
from qdcnn.quantum.execute import check_backend, run_probabilities
from qdcnn.quantum.noise import GateNoise, NoiseSpec
from qdcnn.quantum.sampling import sample_probabilities
from qdcnn.quantum.simulator import unitary

_INTERPRETS: dict[str, tuple[int, int, int, int]] = {
    "mod3": (0, 1, 2, 0),
    "min2": (0, 1, 2, 2),
}
_LOSSES: tuple[str, ...] = ("mse", "cross_entropy")
_SCALINGS: tuple[str, ...] = ("minmax", "arctan", "none")
_ENGINES: tuple[str, ...] = ("qdcnn", "qiskit-ml")
_DEFAULTS = VQCConfig()


def _interpret_table(interpret: str | Sequence[int]) -> tuple[int, ...]:
    """The basis-index -> class table of ``interpret`` (a name or four class indices)."""
    if isinstance(interpret, str):
        if interpret not in _INTERPRETS:
            raise ParameterError("interpret", interpret, "'min2', 'mod3' or 4 class indices")
        return _INTERPRETS[interpret]
    table = tuple(interpret)
    ok = len(table) == 4 and all(
        isinstance(c, int | np.integer) and not isinstance(c, bool) for c in table
    )
    if not ok or set(table) != {0, 1, 2}:
        raise ParameterError(
            "interpret", interpret, "4 class indices in which 0, 1 and 2 all appear"
        )
    return tuple(int(c) for c in table)


def interpret_matrix(interpret: str | Sequence[int]) -> NDArray[np.float64]:
    """``M[k, c] = 1`` when basis state ``k`` counts for class ``c``; shape ``(4, 3)``."""
    return np.eye(N_CLASSES)[list(_interpret_table(interpret))]


class Interpret:
    """``interpret`` as the callable qiskit-machine-learning expects (basis index -> class)."""

    def __init__(self, interpret: str | Sequence[int]) -> None:
        self.table = _interpret_table(interpret)

    def __call__(self, index: int) -> int:
        return self.table[int(index)]


def basis_probabilities(
    angles: ArrayLike,
    weights: ArrayLike,
    *,
    feature_map_reps: int = _DEFAULTS.feature_map_reps,
    ansatz_reps: int = _DEFAULTS.ansatz_reps,
    shots: int | None = None,
    noise: NoiseSpec | None = None,
    backend: str = "numpy",
    rng: int | np.random.Generator | None = None,
) -> NDArray[np.float64]:
    """Probabilities of the four basis states for every sample, in one batched run.

    Parameters
    ----------
    angles : array_like, shape (N, 2)
        Scaled features (the feature map's ``x``).
    weights : array_like, shape (2 (ansatz_reps + 1),)
        Ansatz angles in Qiskit's parameter order.

    Returns
    -------
    ndarray, shape (N, 4)
        Index = basis state, qubit 0 the least significant bit.
    """
    if _runs_split(backend, noise):
        if shots is not None:
            check_shots(shots)
        states = feature_map_states(angles, feature_map_reps)
        return _split_probabilities(states, weights, ansatz_reps, shots, rng)
    circuit = vqc_circuit(
        angles, weights, feature_map_reps=feature_map_reps, ansatz_reps=ansatz_reps
    )
    return run_probabilities(circuit, shots=shots, noise=noise, backend=backend, rng=rng)


def _runs_split(backend: str, noise: GateNoise | None) -> bool:
    """Whether the split simulation (feature-map states, ansatz unitary) applies."""
    return backend == "numpy" and (noise is None or noise.is_ideal)


def _split_probabilities(
    states: NDArray[np.complex128],
    weights: ArrayLike,
    ansatz_reps: int,
    shots: int | None,
    rng: int | np.random.Generator | None,
) -> NDArray[np.float64]:
    """Basis probabilities from feature-map states: exact, or estimated from ``shots``."""
    exact = ansatz_probabilities(states, weights, ansatz_reps)
    return exact if shots is None else sample_probabilities(exact, shots, rng)


_HADAMARD_2 = 0.5 * np.array([[1, 1, 1, 1], [1, -1, 1, -1], [1, 1, -1, -1], [1, -1, -1, 1]])
_BIT0 = np.array([0.0, 1.0, 0.0, 1.0])  # qubit 0 of basis index k (the least significant bit)
_BIT1 = np.array([0.0, 0.0, 1.0, 1.0])


def feature_map_states(angles: ArrayLike, reps: int = 2) -> NDArray[np.complex128]:
    """Statevectors ``(N, 4)`` after ``zz_feature_map(2, reps)`` from ``|00>``.

    Each repetition is ``H`` on both qubits, then gates that are all diagonal:
    ``P(2 x_0)`` on qubit 0, ``P(2 x_1)`` on qubit 1 and ``CX P(phi) CX`` with
    ``phi = 2 (pi - x_0)(pi - x_1)``, which gives the phase ``phi`` exactly when the
    two qubits differ. So basis state ``k = (b_1 b_0)`` gains the phase
    ``2 x_0 b_0 + 2 x_1 b_1 + phi (b_0 xor b_1)`` per repetition, with one 4x4
    Hadamard product in between (the same result as simulating the gates one by one).
    """
    x = feature_pairs(angles)
    reps = check_int("feature_map_reps", reps, 1)
    pair = 2.0 * (np.pi - x[:, :1]) * (np.pi - x[:, 1:])
    phase = np.exp(1j * (2.0 * x[:, :1] * _BIT0 + 2.0 * x[:, 1:] * _BIT1 + pair * (_BIT0 != _BIT1)))
    state = 0.5 * phase  # the first H layer takes |00> to the uniform superposition
    for _ in range(reps - 1):
        state = (state @ _HADAMARD_2) * phase
    return state


def _ansatz_unitary(weights: ArrayLike, reps: int = 1) -> NDArray[np.complex128]:
    """The unitary of ``real_amplitudes(2, reps)``: ``(1, 4, 4)``, or ``(N, 4, 4)`` for
    per-sample weights of shape ``(N, 2 (reps + 1))``."""
    w = np.asarray(weights, dtype=np.float64)
    reps = check_int("ansatz_reps", reps, 0)
    if w.ndim == 1:  # a trained model's weights: the same unitary for every prediction
        return _shared_ansatz_unitary(tuple(w.tolist()), reps)
    return _real_amplitudes_unitary(w, reps)


@lru_cache(maxsize=64)
def _shared_ansatz_unitary(weights: tuple[float, ...], reps: int) -> NDArray[np.complex128]:
    u = _real_amplitudes_unitary(np.array(weights), reps)
    u.setflags(write=False)
    return u


def _real_amplitudes_unitary(w: NDArray[np.float64], reps: int) -> NDArray[np.complex128]:
    builder = CircuitBuilder(2, w.shape[0] if w.ndim == 2 else 1)
    return unitary(real_amplitudes(builder, w, reps).build("ansatz"))


def ansatz_probabilities(
    states: NDArray[np.complex128], weights: ArrayLike, reps: int = 1
) -> NDArray[np.float64]:
    """Basis probabilities ``(N, 4)`` of ``states`` (feature-map outputs) after the ansatz."""
    u = _ansatz_unitary(weights, reps)
    final = states @ u[0].T if u.shape[0] == 1 else np.einsum("bij,bj->bi", u, states)
    probs = final.real**2 + final.imag**2
    out: NDArray[np.float64] = probs / probs.sum(axis=1, keepdims=True)
    return out


def class_probabilities(
    angles: ArrayLike,
    weights: ArrayLike,
    *,
    interpret: str | Sequence[int] = "min2",
    **kwargs: Any,
) -> NDArray[np.float64]:
    """Class probabilities ``(N, 3)``: :func:`basis_probabilities` summed through ``interpret``.

    Other keyword arguments go to :func:`basis_probabilities`.
    """
    out: NDArray[np.float64] = basis_probabilities(angles, weights, **kwargs) @ interpret_matrix(
        interpret
    )
    return out


def loss_value(probs: NDArray[np.float64], onehot: NDArray[np.float64], loss: str) -> float:
    """The training objective (see the module docstring) for class probabilities ``(N, 3)``."""
    n = max(probs.shape[0], 1)
    if loss == "mse":
        return float(np.sum((onehot - probs) ** 2) / n)
    if loss == "cross_entropy":
        return float(-np.sum(onehot * np.log2(np.clip(probs, 1e-10, None))) / n)
    raise ParameterError("loss", loss, "'mse' or 'cross_entropy'")


def make_sampler_qnn(
    interpret: str | Sequence[int] = "min2",
    *,
    feature_map_reps: int = _DEFAULTS.feature_map_reps,
    ansatz_reps: int = _DEFAULTS.ansatz_reps,
    shots: int | None = None,
    seed: int | None = None,
) -> Any:
    """qiskit-machine-learning's ``SamplerQNN`` for the same circuit and interpret map.

    The circuit is ``zz_feature_map(2, reps)`` composed with ``real_amplitudes(2, reps)``
    from ``qiskit.circuit.library``, ``output_shape=3``. The sampler is
    ``qiskit_machine_learning.primitives.QMLSampler(shots=shots)``: with ``shots=None`` it
    computes exact probabilities from ``qiskit.quantum_info.Statevector`` (no sampling).
    """
    require("qiskit_machine_learning", "the qiskit-machine-learning VQC engine")
    from qiskit import QuantumCircuit
    from qiskit.circuit.library import real_amplitudes, zz_feature_map
    from qiskit_machine_learning.neural_networks import SamplerQNN
    from qiskit_machine_learning.primitives import QMLSampler

    feature_map = zz_feature_map(2, reps=feature_map_reps)
    ansatz = real_amplitudes(2, reps=ansatz_reps)
    circuit = QuantumCircuit(2)
    circuit.compose(feature_map, inplace=True)
    circuit.compose(ansatz, inplace=True)
    sampler = QMLSampler() if shots is None else QMLSampler(shots=shots, seed=seed)
    return SamplerQNN(
        circuit=circuit,
        input_params=feature_map.parameters,
        weight_params=ansatz.parameters,
        interpret=Interpret(interpret),
        output_shape=N_CLASSES,
        sampler=sampler,
    )


class VQCClassifier(ClassifierMixin, BaseEstimator):
    """Two-qubit VQC (ZZ feature map + RealAmplitudes) on ``[slope_left, slope_right]``.

    Classes are fixed: 0 left, 1 straight, 2 right (:mod:`qdcnn.data.labels`).

    Parameters
    ----------
    feature_map_reps : int
        Repetitions of the ZZ feature map (Qiskit's default, 2).
    ansatz_reps : int
        Repetitions of RealAmplitudes; ``2 (reps + 1)`` weights (4 for the paper's 1).
    maxiter : int
        COBYLA's budget of objective evaluations (paper: 30).
    loss : {"mse", "cross_entropy"}
        Training objective (module docstring).
    interpret : {"min2", "mod3"} or tuple of 4 int
        Basis state -> class map (module docstring).
    scaling : {"minmax", "arctan", "none"}
        Feature -> angle map learned in :meth:`fit` (module docstring).
    angle_span : float
        Fraction in ``(0, 1]`` of the "minmax"/"arctan" angle range kept, centred on
        ``pi/2`` (module docstring); 1 keeps ``[0, pi]``.
    restarts : int
        COBYLA runs from different seeded starting points (the first is the single run's);
        the run with the lowest final training objective is kept. 1 (the paper) is one run.
    shots : int or None
        Shots per circuit in training and prediction; ``None`` (default) is exact.
    backend : {"numpy", "aer"}
        Simulator (training with the "qdcnn" engine, and prediction).
    noise : NoiseSpec or None
        Noise at prediction (a per-call ``noise`` argument overrides it).
    train_noise : NoiseSpec or None
        Noise during training (engine "qdcnn" only).
    seed : int
        Seed of the initial weights and of shot sampling.
    engine : {"qdcnn", "qiskit-ml"}
        Who trains: qdcnn's batched simulator with ``scipy.optimize.minimize(method="COBYLA")``,
        or qiskit-machine-learning's ``NeuralNetworkClassifier`` + ``SamplerQNN`` with its
        ``COBYLA`` (same circuit, initial point, loss, ``output_shape=3`` and interpret map;
        exact ``QMLSampler`` unless ``shots`` is set). Prediction always uses qdcnn's simulator.
    feature_columns : pair of int or None
        Two columns of a wider ``X``; ``None`` requires exactly two columns.

    Attributes
    ----------
    weights_ : ndarray, shape (2 (ansatz_reps + 1),)
        Trained ansatz angles (Qiskit parameter order).
    initial_weights_ : ndarray
        The seeded starting point (of the kept run).
    objective_history_ : list of float
        Objective value at every COBYLA evaluation, in order (the paper's callback).
    weight_history_ : list of ndarray
        The weights of every evaluation, in the same order.
    objective_ : float
        Objective at ``weights_`` as reported by the optimizer.
    scaler_params_ : ndarray, shape (2, 2)
        Per feature ``(lo, hi)`` ("minmax") or ``(median, MAD)`` ("arctan"); NaN for "none".
    class_prior_ : ndarray, shape (3,)
        Training class frequencies.
    majority_class_ : int
        Prediction for rows with a missing feature.
    classes_ : ndarray
        ``[0, 1, 2]``.
    n_features_in_ : int
    """

    #: What a fitted classifier learned (saved in model files, :mod:`qdcnn.persistence`).
    fitted_attributes: tuple[str, ...] = (
        "weights_",
        "initial_weights_",
        "objective_history_",
        "weight_history_",
        "objective_",
        "scaler_params_",
        "class_prior_",
        "majority_class_",
        "classes_",
        "n_features_in_",
    )

    def __init__(
        self,
        feature_map_reps: int = _DEFAULTS.feature_map_reps,
        ansatz_reps: int = _DEFAULTS.ansatz_reps,
        maxiter: int = _DEFAULTS.maxiter,
        loss: str = _DEFAULTS.loss,
        interpret: str | tuple[int, ...] = "min2",
        scaling: str = "minmax",
        shots: int | None = _DEFAULTS.shots,
        backend: str = "numpy",
        noise: NoiseSpec | None = None,
        train_noise: NoiseSpec | None = None,
        seed: int = _DEFAULTS.seed,
        engine: str = "qdcnn",
        feature_columns: tuple[int, int] | None = None,
        angle_span: float = 1.0,
        restarts: int = 1,
    ) -> None:
        self.feature_map_reps = feature_map_reps
        self.ansatz_reps = ansatz_reps
        self.maxiter = maxiter
        self.loss = loss
        self.interpret = interpret
        self.scaling = scaling
        self.shots = shots
        self.backend = backend
        self.noise = noise
        self.train_noise = train_noise
        self.seed = seed
        self.engine = engine
        self.feature_columns = feature_columns
        self.angle_span = angle_span
        self.restarts = restarts

    def __sklearn_tags__(self) -> Any:
        tags = super().__sklearn_tags__()
        tags.input_tags.allow_nan = True
        return tags

    def _check_params(self) -> None:
        check_int("feature_map_reps", self.feature_map_reps, 1)
        check_int("ansatz_reps", self.ansatz_reps, 0)
        check_int("maxiter", self.maxiter, 1)
        if self.loss not in _LOSSES:
            raise ParameterError("loss", self.loss, "'mse' or 'cross_entropy'")
        _interpret_table(self.interpret)
        if self.scaling not in _SCALINGS:
            raise ParameterError("scaling", self.scaling, "'minmax', 'arctan' or 'none'")
        check_optional_shots(self.shots)
        check_backend(self.backend)
        check_noise(self.noise)
        check_noise(self.train_noise, "train_noise")
        check_seed("seed", self.seed)
        check_int("restarts", self.restarts, 1)
        check_float("angle_span", self.angle_span, 0.0, 1.0, open_lo=True)
        if self.engine not in _ENGINES:
            raise ParameterError("engine", self.engine, "'qdcnn' or 'qiskit-ml'")
        if self.engine == "qiskit-ml" and self.train_noise is not None:
            raise ParameterError("train_noise", self.train_noise, "None with engine='qiskit-ml'")

    @property
    def n_weights(self) -> int:
        """Number of trainable angles, ``2 (ansatz_reps + 1)``."""
        return 2 * (int(self.ansatz_reps) + 1)

    # ------------------------------------------------------------ scaling

    def _fit_scaler(self, feats: NDArray[np.float64]) -> NDArray[np.float64]:
        params = np.full((2, 2), np.nan)
        if self.scaling == "minmax":
            lo, hi = np.percentile(feats, [1, 99], axis=0)
            params[:, 0], params[:, 1] = lo, np.where(hi > lo, hi, lo + 1.0)
        elif self.scaling == "arctan":
            med = np.median(feats, axis=0)
            mad = np.median(np.abs(feats - med), axis=0)
            params[:, 0], params[:, 1] = med, np.where(mad > 0, mad, 1.0)
        return params

    def scale_features(self, X: ArrayLike) -> NDArray[np.float64]:
        """The feature-map angles ``(N, 2)`` of ``X`` under the fitted scaling (NaN kept)."""
        check_is_fitted(self, "scaler_params_")
        feats = check_feature_pairs(X, self.feature_columns, self.n_features_in_)
        a, b = self.scaler_params_[:, 0], self.scaler_params_[:, 1]
        span = float(self.angle_span)
        if self.scaling == "minmax":
            unit = np.clip((feats - a) / (b - a), 0.0, 1.0)
            return np.pi * unit if span == 1.0 else np.pi / 2 + span * np.pi * (unit - 0.5)
        if self.scaling == "arctan":
            return np.pi / 2 + span * np.arctan((feats - a) / b)
        return feats

    # ------------------------------------------------------------ training

    def fit(self, X: ArrayLike, y: ArrayLike) -> VQCClassifier:
        """Train the ansatz weights with COBYLA from a seeded starting point.

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
        ok = np.all(np.isfinite(feats), axis=1)
        if not ok.any():
            raise InputError("X", "no row has both features finite: nothing to train on")
        self.n_features_in_ = int(np.asarray(X).shape[1])
        self.classes_ = np.arange(N_CLASSES)
        self.class_prior_ = class_prior(labels)
        self.majority_class_ = int(np.argmax(self.class_prior_))
        self.scaler_params_ = self._fit_scaler(feats[ok])
        angles = self.scale_features(np.asarray(X, dtype=np.float64)[ok])
        onehot = np.eye(N_CLASSES)[labels[ok]]
        best: tuple[float, Any, Any, Any, Any] | None = None
        for restart in range(int(self.restarts)):
            # restart 0 starts where a single fit does; the others from seeds [seed, 2, r]
            start_rng = np.random.default_rng(
                self.seed if restart == 0 else [self.seed, 2, restart]
            )
            self.initial_weights_ = start_rng.uniform(0.0, 2 * np.pi, self.n_weights)
            self.objective_history_: list[float] = []
            self.weight_history_: list[NDArray[np.float64]] = []
            if self.engine == "qdcnn":
                weights, value = self._fit_qdcnn(angles, onehot)
            else:
                weights, value = self._fit_qiskit_ml(angles, onehot)
            if best is None or value < best[0]:
                best = (
                    float(value),
                    np.asarray(weights, dtype=np.float64).copy(),
                    self.initial_weights_,
                    self.objective_history_,
                    self.weight_history_,
                )
        assert best is not None
        self.objective_, self.weights_, self.initial_weights_ = best[0], best[1], best[2]
        self.objective_history_, self.weight_history_ = best[3], best[4]
        return self

    def _fit_qdcnn(
        self, angles: NDArray[np.float64], onehot: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], float]:
        gen = np.random.default_rng(self.seed)
        table = interpret_matrix(self.interpret)
        # the feature map does not depend on the weights: its states are computed once
        split = _runs_split(self.backend, self.train_noise)
        states = feature_map_states(angles, self.feature_map_reps) if split else None

        def objective(weights: NDArray[np.float64]) -> float:
            if states is not None:
                probs = _split_probabilities(states, weights, self.ansatz_reps, self.shots, gen)
            else:
                probs = basis_probabilities(
                    angles,
                    weights,
                    feature_map_reps=self.feature_map_reps,
                    ansatz_reps=self.ansatz_reps,
                    shots=self.shots,
                    noise=self.train_noise,
                    backend=self.backend,
                    rng=gen,
                )
            value = loss_value(probs @ table, onehot, self.loss)
            self.objective_history_.append(value)
            self.weight_history_.append(np.array(weights, dtype=np.float64))
            return value

        res = minimize(
            objective,
            self.initial_weights_,
            method="COBYLA",
            options={"maxiter": int(self.maxiter), "rhobeg": 1.0},
        )
        return np.asarray(res.x, dtype=np.float64), float(res.fun)

    def _fit_qiskit_ml(
        self, angles: NDArray[np.float64], onehot: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], float]:
        require("qiskit_machine_learning", "the qiskit-machine-learning VQC engine")
        from qiskit_machine_learning.algorithms import NeuralNetworkClassifier
        from qiskit_machine_learning.optimizers import COBYLA

        qnn = make_sampler_qnn(
            self.interpret,
            feature_map_reps=self.feature_map_reps,
            ansatz_reps=self.ansatz_reps,
            shots=self.shots,
            seed=self.seed,
        )

        def record(weights: Any, value: float) -> None:
            self.objective_history_.append(float(value))
            self.weight_history_.append(np.array(weights, dtype=np.float64))

        clf = NeuralNetworkClassifier(
            qnn,
            loss="squared_error" if self.loss == "mse" else "cross_entropy",
            one_hot=True,
            optimizer=COBYLA(maxiter=int(self.maxiter)),
            initial_point=self.initial_weights_.copy(),
            callback=record,
        )
        # one-hot targets with all three columns, so a training set without one class works
        clf.fit(angles, onehot)
        fun = clf.fit_result.fun
        value = min(self.objective_history_) if fun is None else float(fun)
        return np.asarray(clf.weights, dtype=np.float64), value

    # ------------------------------------------------------------ prediction

    def basis_probabilities(
        self, X: ArrayLike, noise: NoiseSpec | None = None
    ) -> NDArray[np.float64]:
        """Basis-state probabilities ``(N, 4)`` of the trained circuit; NaN rows stay NaN.

        ``noise`` overrides the estimator's ``noise`` (``NoiseSpec()`` for an ideal run).
        """
        check_is_fitted(self, "weights_")
        angles = self.scale_features(X)
        noise = self.noise if noise is None else check_noise(noise)
        out = np.full((angles.shape[0], 4), np.nan)
        ok = np.all(np.isfinite(angles), axis=1)
        if ok.any():
            out[ok] = basis_probabilities(
                angles[ok],
                self.weights_,
                feature_map_reps=self.feature_map_reps,
                ansatz_reps=self.ansatz_reps,
                shots=self.shots,
                noise=noise,
                backend=self.backend,
                rng=None if self.shots is None else np.random.default_rng([self.seed, 1]),
            )
        return out

    def predict_proba(self, X: ArrayLike, noise: NoiseSpec | None = None) -> NDArray[np.float64]:
        """Class probabilities ``(N, 3)`` (left, straight, right) through ``interpret``.

        Rows with a missing feature get the training class frequencies.
        """
        basis = self.basis_probabilities(X, noise)
        out: NDArray[np.float64] = basis @ interpret_matrix(self.interpret)
        bad = ~np.all(np.isfinite(basis), axis=1)
        out[bad] = self.class_prior_
        return out

    def predict(self, X: ArrayLike, noise: NoiseSpec | None = None) -> NDArray[np.int64]:
        """Most probable class per row; majority training class for rows with a missing feature."""
        # rows with a missing feature carry class_prior_, whose argmax is majority_class_
        out: NDArray[np.int64] = np.argmax(self.predict_proba(X, noise), axis=1).astype(np.int64)
        return out

    @classmethod
    def predict_many(
        cls,
        models: Sequence[tuple[ArrayLike, VQCClassifier]],
        X: ArrayLike,
        *,
        noise: NoiseSpec | None = None,
        shots: int | None = None,
        rng: int | np.random.Generator | None = None,
        backend: str = "numpy",
    ) -> NDArray[np.int64]:
        """Predictions of several fitted VQCs, each on its own rows, in one circuit run.

        The circuits of all models (per-sample ansatz weights) are one batch; models whose
        circuits differ in shape (``feature_map_reps``, ``ansatz_reps``) cannot share one,
        so each run of consecutive models of one shape is one batch.

        Parameters
        ----------
        models : sequence of (rows, VQCClassifier)
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
        gen = np.random.default_rng(rng) if not isinstance(rng, np.random.Generator) else rng
        x = np.asarray(X, dtype=np.float64)
        out: list[NDArray[np.int64]] = []

        def shape(pair: tuple[NDArray[np.intp], VQCClassifier]) -> tuple[int, int]:
            return int(pair[1].feature_map_reps), int(pair[1].ansatz_reps)

        for (fm_reps, ansatz_reps), group in groupby(pairs, key=shape):
            parts, angles, weights = [], [], []
            for rows, est in group:
                a = est.scale_features(x[rows])
                ok = np.all(np.isfinite(a), axis=1)
                parts.append((est, ok))
                angles.append(a[ok])
                weights.append(np.broadcast_to(est.weights_, (int(ok.sum()), est.weights_.size)))
            a_all = np.concatenate(angles)
            basis = np.empty((0, 4))
            if a_all.shape[0]:
                basis = basis_probabilities(
                    a_all,
                    np.concatenate(weights),
                    feature_map_reps=fm_reps,
                    ansatz_reps=ansatz_reps,
                    shots=shots,
                    noise=run_noise,
                    backend=backend,
                    rng=gen,
                )
            start = 0
            for est, ok in parts:
                n = int(ok.sum())
                pred = np.full(ok.size, est.majority_class_, dtype=np.int64)
                classes = basis[start : start + n] @ interpret_matrix(est.interpret)
                pred[ok] = np.argmax(classes, axis=1)
                out.append(pred)
                start += n
        return np.concatenate(out) if out else np.empty(0, dtype=np.int64)

    def plot_objective(self, ax: Any = None) -> Any:
        """Draw ``objective_history_`` against evaluation number; returns the Axes.

        See :func:`qdcnn.quantum.vqc_plot.plot_objective_history`.
        """
        check_is_fitted(self, "objective_history_")
        from qdcnn.quantum.vqc_plot import plot_objective_history

        return plot_objective_history(self.objective_history_, ax=ax, loss=self.loss)
