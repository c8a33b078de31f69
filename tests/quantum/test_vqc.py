"""The two-qubit VQC: equality with qiskit-machine-learning, training, noise, sklearn API."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.exceptions import NotFittedError
from sklearn.model_selection import KFold, cross_val_score

from qdcnn._optional import has_module
from qdcnn.errors import InputError, ParameterError
from qdcnn.quantum.circuits import CircuitBuilder, vqc_circuit, zz_feature_map
from qdcnn.quantum.execute import run_probabilities
from qdcnn.quantum.noise import NoiseSpec
from qdcnn.quantum.simulator import statevector
from qdcnn.quantum.vqc import (
    VQCClassifier,
    ansatz_probabilities,
    basis_probabilities,
    class_probabilities,
    feature_map_states,
    interpret_matrix,
    loss_value,
    make_sampler_qnn,
)

needs_qiskit_ml = pytest.mark.skipif(
    not has_module("qiskit_machine_learning"), reason="qiskit-machine-learning missing"
)


def road_slopes(
    n: int, rng: np.random.Generator, noise: float = 0.05
) -> tuple[np.ndarray, np.ndarray]:
    """Separable slope pairs: straight symmetric (left < 0 < right), left bends shift both
    slopes positive, right bends negative."""
    y = rng.integers(0, 3, n)
    spread = rng.uniform(0.8, 1.2, n)
    shift = np.select([y == 0, y == 2], [1.0, -1.0], 0.0) * rng.uniform(0.6, 0.9, n)
    X = np.stack([-spread + shift, spread + shift], axis=1) + rng.normal(0, noise, (n, 2))
    return X, y


@needs_qiskit_ml
@pytest.mark.parametrize(
    ("interpret", "fm_reps", "ansatz_reps"),
    [("min2", 2, 1), ("mod3", 2, 1), ((2, 0, 1, 1), 1, 2)],
)
def test_class_probabilities_equal_sampler_qnn_forward(
    rng: np.random.Generator, interpret: object, fm_reps: int, ansatz_reps: int
) -> None:
    # QMLSampler() (shots=None) computes exact probabilities with qiskit's Statevector
    qnn = make_sampler_qnn(interpret, feature_map_reps=fm_reps, ansatz_reps=ansatz_reps)
    x = rng.uniform(-1, 4, (25, 2))
    for _ in range(3):
        w = rng.uniform(-np.pi, 2 * np.pi, 2 * (ansatz_reps + 1))
        ours = class_probabilities(
            x, w, interpret=interpret, feature_map_reps=fm_reps, ansatz_reps=ansatz_reps
        )
        np.testing.assert_allclose(ours, qnn.forward(x, w), atol=1e-8)


@needs_qiskit_ml
def test_fitted_predict_proba_equals_sampler_qnn(rng: np.random.Generator) -> None:
    X, y = road_slopes(30, rng)
    clf = VQCClassifier(maxiter=6).fit(X, y)
    ref = make_sampler_qnn("min2").forward(clf.scale_features(X), clf.weights_)
    np.testing.assert_allclose(clf.predict_proba(X), ref, atol=1e-8)


@needs_qiskit_ml
@pytest.mark.parametrize("loss", ["mse", "cross_entropy"])
def test_qiskit_ml_engine_trains_the_same_objective(rng: np.random.Generator, loss: str) -> None:
    X, y = road_slopes(16, rng)
    y[:] = np.where(y == 1, 0, y)  # a training set without "straight" still has 3 outputs
    ours = VQCClassifier(maxiter=12, loss=loss).fit(X, y)
    theirs = VQCClassifier(maxiter=12, loss=loss, engine="qiskit-ml").fit(X, y)
    assert len(theirs.objective_history_) == len(ours.objective_history_) == 12
    np.testing.assert_array_equal(theirs.weight_history_[0], ours.initial_weights_)
    # every (weights, value) qiskit-ml evaluated is our objective at those weights; the
    # COBYLA paths themselves may part once values differ by ~1e-12 (seen with cross-entropy)
    angles, onehot = ours.scale_features(X), np.eye(3)[y]
    for w, value in zip(theirs.weight_history_, theirs.objective_history_, strict=True):
        assert loss_value(class_probabilities(angles, w), onehot, loss) == pytest.approx(
            value, abs=1e-9
        )
    assert theirs.objective_ == pytest.approx(min(theirs.objective_history_), abs=1e-12)


def test_loss_known_values() -> None:
    onehot = np.eye(3)[[0, 2]]
    uniform = np.full((2, 3), 1 / 3)
    assert loss_value(onehot, onehot, "mse") == 0.0
    assert loss_value(uniform, onehot, "mse") == pytest.approx(6 / 9)  # (2/3)^2 + 2 (1/3)^2
    assert loss_value(uniform, onehot, "cross_entropy") == pytest.approx(np.log2(3))
    assert loss_value(np.eye(3)[[1, 1]], onehot, "cross_entropy") == pytest.approx(-np.log2(1e-10))


def test_interpret_maps_make_every_class_predictable(rng: np.random.Generator) -> None:
    np.testing.assert_array_equal(interpret_matrix("min2").argmax(axis=1), [0, 1, 2, 2])
    np.testing.assert_array_equal(interpret_matrix("mod3").argmax(axis=1), [0, 1, 2, 0])
    x = rng.uniform(0, np.pi, (400, 2))
    for interpret in ("min2", "mod3"):
        winners = set()
        for _ in range(5):
            w = rng.uniform(0, 2 * np.pi, 4)
            winners |= set(class_probabilities(x, w, interpret=interpret).argmax(axis=1).tolist())
        assert winners == {0, 1, 2}
    with pytest.raises(ParameterError, match=r"^interpret=\(0, 1, 1, 0\) is invalid"):
        VQCClassifier(interpret=(0, 1, 1, 0)).fit(*road_slopes(10, rng))


def test_training_lowers_objective_and_classifies(rng: np.random.Generator) -> None:
    X, y = road_slopes(300, rng)
    Xt, yt = road_slopes(300, rng)
    clf = VQCClassifier().fit(X, y)
    history = clf.objective_history_
    assert len(history) == 30  # COBYLA maxiter counts objective evaluations
    assert min(history) < history[0] - 0.2
    assert clf.objective_ == pytest.approx(min(history))
    # chance is 1/3; 4 angles on a fixed feature map cannot fit these classes exactly
    # (about 0.85-0.9 at best on this data), so ask for clearly better than chance
    assert clf.score(X, y) >= 0.7
    assert clf.score(Xt, yt) >= 0.7
    assert set(clf.predict(Xt).tolist()) == {0, 1, 2}


def test_seeded_training_is_deterministic(rng: np.random.Generator) -> None:
    X, y = road_slopes(60, rng)
    a = VQCClassifier(maxiter=10, seed=5).fit(X, y)
    b = VQCClassifier(maxiter=10, seed=5).fit(X, y)
    np.testing.assert_array_equal(a.weights_, b.weights_)
    assert a.objective_history_ == b.objective_history_
    c = VQCClassifier(maxiter=10, seed=6).fit(X, y)
    assert not np.array_equal(a.initial_weights_, c.initial_weights_)
    # with shots, training and prediction are seeded too
    s1 = VQCClassifier(maxiter=10, shots=256, seed=5).fit(X, y)
    s2 = VQCClassifier(maxiter=10, shots=256, seed=5).fit(X, y)
    assert s1.objective_history_ == s2.objective_history_
    p = s1.basis_probabilities(X)
    np.testing.assert_array_equal(p, s2.basis_probabilities(X))
    np.testing.assert_allclose(p * 256, np.round(p * 256), atol=1e-9)


def test_noise_at_prediction(rng: np.random.Generator) -> None:
    X, y = road_slopes(80, rng)
    clf = VQCClassifier(maxiter=15).fit(X, y)
    ideal = clf.predict_proba(X)
    zero = clf.predict_proba(X, noise=NoiseSpec("depolarizing", 0.0))
    np.testing.assert_allclose(zero, ideal, atol=1e-10)
    assert clf.score(X, y) == np.mean(clf.predict(X, noise=NoiseSpec("bit-flip", 0.0)) == y)
    full = NoiseSpec("depolarizing", 1.0)
    np.testing.assert_allclose(clf.basis_probabilities(X, noise=full), 0.25, atol=1e-12)
    np.testing.assert_allclose(clf.predict_proba(X, noise=full), [[0.25, 0.25, 0.5]] * 80)


def test_training_under_full_depolarizing_sees_a_flat_objective(
    rng: np.random.Generator,
) -> None:
    X, y = road_slopes(40, rng)
    clf = VQCClassifier(maxiter=8, train_noise=NoiseSpec("depolarizing", 1.0)).fit(X, y)
    expected = loss_value(np.tile([0.25, 0.25, 0.5], (40, 1)), np.eye(3)[y], "mse")
    np.testing.assert_allclose(clf.objective_history_, expected, atol=1e-12)


@pytest.mark.skipif(not has_module("qiskit_aer"), reason="qiskit-aer not installed")
def test_aer_backend_matches_numpy(rng: np.random.Generator) -> None:
    x = rng.uniform(0, np.pi, (6, 2))
    w = rng.uniform(0, 2 * np.pi, 4)
    np.testing.assert_allclose(
        basis_probabilities(x, w, backend="aer"), basis_probabilities(x, w), atol=1e-10
    )


def test_rows_with_a_missing_feature_get_the_majority_class(rng: np.random.Generator) -> None:
    X, y = road_slopes(60, rng)
    y[:30] = 2
    X[:4, 1] = np.nan
    clf = VQCClassifier(maxiter=6).fit(X, y)
    assert clf.majority_class_ == 2
    Xt = np.array([[np.nan, 1.0], [-1.0, np.nan], [-1.0, 1.0]])
    assert clf.predict(Xt)[:2].tolist() == [2, 2]
    np.testing.assert_allclose(clf.predict_proba(Xt)[:2], [np.bincount(y, minlength=3) / 60] * 2)
    assert np.isnan(clf.basis_probabilities(Xt)[:2]).all()
    with pytest.raises(InputError, match="^X: no row has both features finite"):
        VQCClassifier().fit(np.full((3, 2), np.nan), [0, 1, 2])


def test_input_errors(rng: np.random.Generator) -> None:
    X, y = road_slopes(20, rng)
    with pytest.raises(NotFittedError):
        VQCClassifier().predict(X)
    with pytest.raises(ParameterError, match=r"^X='<3 features>' is invalid: exactly 2 features"):
        VQCClassifier().fit(np.column_stack([X, X[:, 0]]), y)
    clf = VQCClassifier(maxiter=6).fit(X, y)
    match = r"^X='<1 features>' is invalid: 2 features, as in fit$"
    with pytest.raises(ParameterError, match=match):
        clf.predict(X[:, :1])
    with pytest.raises(ParameterError, match="^loss='hinge' is invalid"):
        VQCClassifier(loss="hinge").fit(X, y)
    with pytest.raises(ParameterError, match="^engine='torch' is invalid"):
        VQCClassifier(engine="torch").fit(X, y)
    match = "^train_noise=.* is invalid: None with engine='qiskit-ml'"
    with pytest.raises(ParameterError, match=match):
        VQCClassifier(engine="qiskit-ml", train_noise=NoiseSpec("bit-flip", 0.1)).fit(X, y)


def test_feature_columns_pick_the_slopes_of_a_wider_table(rng: np.random.Generator) -> None:
    X, y = road_slopes(40, rng)
    wide = np.column_stack([X, rng.normal(size=(40, 2))])
    a = VQCClassifier(maxiter=6).fit(X, y)
    b = VQCClassifier(maxiter=6, feature_columns=(0, 1)).fit(wide, y)
    np.testing.assert_array_equal(a.weights_, b.weights_)
    np.testing.assert_allclose(a.predict_proba(X), b.predict_proba(wide))


@pytest.mark.parametrize("scaling", ["minmax", "arctan"])
def test_angle_span_shrinks_the_angles_towards_half_pi(
    rng: np.random.Generator, scaling: str
) -> None:
    X, y = road_slopes(60, rng)
    full = VQCClassifier(maxiter=6, scaling=scaling).fit(X, y)
    half = VQCClassifier(maxiter=6, scaling=scaling, angle_span=0.5).fit(X, y)
    a, b = full.scale_features(X), half.scale_features(X)
    np.testing.assert_allclose(b, np.pi / 2 + 0.5 * (a - np.pi / 2), atol=1e-12)
    assert b.min() >= np.pi / 4 - 1e-12 and b.max() <= 3 * np.pi / 4 + 1e-12
    if scaling == "minmax":  # the 1st and 99th percentiles go to the ends of the span
        lo, hi = np.percentile(X, [1, 99], axis=0)
        np.testing.assert_allclose(
            half.scale_features(np.vstack([lo, hi])), [[np.pi / 4] * 2, [3 * np.pi / 4] * 2]
        )


def test_restarts_keep_the_run_of_lowest_training_objective(rng: np.random.Generator) -> None:
    X, y = road_slopes(60, rng)
    one = VQCClassifier(maxiter=10).fit(X, y)
    three = VQCClassifier(maxiter=10, restarts=3).fit(X, y)
    assert three.objective_ <= one.objective_
    assert len(three.objective_history_) == len(three.weight_history_) > 0
    # the kept history is one run's: it starts at the kept run's starting point
    np.testing.assert_array_equal(three.weight_history_[0], three.initial_weights_)
    if three.objective_ == one.objective_:  # restart 0 is the single run
        np.testing.assert_array_equal(three.weights_, one.weights_)
    with pytest.raises(ParameterError, match="^restarts=0 is invalid"):
        VQCClassifier(restarts=0).fit(X, y)


def test_angle_span_must_be_in_zero_one(rng: np.random.Generator) -> None:
    X, y = road_slopes(20, rng)
    for span in (0.0, 1.5, True):
        with pytest.raises(
            ParameterError, match=f"^angle_span={span!r} is invalid: a finite number in"
        ):
            VQCClassifier(angle_span=span).fit(X, y)


def test_sklearn_compatibility(rng: np.random.Generator) -> None:
    X, y = road_slopes(90, rng)
    clf = VQCClassifier(maxiter=10, scaling="arctan")
    assert clf.get_params()["scaling"] == "arctan"
    assert clf.set_params(loss="cross_entropy").loss == "cross_entropy"
    twin = clone(clf)
    assert twin.get_params() == clf.get_params() and not hasattr(twin, "weights_")
    scores = cross_val_score(clf, X, y, cv=KFold(3, shuffle=False))
    assert scores.shape == (3,) and np.all((scores >= 0) & (scores <= 1))
    assert clf.__sklearn_tags__().input_tags.allow_nan


def test_plot_objective_draws_the_history(rng: np.random.Generator) -> None:
    clf = VQCClassifier(maxiter=7).fit(*road_slopes(30, rng))
    ax = clf.plot_objective()
    line = ax.get_lines()[0]
    np.testing.assert_array_equal(line.get_xdata(), np.arange(1, 8))
    np.testing.assert_array_equal(line.get_ydata(), clf.objective_history_)
    assert ax.get_xlabel() == "objective evaluation (COBYLA)"


@pytest.mark.parametrize("reps", [1, 2, 3])
def test_feature_map_states_equal_the_gate_by_gate_simulation(
    rng: np.random.Generator, reps: int
) -> None:
    x = rng.uniform(-1, 4, (40, 2))
    gates = statevector(zz_feature_map(CircuitBuilder(2, 40), x, reps).build("fm"))
    np.testing.assert_allclose(feature_map_states(x, reps), gates, rtol=0, atol=1e-12)


@pytest.mark.parametrize(("fm_reps", "ansatz_reps"), [(2, 1), (1, 0), (3, 2)])
@pytest.mark.parametrize("per_sample_weights", [False, True])
def test_split_vqc_probabilities_equal_the_whole_circuit(
    rng: np.random.Generator, fm_reps: int, ansatz_reps: int, per_sample_weights: bool
) -> None:
    x = rng.uniform(-1, 4, (30, 2))
    n_w = 2 * (ansatz_reps + 1)
    w = rng.uniform(-np.pi, 2 * np.pi, (30, n_w) if per_sample_weights else n_w)
    whole = run_probabilities(vqc_circuit(x, w, feature_map_reps=fm_reps, ansatz_reps=ansatz_reps))
    split = ansatz_probabilities(feature_map_states(x, fm_reps), w, ansatz_reps)
    np.testing.assert_allclose(split, whole, rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        basis_probabilities(x, w, feature_map_reps=fm_reps, ansatz_reps=ansatz_reps),
        whole,
        rtol=0,
        atol=1e-12,
    )


def test_split_shots_have_the_circuit_statistics(rng: np.random.Generator) -> None:
    x = rng.uniform(0, 3, (4000, 2))
    w = rng.uniform(-np.pi, np.pi, 4)
    exact = basis_probabilities(x, w)
    est = basis_probabilities(x, w, shots=256, rng=5)
    np.testing.assert_allclose(est * 256, np.round(est * 256), atol=1e-9)
    # the mean estimate of each basis state is unbiased within 4 standard errors
    se = np.sqrt((exact * (1 - exact)).sum(axis=0) / 256) / x.shape[0]
    assert (np.abs((est - exact).mean(axis=0)) < 4 * se).all()


def test_feature_map_states_check_their_input() -> None:
    with pytest.raises(ParameterError, match="two features per sample"):
        feature_map_states(np.zeros((3, 3)))
    with pytest.raises(ParameterError, match="feature_map_reps=0 is invalid"):
        feature_map_states(np.zeros((3, 2)), 0)


@pytest.fixture(scope="module")
def vqc_folds() -> tuple[np.ndarray, list]:
    rng = np.random.default_rng(8)
    X, y = road_slopes(90, rng)
    X[[3, 40], 1] = np.nan
    parts = [np.arange(0, 30), np.arange(30, 60), np.arange(60, 90)]
    settings = [
        {"interpret": "min2"},
        {"interpret": "mod3", "seed": 2},
        {"feature_map_reps": 1, "ansatz_reps": 2},  # another circuit shape: its own batch
    ]
    models = []
    for rows, kw in zip(parts, settings, strict=True):
        train = np.setdiff1d(np.arange(90), rows)
        models.append((rows, VQCClassifier(maxiter=12, **kw).fit(X[train], y[train])))
    return X, models


@pytest.mark.parametrize(
    "noise",
    [
        NoiseSpec(),
        NoiseSpec("depolarizing", 0.3),
        NoiseSpec("amplitude-damping", 0.7, readout=0.05),
        NoiseSpec("phase-damping-paper", 0.2),
    ],
)
def test_predict_many_equals_each_predict(vqc_folds: tuple, noise: NoiseSpec) -> None:
    X, models = vqc_folds
    expected = np.concatenate([est.predict(X[rows], noise=noise) for rows, est in models])
    np.testing.assert_array_equal(VQCClassifier.predict_many(models, X, noise=noise), expected)
    # one model at a time gives the same
    one_by_one = [VQCClassifier.predict_many([m], X, noise=noise) for m in models]
    np.testing.assert_array_equal(np.concatenate(one_by_one), expected)


def test_predict_many_shots_and_known_answer(vqc_folds: tuple) -> None:
    X, models = vqc_folds
    noise = NoiseSpec("bit-flip", 0.1)
    a = VQCClassifier.predict_many(models, X, noise=noise, shots=16, rng=4)
    np.testing.assert_array_equal(
        a, VQCClassifier.predict_many(models, X, noise=noise, shots=16, rng=4)
    )
    assert not np.array_equal(
        a, VQCClassifier.predict_many(models, X, noise=noise, shots=16, rng=5)
    )
    # depolarizing at p=1 leaves I/4: "min2" gives classes 1/4, 1/4, 1/2 -> right (2),
    # "mod3" gives 1/2, 1/4, 1/4 -> left (0); rows with a missing feature get the majority
    rows, est = models[0]
    full = VQCClassifier.predict_many([(rows, est)], X, noise=NoiseSpec("depolarizing", 1.0))
    ok = np.all(np.isfinite(X[rows]), axis=1)
    assert (full[ok] == 2).all() and (full[~ok] == est.majority_class_).all()
    rows, est = models[1]
    full = VQCClassifier.predict_many([(rows, est)], X, noise=NoiseSpec("depolarizing", 1.0))
    ok = np.all(np.isfinite(X[rows]), axis=1)
    assert (~ok).any() and (full[ok] == 0).all() and (full[~ok] == est.majority_class_).all()
    with pytest.raises(ParameterError, match=r"^models\[0\]='<UUDirectionClassifier>' is invalid"):
        from qdcnn.quantum.direction import UUDirectionClassifier

        VQCClassifier.predict_many([(rows, UUDirectionClassifier())], X)


def test_train_noise_through_set_params_retrains_under_noise(rng: np.random.Generator) -> None:
    X, y = road_slopes(60, rng)
    clf = VQCClassifier(maxiter=10).fit(X, y)
    noise = NoiseSpec("depolarizing", 0.4)
    noisy = clone(clf).set_params(train_noise=noise).fit(X, y)
    # same start, different objective: the noisy run's first evaluation is the noisy loss
    np.testing.assert_array_equal(noisy.initial_weights_, clf.initial_weights_)
    probs = class_probabilities(
        noisy.scale_features(X), noisy.initial_weights_, interpret="min2", noise=noise
    )
    onehot = np.eye(3)[y]
    assert noisy.objective_history_[0] == pytest.approx(loss_value(probs, onehot, "mse"), abs=1e-12)
    assert noisy.objective_history_[0] != pytest.approx(clf.objective_history_[0], abs=1e-6)
