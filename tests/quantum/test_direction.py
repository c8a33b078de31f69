"""The UU-dagger direction rule: the printed rule, training, noise, NaN rows, sklearn API."""

from __future__ import annotations

import json

import numpy as np
import pytest
from sklearn.base import clone
from sklearn.exceptions import NotFittedError
from sklearn.model_selection import KFold, cross_val_score

from qdcnn._optional import has_module
from qdcnn.errors import InputError, ParameterError
from qdcnn.quantum.direction import UUDirectionClassifier, grid_search, rule, soft_scores
from qdcnn.quantum.noise import CHANNELS, NoiseSpec


def road_slopes(
    n: int, rng: np.random.Generator, noise: float = 0.15
) -> tuple[np.ndarray, np.ndarray]:
    """Slopes dx/dy of two lane lines: straight roads are symmetric (left < 0 < right),
    a left bend shifts both slopes positive, a right bend negative."""
    y = rng.integers(0, 3, n)
    spread = rng.uniform(0.5, 1.5, n)
    shift = np.select([y == 0, y == 2], [1.0, -1.0], 0.0) * rng.uniform(0.4, 1.0, n)
    X = np.stack([-spread + shift, spread + shift], axis=1) + rng.normal(0, noise, (n, 2))
    return X, y


def known_rule_data(
    n: int, rng: np.random.Generator, centroid: float, margin: float
) -> tuple[np.ndarray, np.ndarray]:
    """Slopes labelled by the printed rule with a known centroid and margin (map: pi/2 + atan)."""
    X = rng.uniform(-3, 3, (n, 2))
    p = np.cos((centroid - (np.pi / 2 + np.arctan(X))) / 2) ** 2
    return X, rule(p[:, 0], p[:, 1], margin)


def fixed(centroid: float, margin: float = 0.2, **kw: object) -> UUDirectionClassifier:
    return UUDirectionClassifier(
        straight_margin=margin,
        centroid=centroid,
        train_margin=False,
        angle_map="identity",
        shots=None,
        **kw,
    )


def test_rule_as_printed_known_answers() -> None:
    p1 = [0.9, 0.2, 0.50, 0.50, 1.0, 1.0, 0.3]
    p2 = [0.2, 0.9, 0.45, 0.55, 0.8 - 1e-9, 0.8 + 1e-9, 0.3]
    # |d| < 0.2 straight; else d > 0 right, d < 0 left; d = 0 with margin 0 is "otherwise" = left
    assert rule(p1, p2, 0.2).tolist() == [2, 0, 1, 1, 2, 1, 1]
    assert rule(p1, p2, 0.0).tolist() == [2, 0, 2, 0, 2, 2, 0]


def test_fixed_centroid_and_margin_follow_the_three_cases() -> None:
    # centroid 0, identity angles: P_i = cos^2(theta_i / 2)
    X = np.array([[0.0, np.pi], [np.pi, 0.0], [1.0, 1.0], [0.5, 0.9], [0.2, 1.6], [1.6, 0.2]])
    clf = fixed(0.0).fit(X, [2, 0, 1, 1, 2, 0])
    p = clf.circuit_probabilities(X)
    np.testing.assert_allclose(p, np.cos(X / 2) ** 2, atol=1e-12)
    # d = 1, -1, 0, 0.1297, 0.5046, -0.5046
    assert clf.predict(X).tolist() == [2, 0, 1, 1, 2, 0]
    assert clf.centroid_ == 0.0 and clf.margin_ == 0.2 and clf.accuracy_grid_ is None
    proba = clf.predict_proba(X)
    np.testing.assert_allclose(proba.sum(axis=1), 1.0)
    assert np.argmax(proba, axis=1).tolist() == clf.predict(X).tolist()


def test_antipodal_centroid_mirrors_left_and_right(rng: np.random.Generator) -> None:
    X = rng.uniform(0, np.pi, (200, 2))
    a = fixed(0.7).fit(X, np.zeros(200, int)).predict(X)
    b = fixed(0.7 + np.pi).fit(X, np.zeros(200, int)).predict(X)
    np.testing.assert_array_equal(b, np.choose(a, [2, 1, 0]))


