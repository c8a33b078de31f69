"""Contiguous folds, majority baseline and result bookkeeping of the evaluation harness."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from qdcnn.config import GroupingConfig, PipelineConfig
from qdcnn.errors import InputError, ParameterError
from qdcnn.experiments.evaluate import (
    QUANTUM_METHODS,
    contiguous_folds,
    evaluate_features,
    majority_accuracy,
    make_classifier,
    summarise,
)


@pytest.mark.parametrize(("n", "k", "gap"), [(100, 5, 0), (103, 4, 5), (50, 10, 2)])
def test_folds_are_contiguous_cover_everything_and_respect_the_gap(
    n: int, k: int, gap: int
) -> None:
    folds = contiguous_folds(n, k, gap)
    assert len(folds) == k
    tests = np.concatenate([t for _, t in folds])
    np.testing.assert_array_equal(np.sort(tests), np.arange(n))
    for train, test in folds:
        np.testing.assert_array_equal(test, np.arange(test[0], test[-1] + 1))  # one block
        dist = np.min(np.abs(train[:, None] - test[None, :]), axis=1)
        assert dist.min() > gap  # no training frame within `gap` of the test block
        assert len(train) + len(test) + min(gap, test[0]) + min(gap, n - 1 - test[-1]) == n


def test_bad_fold_counts() -> None:
    with pytest.raises(ParameterError, match="folds=1 is invalid"):
        contiguous_folds(10, 1)
    with pytest.raises(ParameterError, match="folds=11 is invalid"):
        contiguous_folds(10, 11)


def test_majority_baseline_uses_training_majority() -> None:
    assert majority_accuracy(np.array([0, 0, 1]), np.array([0, 1, 1, 1])) == 0.25


def test_summarise_known_answer() -> None:
    y = np.array([0, 0, 1, 1, 2, 2])
    preds = [(np.array([0, 1, 2]), np.array([0, 1, 1])), (np.array([3, 4, 5]), np.array([1, 2, 0]))]
    r = summarise(
        "image-split-uu", "toy", y, preds, [0.5, 0.0], frames_without_lines=1, seconds=0.1
    )
    assert r.accuracy == pytest.approx((2 / 3 + 2 / 3) / 2)
    assert r.confusion == [[1, 1, 0], [0, 2, 0], [1, 0, 1]]
    assert r.per_class["left"]["recall"] == 0.5
    assert r.majority_baseline == 0.25
    assert set(r.to_dict()) >= {
        "method",
        "dataset",
        "n",
        "accuracy",
        "accuracy_std",
        "per_class",
        "confusion",
        "majority_baseline",
        "frames_without_lines",
        "seconds",
    }


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


def test_paper_has_six_quantum_methods() -> None:
    assert len(QUANTUM_METHODS) == 6
    assert {k for _, k in QUANTUM_METHODS.values()} == {"uu", "vqc"}


def test_paper_mode_keeps_the_paper_grids_and_reads_all_columns() -> None:
    uu, uu_grid = make_classifier("uu", PipelineConfig())
    assert uu.get_params()["feature_columns"] is None
    assert uu_grid == {"angle_map": ["arctan", "minmax"]}
    vqc, vqc_grid = make_classifier("vqc", PipelineConfig())
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
    uu, uu_grid = make_classifier("uu", cfg)
    assert uu.get_params()["feature_columns"] == columns
    assert uu_grid == {"angle_map": ["arctan", "minmax"]}
    vqc, grid = make_classifier("vqc", cfg)
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
