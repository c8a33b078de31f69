"""run_evaluation and evaluate_features: every method through the one protocol."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from qdcnn.config import GroupingConfig, PipelineConfig
from qdcnn.direction.methods import get_method
from qdcnn.errors import InputError, ParameterError
from qdcnn.experiments.evaluate import EvaluationSpec, evaluate_features, run_evaluation
from qdcnn.runtime.reporting import Collector


def test_evaluate_learns_separable_features(rng: np.random.Generator) -> None:
    # slopes that follow the road geometry: left bends tilt both lines one way, right the other
    y = np.repeat([0, 1, 2, 1, 0, 2, 1, 2, 0, 1], 30)
    shift = np.array([-0.6, 0.0, 0.6])[y]
    X = np.column_stack([-1.0 + shift, 1.0 + shift]) + rng.normal(0, 0.08, (y.size, 2))
    # the 4-weight VQC cannot fit this as well as the geometric UU rule; both beat chance (1/3)
    for method, floor in (("image-split-uu", 0.9), ("image-split-vqc", 0.6)):
        r = evaluate_features(method, "toy", X, y, folds=5, gap=2)
        assert r.accuracy > floor, method
        assert len(r.extra["chosen_hyperparameters"]) == 5


def test_single_class_labels_are_an_error() -> None:
    with pytest.raises(InputError, match="all 20 labels are 'straight'"):
        evaluate_features("kmeans-vqc", "flat", np.zeros((20, 2)), np.ones(20, np.int64))


def test_paper_mode_keeps_the_paper_grids_and_reads_all_columns() -> None:
    uu, uu_grid = get_method("image-split-uu").estimator(PipelineConfig())
    assert uu.get_params()["feature_columns"] is None
    assert uu_grid == {"angle_map": ["arctan", "minmax"]}
    vqc, vqc_grid = get_method("image-split-vqc").estimator(PipelineConfig())
    assert vqc.get_params()["feature_columns"] is None and vqc.get_params()["restarts"] == 1
    assert vqc_grid == {"interpret": ["min2", "mod3"]}


@pytest.mark.parametrize(
    ("mode", "extras", "columns"),
    [
        ("slopes", ("angles",), (0, 1)),
        ("far-offsets", ("far-offsets",), (2, 3)),
        ("road-centre", ("intercepts", "road-centre"), (4, 5)),
        ("vanishing-points", ("near-vanishing-point-offset", "vanishing-point-offset"), (3, 2)),
    ],
)
def test_other_modes_pick_their_columns_and_widen_the_vqc_grid(
    mode: str, extras: tuple[str, ...], columns: tuple[int, int]
) -> None:
    cfg = replace(PipelineConfig(), grouping=GroupingConfig(features=mode, extra_features=extras))
    uu, uu_grid = get_method("kmeans-uu").estimator(cfg)
    assert uu.get_params()["feature_columns"] == columns
    assert uu_grid == {"angle_map": ["arctan", "minmax"]}
    vqc, grid = get_method("kmeans-vqc").estimator(cfg)
    assert vqc.get_params()["feature_columns"] == columns
    if mode == "slopes":
        assert grid == {"interpret": ["min2", "mod3"]}
    else:
        assert vqc.get_params()["restarts"] == 3
        assert grid == {
            "interpret": ["min2", "mod3"],
            "angle_span": [1.0, 0.5],
            "feature_map_reps": [1, 2],
        }


def test_mode_needs_its_extras() -> None:
    with pytest.raises(ParameterError, match="to include \\('road-centre',\\)"):
        GroupingConfig(features="road-centre")
    with pytest.raises(ParameterError, match="grouping.features='curvature' is invalid"):
        GroupingConfig.for_features("curvature")


def test_evaluation_reads_only_the_mode_columns(rng: np.random.Generator) -> None:
    # the slopes are noise; the road-centre columns carry the direction (the far centre
    # moves with the bend, the near one stays in front of the car; UU compares the two)
    y = np.repeat([0, 1, 2, 1, 0, 2, 1, 2, 0, 1], 30)
    shift = np.array([-0.3, 0.0, 0.3])[y]
    centre = np.column_stack([shift, 0.0 * shift]) + rng.normal(0, 0.03, (y.size, 2))
    X = np.column_stack([rng.normal(0, 1, (y.size, 2)), centre])
    cfg = replace(PipelineConfig(), grouping=GroupingConfig.for_features("road-centre"))
    paper = evaluate_features("image-split-uu", "toy", X[:, :2], y, folds=5, gap=2)
    mode = evaluate_features("image-split-uu", "toy", X, y, config=cfg, folds=5, gap=2)
    assert paper.accuracy < 0.6 < 0.9 < mode.accuracy


def test_run_evaluation_reports_each_method_as_it_finishes(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    spec = EvaluationSpec(
        "synthetic:track2:120", "image-split-uu,kmeans-uu", folds=3, gap=2, has_torch=False
    )
    collected = Collector()
    result = run_evaluation(spec, collected)
    assert [r.method for r in result.results] == ["image-split-uu", "kmeans-uu"]
    assert [r["method"] for r in collected.results] == ["image-split-uu", "kmeans-uu"]
    assert result.exit_code == 0 and result.n_frames == 120
    first = result.results[0]
    assert first.n == 120 and len(first.fold_accuracies) == 3
    # pooled accuracy: correct test frames over all test frames
    correct = sum(first.confusion[i][i] for i in range(3))
    assert first.accuracy == pytest.approx(correct / 120)
    json.dumps(result.to_dict())  # plain JSON values only


def test_run_evaluation_all_without_torch_notes_what_it_left_out(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    spec = EvaluationSpec("synthetic:track2:200", "all", folds=2, gap=2, has_torch=False)
    collected = Collector()
    result = run_evaluation(spec, collected)
    assert len(result.results) == 8  # six paper lane methods, hog-logreg and lines-logreg
    assert any("skipping dnn-pilotnet: torch is not installed" in n for n in collected.notes)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"gap": -1}, "gap=-1 is invalid"),
        ({"folds": 1}, "folds=1 is invalid"),
        ({"inner_folds": 1}, "inner_folds=1 is invalid"),
        ({"gap": True}, "gap=True is invalid"),
    ],
)
def test_spec_refuses_dishonest_protocols(changes, message) -> None:
    with pytest.raises(ParameterError, match=message):
        EvaluationSpec("synthetic:track2:120", **changes)


def test_a_gap_as_long_as_a_fold_is_refused(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    spec = EvaluationSpec("synthetic:track2:100", "image-split-uu", folds=5, gap=20)
    with pytest.raises(
        ParameterError, match="gap=20 is invalid: smaller than the shortest test block"
    ):
        run_evaluation(spec)


@pytest.mark.slow
def test_folds_on_a_local_dask_cluster_give_the_same_scores(tmp_path, monkeypatch) -> None:
    pytest.importorskip("distributed")
    from qdcnn.experiments.noise.runner import NoiseSweepSpec, run_noise_sweep

    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    spec = EvaluationSpec("synthetic:track2:200", "image-split-uu,kmeans-vqc", folds=3, gap=2)
    here = run_evaluation(spec)
    there = run_evaluation(replace(spec, scheduler="local:2"))
    for a, b in zip(here.results, there.results, strict=True):
        assert a.confusion == b.confusion
        assert a.extra["chosen_hyperparameters"] == b.extra["chosen_hyperparameters"]
    sweep = NoiseSweepSpec(
        data="synthetic:track2:200",
        methods=("uu",),
        channels=("bit-flip", "depolarizing"),
        strengths=(0.0, 0.5),
        folds=3,
    )
    rows = run_noise_sweep(sweep).to_dicts()
    assert run_noise_sweep(replace(sweep, scheduler="local:2")).to_dicts() == rows


def test_a_scheduler_that_does_not_answer_is_a_one_line_error(tmp_path, monkeypatch) -> None:
    pytest.importorskip("distributed")
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    spec = EvaluationSpec(
        "synthetic:track2:200", "image-split-uu", folds=3, scheduler="tcp://127.0.0.1:9"
    )
    with pytest.raises(InputError, match="127.0.0.1:9"):
        run_evaluation(spec)