def test_soft_scores_argmax_reproduces_rule(rng: np.random.Generator) -> None:
    d = rng.uniform(-1, 1, 1000)
    for m in (0.0, 0.05, 0.2, 0.6):
        s = soft_scores(d, m, 0.05)
        np.testing.assert_allclose(s.sum(axis=1), 1.0)
        np.testing.assert_array_equal(np.argmax(s, axis=1), rule(d, 0.0, m))


def test_training_on_road_geometry_reaches_high_accuracy(rng: np.random.Generator) -> None:
    X, y = road_slopes(300, rng)
    Xt, yt = road_slopes(300, rng)
    clf = UUDirectionClassifier(shots=None).fit(X, y)
    assert clf.train_accuracy_ >= 0.95
    assert clf.score(Xt, yt) >= 0.9
    # the printed orientation (P1 > P2 -> right) needs the antipode of straight-ahead (pi/2)
    assert abs(clf.centroid_ - 3 * np.pi / 2) < 0.3
    # the default 1024 shots change few decisions
    assert UUDirectionClassifier().fit(X, y).score(Xt, yt) >= 0.88


@pytest.mark.parametrize(("centroid", "margin"), [(4.3, 0.27), (1.2, 0.1)])
def test_training_recovers_known_centroid_and_margin(
    rng: np.random.Generator, centroid: float, margin: float
) -> None:
    X, y = known_rule_data(500, rng, centroid, margin)
    clf = UUDirectionClassifier(slope_scale=1.0, shots=None).fit(X, y)
    assert clf.train_accuracy_ == 1.0
    assert abs(clf.centroid_ - centroid) < 0.05
    assert abs(clf.margin_ - margin) < 0.03


def test_margin_only_and_centroid_only_training(rng: np.random.Generator) -> None:
    X, y = known_rule_data(500, rng, 4.3, 0.27)
    only_margin = UUDirectionClassifier(centroid=4.3, slope_scale=1.0, shots=None).fit(X, y)
    assert only_margin.centroid_ == 4.3 and abs(only_margin.margin_ - 0.27) < 0.03
    only_centroid = UUDirectionClassifier(
        straight_margin=0.27, train_margin=False, slope_scale=1.0, shots=None
    ).fit(X, y)
    assert only_centroid.margin_ == 0.27 and abs(only_centroid.centroid_ - 4.3) < 0.05


def test_angle_maps() -> None:
    X = np.array([[-2.0, 0.0], [1.0, 4.0]])
    arctan = UUDirectionClassifier(shots=None).fit(X, [0, 1])
    assert arctan.angle_params_ == (1.5,)  # median |slope|
    np.testing.assert_allclose(arctan.slope_angles(X), np.pi / 2 + np.arctan(X / 1.5))
    minmax = UUDirectionClassifier(angle_map="minmax", shots=None).fit(X, [0, 1])
    lo, hi = np.percentile(X, [1, 99])
    expected = np.pi * np.clip((X - lo) / (hi - lo), 0, 1)
    np.testing.assert_allclose(minmax.slope_angles(X), expected)
    assert expected[0, 0] == 0.0 and expected[1, 1] == np.pi  # min and max lie past the percentiles
    np.testing.assert_allclose(minmax.slope_angles([[-10.0, 10.0]]), [[0.0, np.pi]])


