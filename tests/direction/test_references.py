"""The classical references hog-logreg and lines-logreg: registered, honest, saved data-only."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from sklearn.linear_model import LogisticRegression
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from typer.testing import CliRunner

from qdcnn.cli import app
from qdcnn.config import PipelineConfig
from qdcnn.data.frames import load_frameset, stack_images
from qdcnn.data.labels import DIRECTIONS
from qdcnn.direction.methods import get_method, select_methods
from qdcnn.direction.model import DirectionModel, train_direction_model
from qdcnn.direction.references import (
    C_GRID,
    HOGLogisticClassifier,
    LinesLogisticClassifier,
    hog_rows,
)
from qdcnn.errors import InputError, ParameterError
from qdcnn.experiments.evaluate import EvaluationSpec, run_evaluation

runner = CliRunner()


def _lane_table(rng: np.random.Generator, n: int = 90) -> tuple[np.ndarray, np.ndarray]:
    """Slopes that lean with the direction, some lines missing."""
    y = np.repeat([0, 1, 2], n // 3)
    lean = np.array([-1.0, 0.0, 1.0])[y]
    X = np.column_stack([lean - 1 + rng.normal(0, 0.4, n), lean + 1 + rng.normal(0, 0.4, n)])
    X[rng.random(n) < 0.1, 0] = np.nan
    return X, y


def test_both_are_registered_classical_methods_with_a_c_grid() -> None:
    hog, lines = get_method("hog-logreg"), get_method("lines-logreg")
    assert (hog.inputs, hog.grouping) == ("frames", None)
    assert (lines.inputs, lines.grouping) == ("lanes", "image-split")
    for m in (hog, lines):
        assert not (m.quantum or m.needs_torch or m.needs_gpu)
        _, grid = m.estimator(PipelineConfig())
        assert grid == {"C": list(C_GRID)}
    chosen, notes = select_methods("all", has_torch=False, has_gpu=False)
    assert {"hog-logreg", "lines-logreg"} <= {m.name for m in chosen}
    assert not any("logreg" in n for n in notes)


@pytest.mark.parametrize("name", ["hog-logreg", "lines-logreg"])
def test_noise_sweeps_refuse_them_as_they_have_no_circuit(name: str) -> None:
    from qdcnn.experiments.noise.options import parse_methods

    with pytest.raises(ParameterError, match=f"methods='{name}' is invalid: a quantum method"):
        parse_methods(name)
    assert name not in parse_methods("all")


def test_lines_predictions_are_those_of_the_sklearn_pipeline(rng: np.random.Generator) -> None:
    X, y = _lane_table(rng)
    clf = LinesLogisticClassifier(C=0.1).fit(X, y)
    table = clf.features(X)
    filled = np.where(np.isnan(table), np.nanmean(table, axis=0), table)
    reference = make_pipeline(
        StandardScaler(), LogisticRegression(C=0.1, class_weight="balanced", max_iter=3000)
    ).fit(filled, y)
    np.testing.assert_array_equal(clf.predict(X), reference.predict(filled))
    np.testing.assert_allclose(clf.predict_proba(X), reference.predict_proba(filled), atol=1e-10)
    assert table.shape == (90, 4)  # two slopes, then their missing flags


def test_two_training_classes_give_three_probability_columns(rng: np.random.Generator) -> None:
    X, y = _lane_table(rng)
    keep = y != 1
    clf = LinesLogisticClassifier(C=1.0).fit(X[keep], y[keep])
    proba = clf.predict_proba(X)
    assert proba.shape == (90, 3) and np.allclose(proba[:, 1], 0) and np.allclose(proba.sum(1), 1)
    assert set(clf.predict(X)) <= {0, 2}
    np.testing.assert_array_equal(clf.predict(X), np.array([0, 2])[proba[:, [0, 2]].argmax(1)])


def test_hog_reads_any_frame_size_and_grey_frames(rng: np.random.Generator) -> None:
    small = rng.integers(0, 255, (2, 48, 64, 3), dtype=np.uint8)
    large = rng.integers(0, 255, (2, 240, 320, 3), dtype=np.uint8)
    grey = small[..., 0]
    width = 8 * (128 // 8) * (40 // 8)
    assert hog_rows(small).shape == hog_rows(large).shape == hog_rows(grey).shape == (2, width)


def test_hog_rows_are_the_studies_recipe_and_remembered(rng: np.random.Generator) -> None:
    """The band, size and bins of benchmarks/direction_study.py (rows 60-139 of a 160-row
    frame, 128 x 40, 8 bins), resized by area as in benchmarks/lane_study.py."""
    import cv2
    from skimage.feature import hog

    frames = rng.integers(0, 255, (3, 160, 320, 3), dtype=np.uint8)
    expected = [
        hog(
            cv2.resize(
                cv2.cvtColor(f, cv2.COLOR_RGB2GRAY)[60:140], (128, 40), interpolation=cv2.INTER_AREA
            ),
            orientations=8,
            pixels_per_cell=(8, 8),
            cells_per_block=(1, 1),
        )
        for f in frames
    ]
    np.testing.assert_array_equal(hog_rows(frames), expected)
    np.testing.assert_array_equal(hog_rows(frames), expected)  # from the cache


@pytest.mark.parametrize(
    ("estimator", "inputs", "message"),
    [
        (HOGLogisticClassifier(), np.zeros((2, 8, 8, 4), np.uint8), r"X='<array of shape \(2, 8, "),
        (HOGLogisticClassifier(), np.zeros((8, 8), np.uint8), "frames \\(N, H, W, 3\\)"),
        (HOGLogisticClassifier(), np.zeros((2, 8, 8, 3)), "uint8 pixels"),
        (HOGLogisticClassifier(band=(0.8, 0.2)), np.zeros((2, 8, 8, 3), np.uint8), "top < bottom"),
        (LinesLogisticClassifier(), np.zeros(4), "a 2-D table"),
        (LinesLogisticClassifier(), [["a", "b"]], "a numeric table"),
        (LinesLogisticClassifier(C=0.0), np.zeros((2, 2)), "C=0.0 is invalid"),
    ],
)
def test_bad_inputs_give_one_line_errors(estimator, inputs, message) -> None:
    with pytest.raises(ParameterError, match=message) as info:
        estimator.fit(inputs, np.zeros(len(inputs), int))
    assert "\n" not in str(info.value)


def test_fitted_estimators_check_what_they_are_given(rng: np.random.Generator) -> None:
    X, y = _lane_table(rng)
    clf = LinesLogisticClassifier().fit(X, y)
    with pytest.raises(ParameterError, match="X='<3 columns>' is invalid: 2 columns, as in fit"):
        clf.predict(np.zeros((1, 3)))
    one = LinesLogisticClassifier().fit(X, np.full(len(y), 2))
    assert set(one.predict(X)) == {2} and np.allclose(one.predict_proba(X)[:, 2], 1)
    with pytest.raises(InputError, match="no samples to fit"):
        LinesLogisticClassifier().fit(np.zeros((0, 2)), np.zeros(0, int))


@pytest.fixture(scope="module")
def track2_frames() -> tuple[np.ndarray, np.ndarray]:
    frames = load_frameset("synthetic:track2:60")
    images, readable, _ = stack_images(frames)
    return images[readable], frames.labels()[readable]


def test_a_saved_hog_model_predicts_as_before(tmp_path: Path, track2_frames) -> None:
    images, y = track2_frames
    model = train_direction_model("hog-logreg", images, y, PipelineConfig(), "synthetic:track2:60")
    assert model.summary["chosen_hyperparameters"]["C"] in C_GRID
    loaded = DirectionModel.load(model.save(tmp_path / "hog.qdcnn"))
    assert (tmp_path / "hog.qdcnn").read_bytes()[8:9] == b"{"  # safetensors, never pickle
    np.testing.assert_array_equal(loaded.predict(images), model.predict(images))
    np.testing.assert_array_equal(loaded.predict_proba(images), model.predict_proba(images))
    assert loaded.estimator.get_params() == model.estimator.get_params()


def test_a_saved_lines_model_predicts_as_before(tmp_path: Path, rng: np.random.Generator) -> None:
    X, y = _lane_table(rng)
    model = train_direction_model("lines-logreg", X, y, PipelineConfig(), "table")
    loaded = DirectionModel.load(model.save(tmp_path / "lines.qdcnn"))
    np.testing.assert_array_equal(loaded.predict(X), model.predict(X))
    np.testing.assert_array_equal(loaded.predict_proba(X), model.predict_proba(X))
    assert loaded.predict(X[0]).shape == (1,)  # one frame's row


def test_train_direction_then_detect_lanes_gives_the_models_directions(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from qdcnn.data.images import read_image

    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    model_path = tmp_path / "hog.qdcnn"
    args = ["train-direction", "--data", "synthetic:track2:60", "--method", "hog-logreg"]
    res = runner.invoke(app, [*args, "--out", str(model_path), "--json"])
    assert res.exit_code == 0, res.stderr
    assert json.loads(res.stdout)["method"] == "hog-logreg"
    synth = tmp_path / "synth"
    res = runner.invoke(app, ["synth", "--preset", "track1", "--n", "4", "--out", str(synth)])
    assert res.exit_code == 0, res.stderr
    paths = sorted((synth / "udacity" / "IMG").glob("*"))
    out = tmp_path / "lanes"
    res = runner.invoke(
        app,
        ["detect-lanes", *map(str, paths), "--out", str(out), "--model", str(model_path), "--json"],
    )
    assert res.exit_code == 0, res.stderr
    *rows, _ = [json.loads(line) for line in res.stdout.splitlines()]
    model = DirectionModel.load(model_path)
    expected = model.predict(np.stack([read_image(p) for p in paths]))
    assert [r["direction"] for r in rows] == [DIRECTIONS[int(k)] for k in expected]


@pytest.mark.slow
def test_both_references_beat_chance_on_track2_held_out_folds() -> None:
    """Measured (5 contiguous folds, gap 5): balanced accuracy hog-logreg 0.62, lines-logreg
    0.45 against a chance level of 1/3; pooled accuracy 0.82 and 0.56 against the
    majority baseline's 0.14. With 35 straight frames of 300, a chance-level balanced
    accuracy has a spread of about 0.035, so 0.40 is about two spreads above chance."""
    spec = EvaluationSpec("synthetic:track2:300", "hog-logreg,lines-logreg", has_torch=False)
    result = run_evaluation(spec)
    scores = {r.method: r for r in result.results}
    assert set(scores) == {"hog-logreg", "lines-logreg"}
    for name, floor in (("hog-logreg", 0.55), ("lines-logreg", 0.40)):
        r = scores[name]
        confusion = np.asarray(r.confusion)
        balanced = float(np.mean(np.diag(confusion) / confusion.sum(axis=1)))
        assert balanced > floor, (name, balanced)
        assert r.accuracy > r.majority_baseline + 0.3, (name, r.accuracy)
        assert all(c["C"] in C_GRID for c in r.extra["chosen_hyperparameters"])
