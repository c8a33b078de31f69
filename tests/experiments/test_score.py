"""``run_score``: a saved or built-in direction model's scores on labelled data."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from qdcnn.data.frames import load_frameset
from qdcnn.direction.features import compute_features
from qdcnn.direction.model import KIND, DirectionModel
from qdcnn.direction.scores import block_bootstrap, block_length, score
from qdcnn.errors import InputError, ParameterError
from qdcnn.experiments.score import ScoreSpec, run_score
from qdcnn.experiments.train_direction import TrainDirectionSpec, train_direction
from qdcnn.persistence import load_model, save_model
from qdcnn.runtime.reporting import Collector

TRAIN, TEST = "synthetic:track2:200", "synthetic:track2:120"


@pytest.fixture(scope="module")
def model_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A lane model trained by train-direction on the seed-0 drive."""
    out = tmp_path_factory.mktemp("score") / "uu.safetensors"
    return train_direction(TrainDirectionSpec(TRAIN, out, inner_folds=2)).path


def by_hand(model_file: Path, dataset: str, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Labels and the model's predictions of ``dataset``, computed without the runner."""
    model = DirectionModel.load(model_file)
    frames = load_frameset(dataset, seed=seed)
    assert model.grouping is not None
    table = compute_features(frames, model.config, (model.grouping,))
    keep = table.readable
    truth = frames.labels(model.config.labels)[keep]
    return truth, model.predict(table.features[model.grouping][keep])


def test_scores_on_another_seeds_drive_equal_those_computed_by_hand(model_file: Path) -> None:
    collector = Collector()
    result = run_score(ScoreSpec((TEST,), model_file, seed=1, resamples=200), collector)
    truth, predictions = by_hand(model_file, TEST, seed=1)
    (row,) = result.rows
    assert row.scores == score(truth, predictions)
    block = block_length(truth, predictions)
    assert row.block == block
    for metric in ("balanced_accuracy", "accuracy", "macro_f1"):
        expected = block_bootstrap(truth, predictions, metric, block=block, resamples=200, seed=1)
        assert row.intervals[metric] == expected
    assert result.exit_code == 0 and not collector.failures
    assert collector.results == [row.to_dict(str(model_file))]


def test_each_row_carries_the_metrics_the_intervals_and_the_model(model_file: Path) -> None:
    result = run_score(ScoreSpec((TEST,), model_file, seed=1, resamples=100))
    d = result.rows[0].to_dict(result.model_name)
    assert d["dataset"] == TEST and d["model"] == str(model_file) and d["n"] == 120
    for key in ("accuracy", "balanced_accuracy", "macro_f1", "per_class", "confusion"):
        assert key in d
    low, high = d["balanced_accuracy_ci"]
    assert low <= d["balanced_accuracy"] <= high
    assert len(d["accuracy_ci"]) == 2 and d["resamples"] == 100 and d["block"] >= 11
    assert d["labels"]["steering_unit"] == "norm" and d["skipped_frames"] == 0
    summary = result.summary()
    assert summary["summary"] is True and summary["n_datasets"] == 1 and summary["n_failed"] == 0


def test_a_dataset_of_one_class_has_no_balanced_accuracy_and_the_others_are_kept(
    model_file: Path,
) -> None:
    # threshold 0.99 of steering in [-1, 1]: every frame is straight
    spec = ScoreSpec((TEST, "synthetic:track1:60"), model_file, seed=1, label_threshold=0.99)
    result = run_score(spec)
    assert result.exit_code == 0 and len(result.rows) == 2
    for row in result.rows:
        d = row.to_dict(result.model_name)
        assert d["balanced_accuracy"] is None and d["balanced_accuracy_ci"] is None
        assert d["undefined"].endswith("test labels are 'straight'")
        assert d["accuracy_ci"] is not None
        assert d["labels"]["label_threshold"] == 0.99


def test_too_few_frames_for_two_blocks_give_scores_without_intervals(model_file: Path) -> None:
    (row,) = run_score(ScoreSpec(("synthetic:track2:20",), model_file, seed=1)).rows
    assert row.scores.n == 20 and row.block is None
    assert set(row.intervals.values()) == {None}
    assert row.interval_note is not None and "too few" in row.interval_note


def test_a_dataset_that_cannot_be_loaded_is_a_failure_and_the_others_are_scored(
    model_file: Path, tmp_path: Path
) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    collector = Collector()
    result = run_score(ScoreSpec((f"udacity:{empty}", TEST), model_file, seed=1), collector)
    assert result.exit_code == 1
    assert [row.dataset for row in result.rows] == [TEST]
    assert [f.file for f in result.failures] == [f"udacity:{empty}"]
    assert "empty folder" in collector.failures[0].error


def test_a_missing_recording_stops_the_run_before_anything_is_scored(model_file: Path) -> None:
    collector = Collector()
    with pytest.raises(InputError, match="nope: file not found"):
        run_score(ScoreSpec((TEST, "udacity:/nope"), model_file), collector)
    assert collector.results == []


def test_missing_corrupt_and_foreign_model_files_are_refused(
    model_file: Path, tmp_path: Path
) -> None:
    with pytest.raises(InputError, match="file not found"):
        run_score(ScoreSpec((TEST,), tmp_path / "none.safetensors"))
    corrupt = tmp_path / "corrupt.safetensors"
    corrupt.write_bytes(b"not a model at all")
    with pytest.raises(InputError, match=str(corrupt)):
        run_score(ScoreSpec((TEST,), corrupt))
    header, arrays = load_model(model_file, KIND, {2})
    foreign = tmp_path / "foreign.safetensors"
    save_model(foreign, KIND, 2, {**header.meta, "classes": ["left", "right"]}, arrays)
    with pytest.raises(InputError, match=r"classes \['left', 'right'\] are not"):
        run_score(ScoreSpec((TEST,), foreign))


def test_bad_specs_are_refused_before_anything_runs() -> None:
    with pytest.raises(ParameterError):
        ScoreSpec(())
    with pytest.raises(ParameterError):
        ScoreSpec(("video:x.mp4",))
    with pytest.raises(ParameterError):
        ScoreSpec((TEST,), block=3)
    with pytest.raises(ParameterError):
        ScoreSpec((TEST,), steering_unit="furlongs")


@pytest.mark.slow
@pytest.mark.base
def test_without_a_model_or_torch_the_built_in_lane_model_decides(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr("qdcnn.direction.builtin.has_torch", lambda: False)
    collector = Collector()
    result = run_score(ScoreSpec(("synthetic:track1:60",), resamples=50), collector)
    assert result.model_name.startswith("built-in lane model image-split-uu trained on ")
    assert result.rows[0].to_dict(result.model_name)["model"] == result.model_name
    assert f"no --model: model: {result.model_name}" in collector.notes


def test_without_a_model_the_built_in_qdcnn_model_decides_with_torch() -> None:
    pytest.importorskip("torch")
    collector = Collector()
    result = run_score(ScoreSpec(("synthetic:track1:60",), resamples=50), collector)
    assert result.model_name.startswith("built-in qdcnn-head (trained on udacity-lake-track")
    assert result.rows[0].to_dict(result.model_name)["model"] == result.model_name
    assert f"no --model: model: {result.model_name}" in collector.notes


@pytest.mark.slow
def test_a_frame_model_reads_frames_of_another_size(tmp_path: Path) -> None:
    pytest.importorskip("torch")
    from qdcnn.data.frames import stack_images
    from qdcnn.direction.methods import TrainingOptions

    out = tmp_path / "cnn.safetensors"
    training = TrainingOptions(epochs=1, threads=1)
    spec = TrainDirectionSpec("synthetic:track2:60", out, "dnn-pilotnet", inner_folds=0)
    train_direction(replace(spec, training=training))
    dashcam = "synthetic:dashcam:30"  # 640x480 frames; the model trained on 320x160
    (row,) = run_score(ScoreSpec((dashcam,), out, seed=1)).rows
    model = DirectionModel.load(out)
    frames = load_frameset(dashcam, seed=1)
    images, readable, _ = stack_images(frames)
    truth = frames.labels(model.config.labels)[readable]
    assert row.scores == score(truth, model.predict(images[readable]))