def test_noise_zero_equals_ideal_and_full_depolarizing_is_straight(
    rng: np.random.Generator,
) -> None:
    X, y = road_slopes(120, rng)
    clf = UUDirectionClassifier(shots=None).fit(X, y)
    ideal = clf.predict(X)
    np.testing.assert_array_equal(clf.predict(X, noise=NoiseSpec("depolarizing", 0.0)), ideal)
    assert clf.score(X, y) == np.mean(ideal == y)
    full = NoiseSpec("depolarizing", 1.0)
    np.testing.assert_allclose(clf.circuit_probabilities(X, noise=full), 0.5, atol=1e-12)
    assert set(clf.predict(X, noise=full).tolist()) == {1}
    # the estimator's own noise is used unless a call overrides it
    noisy = clone(clf).set_params(noise=full).fit(X, y)
    assert set(noisy.predict(X).tolist()) == {1}
    np.testing.assert_array_equal(noisy.predict(X, noise=NoiseSpec()), ideal)


def test_shots_are_seeded_and_binomial(rng: np.random.Generator) -> None:
    X, y = road_slopes(200, rng)
    clf = UUDirectionClassifier(shots=1024, seed=3).fit(X, y)
    p = clf.circuit_probabilities(X)
    np.testing.assert_allclose(p * 1024, np.round(p * 1024), atol=1e-9)
    np.testing.assert_array_equal(clf.circuit_probabilities(X), p)
    again = UUDirectionClassifier(shots=1024, seed=3).fit(X, y)
    np.testing.assert_array_equal(again.circuit_probabilities(X), p)
    assert clf.centroid_ == again.centroid_ and clf.margin_ == again.margin_
    other = UUDirectionClassifier(shots=1024, seed=4).fit(X, y).circuit_probabilities(X)
    assert not np.array_equal(other, p)


@pytest.mark.skipif(not has_module("qiskit_aer"), reason="qiskit-aer not installed")
def test_aer_backend_matches_numpy(rng: np.random.Generator) -> None:
    X, y = road_slopes(20, rng)
    ours = UUDirectionClassifier(shots=None).fit(X, y)
    aer = clone(ours).set_params(backend="aer").fit(X, y)
    np.testing.assert_allclose(
        aer.circuit_probabilities(X), ours.circuit_probabilities(X), atol=1e-10
    )


def test_rows_with_a_missing_slope_get_the_majority_class(rng: np.random.Generator) -> None:
    X, y = road_slopes(100, rng)
    y[:60] = 1  # straight is the majority
    X[:5, 0] = np.nan
    X[5:8, 1] = np.nan
    clf = UUDirectionClassifier(shots=None).fit(X, y)
    assert clf.majority_class_ == 1
    Xt = np.array([[np.nan, 1.0], [-1.0, np.nan], [np.nan, np.nan], [-1.0, 1.0]])
    assert clf.predict(Xt)[:3].tolist() == [1, 1, 1]
    proba = clf.predict_proba(Xt)
    np.testing.assert_allclose(proba[:3], np.tile(np.bincount(y, minlength=3) / 100, (3, 1)))
    assert np.isnan(clf.decision_function(Xt)[:3]).all() and np.isfinite(proba).all()


@pytest.mark.parametrize("shots", [None, 1024])
def test_predict_with_proba_is_predict_and_predict_proba(
    rng: np.random.Generator, shots: int | None
) -> None:
    X, y = road_slopes(120, rng)
    X[:4, 0] = np.nan
    clf = UUDirectionClassifier(shots=shots, seed=2).fit(X, y)
    labels, proba = clf.predict_with_proba(X)
    np.testing.assert_array_equal(labels, clf.predict(X))
    np.testing.assert_array_equal(proba, clf.predict_proba(X))
    noise = NoiseSpec("depolarizing", 0.3)
    labels, proba = clf.predict_with_proba(X, noise)
    np.testing.assert_array_equal(labels, clf.predict(X, noise))
    np.testing.assert_array_equal(proba, clf.predict_proba(X, noise))


