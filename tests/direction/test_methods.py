"""The method registry: one entry per method, read by every command."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from sklearn.base import BaseEstimator, ClassifierMixin
from typer.testing import CliRunner

from qdcnn.cli import app
from qdcnn.config import PipelineConfig
from qdcnn.direction.methods import (
    GROUPINGS,
    DirectionMethod,
    get_method,
    method_names,
    register,
    select_methods,
    unregister,
)
from qdcnn.errors import ParameterError

runner = CliRunner()


def test_the_paper_methods_and_baselines_are_registered_once() -> None:
    *lanes, lines_reference = method_names(inputs="lanes")
    assert tuple(lanes) == tuple(f"{g}-{k}" for k in ("uu", "vqc") for g in GROUPINGS)
    assert {get_method(m).kind for m in lanes} == {"uu", "vqc"}
    assert all(get_method(m).quantum for m in lanes)
    *frames, hog_reference = method_names(inputs="frames")
    assert (lines_reference, hog_reference) == ("lines-logreg", "hog-logreg")
    assert frames[0] == "dnn-pilotnet" and frames[-1] == "dnn-resnet50"
    assert set(frames[1:-1]) == {
        f"qdcnn-{k}{t}" for k in ("head", "uuconv", "quanv") for t in ("", "-classical")
    } | {f"qdcnn-head-{a}" for a in ("noent", "fixed", "linear")}
    assert get_method("dnn-resnet50").needs_gpu and get_method("dnn-pilotnet").needs_torch


def test_unknown_method_lists_the_registered_ones() -> None:
    with pytest.raises(ParameterError, match="method='best' is invalid: one of image-split-uu, "):
        get_method("best")


def test_select_all_leaves_out_what_cannot_run_and_says_why() -> None:
    chosen, notes = select_methods("all", has_torch=True, has_gpu=False)
    names = [m.name for m in chosen]
    assert "dnn-pilotnet" in names and "dnn-resnet50" not in names
    assert notes == [
        "skipping dnn-resnet50: no GPU, and its training takes tens of core-hours on a CPU "
        "(ask for it alone: --method dnn-resnet50)"
    ]
    chosen, _ = select_methods("dnn-resnet50,kmeans-uu", has_torch=False, has_gpu=False)
    assert [m.name for m in chosen] == ["dnn-resnet50", "kmeans-uu"]


def test_a_method_needs_a_grouping_exactly_for_lane_inputs() -> None:
    with pytest.raises(ParameterError, match="grouping=None is invalid"):
        DirectionMethod("x", "lanes", lambda c, o: (None, {}), "toy")  # type: ignore[arg-type,return-value]
    with pytest.raises(ParameterError, match="a name not registered yet"):
        register(get_method("kmeans-uu"))


class SignRule(ClassifierMixin, BaseEstimator):
    """A toy direction classifier: left when the mean slope leans one way, right the other."""

    fitted_attributes = ("threshold_", "sign_", "majority_", "classes_")

    def __init__(self, band: float = 0.1) -> None:
        self.band = band

    def fit(self, X, y):
        X, y = np.asarray(X, dtype=float), np.asarray(y)
        ok = np.all(np.isfinite(X[:, :2]), axis=1)
        lean = X[ok, :2].mean(axis=1)
        self.threshold_ = float(np.median(lean))
        right = y[ok] == 2
        right_lean = lean[right].mean() if right.any() else self.threshold_
        self.sign_ = 1.0 if right_lean >= self.threshold_ else -1.0
        self.majority_ = int(np.bincount(y, minlength=3).argmax())
        self.classes_ = np.arange(3)
        return self

    def predict(self, X):
        X = np.asarray(X, dtype=float)
        d = self.sign_ * (X[:, :2].mean(axis=1) - self.threshold_)
        out = np.where(d > 0, 2, 0)
        out[np.abs(d) < self.band] = 1
        out[~np.isfinite(d)] = self.majority_
        return out


@pytest.fixture
def toy_method():
    method = register(
        DirectionMethod(
            "image-split-sign",
            "lanes",
            lambda config, options: (SignRule(), {"band": [0.05, 0.2]}),
            "toy",
            grouping="image-split",
            summary="a toy rule on the two slopes",
        )
    )
    yield method
    unregister(method.name)


def test_one_registry_entry_makes_a_method_work_in_every_command(
    toy_method: DirectionMethod, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    data = ["--data", "synthetic:track2:200"]
    res = runner.invoke(
        app, ["evaluate", *data, "--method", "image-split-sign", "--folds", "2", "--json"]
    )
    assert res.exit_code == 0, res.stderr
    row = json.loads(res.stdout)
    assert row["method"] == "image-split-sign" and len(row["chosen_hyperparameters"]) == 2
    model = tmp_path / "sign.safetensors"
    res = runner.invoke(
        app,
        ["train-direction", *data, "--method", "image-split-sign", "--out", str(model), "--json"],
    )
    assert res.exit_code == 0, res.stderr
    assert json.loads(res.stdout)["chosen_hyperparameters"]["band"] in (0.05, 0.2)
    res = runner.invoke(
        app, ["synth", "--preset", "track2", "--n", "3", "--out", str(tmp_path / "s")]
    )
    res = runner.invoke(
        app,
        [
            "detect-lanes",
            str(tmp_path / "s" / "udacity" / "IMG"),
            "--out",
            str(tmp_path / "l"),
            "--model",
            str(model),
            "--json",
        ],
    )
    assert res.exit_code == 0, res.stderr
    *rows, summary = [json.loads(line) for line in res.stdout.splitlines()]
    assert summary["method"] == "image-split-sign" and len(rows) == 3
    assert all(r["direction"] in ("left", "straight", "right") for r in rows)


def test_the_default_config_is_the_recordings_preset() -> None:
    assert PipelineConfig() == PipelineConfig.udacity() == PipelineConfig.preset("udacity")
    assert PipelineConfig.preset("paper").lanes.smoothing_iterations == 30


def test_an_inner_search_that_cannot_run_is_an_option_conflict() -> None:
    from qdcnn.direction.methods import check_inner_search
    from qdcnn.errors import OptionConflict

    check_inner_search(60, 3, 5)  # blocks of 20 frames: searched
    check_inner_search(10, 0, 1000)  # no search asked for
    with pytest.raises(OptionConflict, match=r"--inner-folds 50 and --gap 5 .*\(--folds 2\)"):
        check_inner_search(28, 50, 5, frames_from="--folds 2")
