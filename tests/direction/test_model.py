"""Direction model files: data only, round trips exactly, refuses what is not one."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest

from qdcnn.config import PipelineConfig
from qdcnn.direction.model import DirectionModel, train_direction_model
from qdcnn.errors import InputError
from qdcnn.persistence import load_model, save_model


def slopes(n: int = 120, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    y = np.repeat([0, 1, 2, 1], n // 4)
    shift = np.array([-0.6, 0.0, 0.6])[y]
    X = np.column_stack([-1.0 + shift, 1.0 + shift]) + rng.normal(0, 0.08, (y.size, 2))
    X[::17] = np.nan  # frames without lines
    return X, y


@pytest.mark.parametrize("method", ["image-split-uu", "kmeans-vqc"])
def test_round_trip_predicts_the_same(method: str, tmp_path: Path) -> None:
    X, y = slopes()
    cfg = PipelineConfig(seed=3).with_lane_options(features="slopes", edges="rgb")
    model = train_direction_model(method, X, y, cfg, "toy", inner_folds=2, gap=2)
    path = model.save(tmp_path / "m.safetensors")
    back = DirectionModel.load(path)
    assert back.method == method and back.config == cfg and back.trained_on == "toy"
    assert back.summary == model.summary
    np.testing.assert_array_equal(back.predict(X), model.predict(X))
    np.testing.assert_allclose(back.predict_proba(X), model.predict_proba(X), atol=0)
    assert back.estimator.get_params() == model.estimator.get_params()
    # one call for both (one circuit run where the estimator offers it) gives the same values
    labels, proba = back.predict_with_proba(X)
    np.testing.assert_array_equal(labels, model.predict(X))
    np.testing.assert_allclose(proba, model.predict_proba(X), atol=0)


def test_a_pickled_model_is_refused_and_never_run(tmp_path: Path) -> None:
    marker = tmp_path / "pwned"

    class Payload:
        def __reduce__(self):
            return (Path.touch, (marker,))

    path = tmp_path / "old-model.pkl"
    path.write_bytes(pickle.dumps({"kind": "qdcnn-direction-model", "x": Payload()}))
    with pytest.raises(InputError, match="pickle-based file .* never loaded"):
        DirectionModel.load(path)
    assert not marker.exists()


def test_damaged_headers_are_named(tmp_path: Path) -> None:
    X, y = slopes()
    path = train_direction_model(
        "image-split-uu", X, y, PipelineConfig(), "toy", inner_folds=0
    ).save(tmp_path / "m.safetensors")
    header, arrays = load_model(path, "qdcnn-direction-model", {2})

    def rewrite(meta: dict, arrays: dict, name: str) -> Path:
        return save_model(tmp_path / name, "qdcnn-direction-model", 2, meta, arrays)

    bad_method = rewrite({**header.meta, "method": "best"}, arrays, "a.safetensors")
    with pytest.raises(
        InputError, match="a.safetensors: model settings are invalid: method='best'"
    ):
        DirectionModel.load(bad_method)
    bad_config = {**header.meta, "config": {**header.meta["config"], "seed": -4}}
    with pytest.raises(InputError, match="b.safetensors: model settings are invalid: seed=-4"):
        DirectionModel.load(rewrite(bad_config, arrays, "b.safetensors"))
    missing = {k: v for k, v in arrays.items() if k != "centroid_"}
    with pytest.raises(InputError, match="fitted attribute 'centroid_' has no array"):
        DirectionModel.load(rewrite(header.meta, missing, "c.safetensors"))
    extra_attr = {
        **header.meta,
        "state": {"attributes": {**header.meta["state"]["attributes"], "predict": "float"}},
    }
    with pytest.raises(InputError, match="fitted attributes are not"):
        DirectionModel.load(
            rewrite(extra_attr, {**arrays, "predict": np.zeros(1)}, "d.safetensors")
        )
    wrong_shape = {**arrays, "centroid_": np.zeros(3)}
    with pytest.raises(InputError, match="fitted attribute 'centroid_' is damaged"):
        DirectionModel.load(rewrite(header.meta, wrong_shape, "e.safetensors"))
    other_classes = {**header.meta, "classes": ["left", "right"]}
    with pytest.raises(InputError, match=r"g.safetensors: the model's classes \['left', 'right'\]"):
        DirectionModel.load(rewrite(other_classes, arrays, "g.safetensors"))
    with pytest.raises(InputError, match="holds a 'qdcnn-shadow-model'"):
        save_model(tmp_path / "f.safetensors", "qdcnn-shadow-model", 1, {}, {})
        DirectionModel.load(tmp_path / "f.safetensors")


def test_a_cnn_direction_model_round_trips(tmp_path: Path) -> None:
    pytest.importorskip("torch")
    from qdcnn.direction.methods import TrainingOptions

    rng = np.random.default_rng(0)
    images = rng.integers(0, 255, (24, 40, 80, 3), dtype=np.uint8)
    y = np.repeat([0, 1, 2], 8)
    options = TrainingOptions(epochs=1, threads=1, params={"val_fraction": 0.0, "batch_size": 8})
    model = train_direction_model(
        "dnn-pilotnet", images, y, PipelineConfig(), "toy", inner_folds=0, options=options
    )
    back = DirectionModel.load(model.save(tmp_path / "cnn.safetensors"))
    np.testing.assert_allclose(back.predict_proba(images), model.predict_proba(images), atol=1e-6)
    assert back.estimator.history_ == model.estimator.history_