def test_input_errors() -> None:
    X = np.array([[-1.0, 1.0], [0.0, 2.0]])
    with pytest.raises(NotFittedError):
        UUDirectionClassifier().predict(X)
    with pytest.raises(ParameterError, match=r"^X='<3 features>' is invalid: exactly 2 features"):
        UUDirectionClassifier().fit(np.zeros((4, 3)), [0, 1, 2, 0])
    clf = UUDirectionClassifier(shots=None).fit(X, [0, 1])
    match = r"^X='<3 features>' is invalid: 2 features, as in fit$"
    with pytest.raises(ParameterError, match=match):
        clf.predict(np.zeros((1, 3)))
    with pytest.raises(ParameterError, match=r"^y='<values \[0, 3\]>' is invalid: 0, 1 or 2$"):
        UUDirectionClassifier().fit(X, [0, 3])
    with pytest.raises(ParameterError, match="^angle_map='cos' is invalid"):
        UUDirectionClassifier(angle_map="cos").fit(X, [0, 1])
    with pytest.raises(ParameterError, match="^straight_margin=1.5 is invalid"):
        UUDirectionClassifier(straight_margin=1.5).fit(X, [0, 1])
    with pytest.raises(InputError, match="^X: no samples to fit$"):
        UUDirectionClassifier().fit(np.zeros((0, 2)), np.zeros(0, int))
    empty = "^training data: no frame has both lane lines .*nothing to train on$"
    with pytest.raises(InputError, match=empty):
        UUDirectionClassifier().fit(np.full((2, 2), np.nan), [0, 1])
    # nothing to train: a fixed rule fits on any rows, and predicts the majority for NaN rows
    rule_only = fixed(0.0).fit(np.full((3, 2), np.nan), [2, 2, 0])
    assert rule_only.predict([[np.nan, 0.0], [0.0, np.pi]]).tolist() == [2, 2]


def test_feature_columns_pick_two_columns_of_a_wider_table(rng: np.random.Generator) -> None:
    X, y = road_slopes(100, rng)
    wide = np.column_stack([rng.normal(size=100), X, rng.normal(size=100)])
    a = UUDirectionClassifier(shots=None).fit(X, y)
    b = UUDirectionClassifier(shots=None, feature_columns=(1, 2)).fit(wide, y)
    np.testing.assert_array_equal(a.predict(X), b.predict(wide))
    assert b.n_features_in_ == 4
    with pytest.raises(ParameterError, match="^feature_columns=\\(1, 1\\) is invalid"):
        UUDirectionClassifier(feature_columns=(1, 1)).fit(wide, y)


def test_sklearn_compatibility(rng: np.random.Generator) -> None:
    X, y = road_slopes(150, rng)
    clf = UUDirectionClassifier(shots=None, n_centroids=180)
    assert clf.get_params()["n_centroids"] == 180
    assert clf.set_params(straight_margin=0.3).straight_margin == 0.3
    twin = clone(clf)
    assert twin.get_params() == clf.get_params() and not hasattr(twin, "centroid_")
    scores = cross_val_score(clf, X, y, cv=KFold(3, shuffle=False))
    assert scores.shape == (3,) and scores.min() >= 0.85
    assert clf.__sklearn_tags__().input_tags.allow_nan


# ---------------------------------------------------------------- training and batches under noise


