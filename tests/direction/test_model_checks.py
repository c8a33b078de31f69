"""Tampered direction model files are refused on load, naming the file and the field."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from qdcnn.cli import app
from qdcnn.config import PipelineConfig
from qdcnn.direction.model import DirectionModel, train_direction_model
from qdcnn.errors import InputError
from qdcnn.persistence import load_model, save_model

runner = CliRunner()
KIND = "qdcnn-direction-model"


def slopes(n: int = 80) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    y = np.repeat([0, 1, 2, 1], n // 4)
    shift = np.array([-0.6, 0.0, 0.6])[y]
    X = np.column_stack([-1.0 + shift, 1.0 + shift]) + rng.normal(0, 0.08, (y.size, 2))
    return X, y


@pytest.fixture(scope="module")
def models(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("models")
    X, y = slopes()
    out = {}
    for method in ("image-split-uu", "kmeans-vqc", "lines-logreg"):
        model = train_direction_model(method, X, y, PipelineConfig(), "toy", inner_folds=0)
        out[method] = model.save(folder / f"{method}.safetensors")
    return out


def tampered(source: Path, target: Path, name: str, value: Any) -> Path:
    """``source`` with fitted attribute ``name`` set to a JSON ``value`` or an array."""
    header, arrays = load_model(source, KIND, {2})
    arrays = {k: v for k, v in arrays.items() if k != name}
    forms = dict(header.meta["state"]["attributes"])
    if isinstance(value, np.ndarray):
        arrays[name] = value
    else:
        forms[name] = {"value": value}
    meta = {**header.meta, "state": {"attributes": forms}}
    return save_model(target, KIND, 2, meta, arrays)


UU_CASES = [
    ("majority_class_", "left"),
    ("majority_class_", np.array([99])),
    ("centroid_", "abc"),
    ("centroid_", np.array([np.inf])),
    ("class_prior_", np.array([np.nan, 0.5, 0.5])),
    ("class_prior_", np.zeros(5)),
    ("angle_params_", np.array([1.0, 2.0, 3.0])),
    ("classes_", np.array([0, 1, 7])),
    ("n_features_in_", np.array([0])),
]


@pytest.mark.parametrize(("name", "value"), UU_CASES)
def test_a_tampered_uu_model_is_refused_naming_the_field(
    models: dict[str, Path], tmp_path: Path, name: str, value: Any
) -> None:
    path = tampered(models["image-split-uu"], tmp_path / "bad.safetensors", name, value)
    with pytest.raises(InputError, match=f"bad.safetensors: fitted attribute '{name}'"):
        DirectionModel.load(path)


@pytest.mark.parametrize(
    ("method", "name", "value"),
    [
        ("kmeans-vqc", "weights_", np.array([np.nan, 0.0, 0.0, 0.0])),
        ("kmeans-vqc", "weights_", np.zeros(7)),
        ("kmeans-vqc", "scaler_params_", np.full((2, 2), np.inf)),
        ("kmeans-vqc", "majority_class_", np.array([-1])),
        ("lines-logreg", "coef_", np.full((3, 2), np.nan)),
        ("lines-logreg", "coef_", np.zeros((3, 9))),
        ("lines-logreg", "classes_", "left"),
    ],
)
def test_tampered_vqc_and_reference_models_are_refused(
    models: dict[str, Path], tmp_path: Path, method: str, name: str, value: Any
) -> None:
    path = tampered(models[method], tmp_path / "bad.safetensors", name, value)
    with pytest.raises(InputError, match=f"fitted attribute '{name}'"):
        DirectionModel.load(path)


def test_untampered_models_load(models: dict[str, Path]) -> None:
    for path in models.values():
        DirectionModel.load(path)


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("drive") / "d"
    res = runner.invoke(app, ["synth", "--preset", "track2", "--n", "3", "--out", str(out)])
    assert res.exit_code == 0, res.stderr
    return out / "udacity"


def command(name: str, drive: Path, model: Path, out: Path) -> list[str]:
    if name == "detect-lanes":
        return ["detect-lanes", str(drive / "IMG"), "--out", str(out), "--model", str(model)]
    if name == "run":
        return ["run", str(drive / "IMG"), "--out", str(out), "--no-video", "--model", str(model)]
    return ["score", "--data", f"udacity:{drive}", "--model", str(model), "--json"]


@pytest.mark.parametrize("name", ["detect-lanes", "run", "score"])
@pytest.mark.parametrize(("field", "value"), UU_CASES[:3])
def test_commands_refuse_a_tampered_model_before_reading_input(
    models: dict[str, Path], drive: Path, tmp_path: Path, name: str, field: str, value: Any
) -> None:
    model = tampered(models["image-split-uu"], tmp_path / "bad.safetensors", field, value)
    out = tmp_path / "out"
    res = runner.invoke(app, command(name, drive, model, out))
    assert res.exit_code == 2, res.stderr
    assert res.stderr.startswith("error: ") and len(res.stderr.splitlines()) == 1
    assert "bad.safetensors" in res.stderr and f"'{field}'" in res.stderr
    assert res.stdout == ""
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize(
    ("method", "param", "value"),
    [
        ("image-split-uu", "shots", -5),
        ("image-split-uu", "straight_margin", 7.0),
        ("kmeans-vqc", "ansatz_reps", -1),
    ],
)
def test_out_of_range_parameters_are_refused_on_load(
    models: dict[str, Path], tmp_path: Path, method: str, param: str, value: Any
) -> None:
    header, arrays = load_model(models[method], KIND, {2})
    meta = {**header.meta, "params": {**header.meta["params"], param: value}}
    path = save_model(tmp_path / "bad.safetensors", KIND, 2, meta, arrays)
    with pytest.raises(InputError, match=f"model settings are invalid: {param}="):
        DirectionModel.load(path)