def drive_slopes(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Road slopes in runs of 10 frames (like a drive), a few missing lines."""
    rng = np.random.default_rng(seed)
    y = np.repeat(rng.integers(0, 3, n // 10 + 1), 10)[:n]
    spread = rng.uniform(0.8, 1.2, n)
    shift = np.select([y == 0, y == 2], [1.0, -1.0], 0.0) * rng.uniform(0.3, 0.9, n)
    X = np.stack([-spread + shift, spread + shift], axis=1) + rng.normal(0, 0.3, (n, 2))
    X[rng.choice(n, n // 20, replace=False), rng.integers(0, 2)] = np.nan
    return X, y


def test_grid_search_under_noise_scores_each_cell_like_predict() -> None:
    X, y = drive_slopes(90, 4)
    ok = np.all(np.isfinite(X), axis=1)
    clf = UUDirectionClassifier(shots=None).fit(X, y)
    theta = clf.slope_angles(X[ok])
    centroids, margins = np.linspace(0, 2 * np.pi, 7, endpoint=False), np.linspace(0, 0.6, 5)
    noise = NoiseSpec("amplitude-damping", 0.35, readout=0.03)
    ic, im, acc = grid_search(theta[:, 0], theta[:, 1], y[ok], centroids, margins, noise=noise)
    for i, c in enumerate(centroids):
        for j, m in enumerate(margins):
            cell = fixed(float(c), float(m)).fit(theta, y[ok])  # identity map on the angles
            assert acc[i, j] == np.mean(cell.predict(theta, noise=noise) == y[ok])
    assert acc[ic, im] == acc.max()
    # the noiseless surface differs: noise moves the probabilities
    assert not np.array_equal(
        acc, grid_search(theta[:, 0], theta[:, 1], y[ok], centroids, margins)[2]
    )


def test_train_noise_zero_strength_equals_training_without_noise() -> None:
    X, y = drive_slopes(120, 3)
    est = UUDirectionClassifier(shots=None, n_centroids=120, n_margins=51)
    plain = clone(est).fit(X, y)
    same = clone(est).set_params(train_noise=NoiseSpec("bit-flip", 0.0)).fit(X, y)
    assert same.centroid_ == pytest.approx(plain.centroid_, abs=1e-12)
    assert same.margin_ == pytest.approx(plain.margin_, abs=1e-12)
    assert same.train_accuracy_ == plain.train_accuracy_


@pytest.mark.parametrize(
    "noise", [NoiseSpec("bit-flip", 0.4), NoiseSpec("amplitude-damping", 0.6, readout=0.05)]
)
def test_training_under_noise_fits_the_noisy_circuits(noise: NoiseSpec) -> None:
    X, y = drive_slopes(120, 3)
    ok = np.all(np.isfinite(X), axis=1)
    est = UUDirectionClassifier(shots=None, n_centroids=120, n_margins=51, refine=False)
    plain = clone(est).fit(X, y)
    noisy = clone(est).set_params(train_noise=noise).fit(X, y)
    # the noiseless choice lies on the same grid, so the noisy search does at least as well
    acc_noisy = np.mean(noisy.predict(X[ok], noise=noise) == y[ok])
    assert acc_noisy >= np.mean(plain.predict(X[ok], noise=noise) == y[ok])
    assert noisy.train_accuracy_ == pytest.approx(acc_noisy, abs=1e-12)
    assert noisy.accuracy_grid_ is not None and noisy.accuracy_grid_.max() == acc_noisy
    # with the refinement, the training accuracy under noise can only rise
    refined = clone(noisy).set_params(refine=True).fit(X, y)
    assert refined.train_accuracy_ >= noisy.train_accuracy_


def test_bit_flip_training_shrinks_the_margin() -> None:
    # bit flip at p=0.4 after both gates scales P1 - P2 by (1 - 2p)**2 = 0.04
    X, y = drive_slopes(120, 3)
    plain = UUDirectionClassifier(shots=None).fit(X, y)
    noisy = UUDirectionClassifier(shots=None, train_noise=NoiseSpec("bit-flip", 0.4)).fit(X, y)
    assert noisy.margin_ < plain.margin_ * 0.2
    with pytest.raises(ParameterError, match="^train_noise='bit-flip:0.4' is invalid"):
        UUDirectionClassifier(train_noise="bit-flip:0.4").fit(X, y)


@pytest.fixture(scope="module")
def folds() -> tuple[np.ndarray, list]:
    X, y = drive_slopes(150, 5)
    parts = [np.arange(0, 50), np.arange(50, 100), np.arange(100, 150)]
    models = []
    for k, rows in enumerate(parts):
        train = np.setdiff1d(np.arange(150), rows)
        est = UUDirectionClassifier(
            shots=None, angle_map=("arctan", "minmax", "arctan")[k], n_centroids=90, n_margins=26
        )
        models.append((rows, est.fit(X[train], y[train])))
    return X, models


@pytest.mark.parametrize("channel", [*CHANNELS, None])
def test_predict_many_equals_each_predict(folds: tuple, channel: str | None) -> None:
    X, models = folds
    for p in (0.0, 0.3, 0.9):
        noise = NoiseSpec(channel, p if channel else 0.0, readout=0.04 if p == 0.3 else 0.0)
        expected = np.concatenate([est.predict(X[rows], noise=noise) for rows, est in models])
        got = UUDirectionClassifier.predict_many(models, X, noise=noise)
        np.testing.assert_array_equal(got, expected)
    assert UUDirectionClassifier.predict_many([], X).shape == (0,)


def test_predict_many_shots_noise_and_bad_models(folds: tuple) -> None:
    X, models = folds
    noise = NoiseSpec("depolarizing", 0.2)
    a = UUDirectionClassifier.predict_many(models, X, noise=noise, shots=64, rng=3)
    assert np.array_equal(
        a, UUDirectionClassifier.predict_many(models, X, noise=noise, shots=64, rng=3)
    )
    assert not np.array_equal(a, UUDirectionClassifier.predict_many(models, X, noise=noise))
    # without a noise argument the models' own noise is used, when they agree
    own = [(rows, clone(est).set_params(noise=noise)) for rows, est in models]
    for (_, twin), (_, est) in zip(own, models, strict=True):
        twin.__dict__.update({k: v for k, v in vars(est).items() if k.endswith("_")})
    np.testing.assert_array_equal(
        UUDirectionClassifier.predict_many(own, X),
        UUDirectionClassifier.predict_many(models, X, noise=noise),
    )
    own[0][1].noise = None
    with pytest.raises(ParameterError, match="noise settings differ"):
        UUDirectionClassifier.predict_many(own, X)
    with pytest.raises(ParameterError, match=r"^models\[0\]='<str>' is invalid"):
        UUDirectionClassifier.predict_many([(np.arange(3), "model")], X)
    with pytest.raises(NotFittedError):
        UUDirectionClassifier.predict_many([(np.arange(3), UUDirectionClassifier())], X)
    with pytest.raises(ParameterError, match="^shots=0 is invalid"):
        UUDirectionClassifier.predict_many(models, X, shots=0)


def test_train_noise_is_saved_by_label_in_model_headers() -> None:
    # model files keep estimator parameters as JSON (noise models by their label); the
    # fitted arrays' round trip is tested with the model files themselves
    from qdcnn.direction.model import _params_from_json, _params_to_json

    noise = NoiseSpec("phase-damping", 0.25, readout=0.01)
    params = UUDirectionClassifier(shots=None, train_noise=noise).get_params()
    header = json.loads(json.dumps(_params_to_json(params)))
    assert header["train_noise"] == {"noise": "phase-damping:0.25,readout:0.01"}
    back = UUDirectionClassifier().set_params(**_params_from_json(header))
    assert back.get_params() == params


@pytest.mark.parametrize(
    ("shots", "noise"), [(None, None), (1024, None), (1024, NoiseSpec("depolarizing", 0.2))]
)
def test_each_row_is_decided_as_if_alone(
    rng: np.random.Generator, shots: int | None, noise: NoiseSpec | None
) -> None:
    X, y = road_slopes(60, rng)
    X[:3, 1] = np.nan
    clf = UUDirectionClassifier(shots=shots, seed=5, noise=noise).fit(X, y)
    alone = [clf.predict_with_proba(X[i : i + 1]) for i in range(len(X))]
    labels, proba = clf.predict_with_proba_each(X)
    np.testing.assert_array_equal(labels, np.concatenate([a[0] for a in alone]))
    np.testing.assert_array_equal(proba, np.concatenate([a[1] for a in alone]))
    rows = np.concatenate([clf.circuit_probabilities(X[i : i + 1]) for i in range(len(X))])
    np.testing.assert_array_equal(clf.circuit_probabilities_each(X), rows)
    if shots is not None:  # one call on all rows shares one stream: not what a row gets alone
        assert not np.array_equal(clf.circuit_probabilities(X)[3:], rows[3:])
