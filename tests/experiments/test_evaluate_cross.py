"""Cross-recording evaluation, seeds, paired differences and resuming (issue 19)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from qdcnn.config import PipelineConfig
from qdcnn.data.images import write_image
from qdcnn.data.synthetic import generate_drive
from qdcnn.direction.methods import get_method
from qdcnn.direction.scores import score
from qdcnn.errors import InputError, ParameterError
from qdcnn.experiments.evaluate import (
    EvaluationSpec,
    method_seeds,
    run_evaluation,
    seed_matters,
)
from qdcnn.runtime.reporting import Collector

TRACK1, TRACK2, RAIN = "synthetic:track1:150", "synthetic:track2:150", "synthetic:rain:120"


@pytest.fixture(autouse=True)
def _cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))


def test_train_on_one_recording_and_score_each_test_recording() -> None:
    spec = EvaluationSpec(
        "", "image-split-uu,kmeans-uu", train=(TRACK2,), test=(TRACK1, RAIN), seeds=2
    )
    result = run_evaluation(spec, Collector())
    assert [(r.method, r.dataset) for r in result.results] == [
        ("image-split-uu", "synthetic-track1"),
        ("image-split-uu", "synthetic-rain"),
        ("kmeans-uu", "synthetic-track1"),
        ("kmeans-uu", "synthetic-rain"),
    ]
    assert result.trained_on == [["synthetic-track2"]]
    assert result.tested_on == ["synthetic-track1", "synthetic-rain"]
    for r in result.results:
        d = r.to_dict()
        assert d["trained_on"] == ["synthetic-track2"] and d["tested_on"] == r.dataset
        assert r.seeds == [0, 1] and np.shape(r.predictions) == (2, r.n)
        # the figures are the means over the two seeds' runs on the same frames
        each = [score(r.test_labels, p) for p in r.predictions]
        assert r.accuracy == pytest.approx(np.mean([s.accuracy for s in each]))
        assert r.balanced_accuracy == pytest.approx(np.mean([s.balanced_accuracy for s in each]))
        assert r.macro_f1 == pytest.approx(np.mean([s.macro_f1 for s in each]))
        ci = d["balanced_accuracy_ci"]
        assert ci["low"] <= r.balanced_accuracy <= ci["high"] and ci["resamples"] == 1000
        assert d["accuracy_ci"]["block"] >= 11
        assert d["majority"]["balanced_accuracy"] == pytest.approx(1 / 3)
    json.dumps(result.to_dict())


def test_a_test_recording_that_overlaps_the_training_set_is_refused() -> None:
    spec = EvaluationSpec("", "image-split-uu", train=(TRACK2,), test=("synthetic:track2:60",))
    with pytest.raises(InputError, match="shares 60 of its 60 frames with the training set"):
        run_evaluation(spec, Collector())


def test_leave_one_out_tests_each_recording_once() -> None:
    recs = ("synthetic:track1:100", "synthetic:track2:100", "synthetic:rain:100")
    result = run_evaluation(EvaluationSpec("", "kmeans-uu", leave_one_out=recs), Collector())
    assert result.tested_on == ["synthetic-track1", "synthetic-track2", "synthetic-rain"]
    assert result.trained_on == [
        ["synthetic-track2", "synthetic-rain"],
        ["synthetic-track1", "synthetic-rain"],
        ["synthetic-track1", "synthetic-track2"],
    ]
    assert [r.dataset for r in result.results] == result.tested_on
    assert result.protocol["protocol"] == "leave-one-out"


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"seeds": 0}, "seeds=0 is invalid"),
        ({"train": (TRACK1,)}, "test='none' is invalid"),
        ({"leave_one_out": (TRACK1,)}, "two recordings or more"),
    ],
)
def test_bad_protocols_are_refused(changes: dict, message: str) -> None:
    with pytest.raises(ParameterError, match=message):
        EvaluationSpec("", **changes)


def test_paired_differences_are_on_the_same_frames() -> None:
    spec = EvaluationSpec(
        "", "image-split-uu,kmeans-uu", train=(TRACK2,), test=(TRACK1,), paired=True
    )
    result = run_evaluation(spec, Collector())
    (c,) = result.comparisons
    a, b = result.results[1], result.results[0]
    assert (c["a"], c["b"], c["dataset"]) == ("kmeans-uu", "image-split-uu", "synthetic-track1")
    assert c["value"] == pytest.approx(a.balanced_accuracy - b.balanced_accuracy)
    assert c["interval"]["low"] <= c["value"] <= c["interval"]["high"]
    assert c["text"].startswith(("+", "-")) and "[" in c["text"]


def test_a_one_class_test_recording_is_scored_with_balanced_accuracy_undefined(
    tmp_path: Path,
) -> None:
    rec = tmp_path / "straight"
    (rec / "IMG").mkdir(parents=True)
    lines = []
    for i, scene in enumerate(generate_drive("track1", 60, seed=5)):
        write_image(rec / "IMG" / f"{i:06d}.png", scene.image)
        lines.append(f"IMG/{i:06d}.png,,,0.0,0,0,0")
    (rec / "driving_log.csv").write_text("\n".join(lines) + "\n")
    spec = EvaluationSpec("", "image-split-uu", train=(TRACK2,), test=(f"udacity:{rec}", TRACK1))
    result = run_evaluation(spec, Collector())
    flat, other = result.results
    assert flat.balanced_accuracy is None and flat.balanced_accuracy_ci is None
    assert any("balanced accuracy is undefined: all 60 test labels" in n for n in flat.notes)
    assert flat.accuracy_ci is not None
    assert other.balanced_accuracy is not None


def test_methods_without_randomness_run_once_and_say_so() -> None:
    exact = replace(PipelineConfig(), direction=replace(PipelineConfig().direction, shots=None))
    uu, vqc = get_method("image-split-uu"), get_method("kmeans-vqc")
    assert not seed_matters(uu, exact, None)
    assert seed_matters(uu, PipelineConfig(), None)  # shot sampling is seeded
    assert seed_matters(vqc, exact, None)
    seeds, notes = method_seeds(uu, exact, None, 3)
    assert seeds == [0] and notes == [
        "image-split-uu has no randomness: seeds do not apply (one run)"
    ]
    assert method_seeds(vqc, replace(exact, seed=7), None, 3) == ([7, 8, 9], [])


def _evaluate_json(cache: Path, *extra: str, wait_for_unit: bool = False) -> list[dict]:
    """``python -m qdcnn evaluate --json`` in a subprocess; killed after its first unit."""
    src = str(Path(__file__).resolve().parents[2] / "src")
    env = {**os.environ, "QDCNN_CACHE": str(cache), "PYTHONPATH": src}
    args = [sys.executable, "-m", "qdcnn", "evaluate", "--data", "synthetic:track2:150"]
    args += ["--method", "kmeans-vqc", "--folds", "3", "--json", *extra]
    proc = subprocess.Popen(
        args, env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True
    )
    if wait_for_unit:
        deadline = time.monotonic() + 600
        while not list(cache.glob("evaluate/unit-*.json")) and proc.poll() is None:
            assert time.monotonic() < deadline
            time.sleep(0.05)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        return []
    stdout, _ = proc.communicate(timeout=900)
    assert proc.returncode == 0
    return [json.loads(line) for line in stdout.splitlines()]


def _without_times(rows: list[dict]) -> list[dict]:
    return [
        {k: v for k, v in r.items() if k not in ("seconds", "pipeline_ms_per_frame")} for r in rows
    ]


@pytest.mark.slow
def test_a_killed_evaluation_resumes_to_the_same_result(tmp_path: Path) -> None:
    resumed = tmp_path / "resumed"
    _evaluate_json(resumed, wait_for_unit=True)
    done_before = len(list(resumed.glob("evaluate/unit-*.json")))
    assert 1 <= done_before < 3  # killed between folds
    rows = _evaluate_json(resumed)
    assert len(list(resumed.glob("evaluate/unit-*.json"))) == 3
    fresh = _evaluate_json(tmp_path / "fresh")
    assert _without_times(rows) == _without_times(fresh)
    # a second seed reruns only the new seed's folds
    _evaluate_json(resumed, "--seeds", "2")
    assert len(list(resumed.glob("evaluate/unit-*.json"))) == 6


def test_a_percentile_threshold_comes_from_the_training_recordings_only() -> None:
    train, test = f"{TRACK2}@threshold=p33", f"{TRACK1}@threshold=p33"
    result = run_evaluation(EvaluationSpec("", "kmeans-uu", train=(train,), test=(test,)))
    trained, tested = result.labels["synthetic-track2"], result.labels["synthetic-track1"]
    assert trained["label_threshold"] == tested["label_threshold"]  # both in norm units
    assert "p33 of the training frames" in tested["description"]
    assert trained["class_balance"]["straight"] == pytest.approx(0.33 * 150, abs=3)


def test_a_rerun_reads_finished_units_and_a_new_method_runs_alone(tmp_path: Path) -> None:
    units = tmp_path / "cache" / "evaluate"
    spec = EvaluationSpec("", "kmeans-uu", train=(TRACK2,), test=(TRACK1, RAIN))
    first = run_evaluation(spec)
    assert len(list(units.glob("unit-*.json"))) == 2  # one per test recording
    again = run_evaluation(spec)
    assert [r.predictions for r in again.results] == [r.predictions for r in first.results]
    assert len(list(units.glob("unit-*.json"))) == 2
    both = run_evaluation(replace(spec, methods="kmeans-uu,image-split-uu"))
    assert len(list(units.glob("unit-*.json"))) == 4
    assert both.results[0].to_dict()["balanced_accuracy"] == first.results[0].balanced_accuracy


@pytest.mark.slow
def test_a_cnn_trains_on_the_training_recordings_and_scores_the_test_one() -> None:
    pytest.importorskip("torch")
    from qdcnn.direction.methods import TrainingOptions

    spec = EvaluationSpec(
        "",
        "dnn-pilotnet",
        train=("synthetic:track2:100",),
        test=("synthetic:track1:80",),
        training=TrainingOptions(epochs=1, threads=1),
    )
    (r,) = run_evaluation(spec).results
    assert r.n == 80 and r.extra["trained_on"] == ["synthetic-track2"]
    assert r.accuracy == pytest.approx(score(r.test_labels, r.predictions[0]).accuracy)


def test_a_percentile_threshold_inside_one_recording_is_refused() -> None:
    with pytest.raises(ParameterError, match="a percentile \\(pNN\\) is taken from training"):
        run_evaluation(EvaluationSpec(f"{TRACK2}@threshold=p33", "kmeans-uu"))


def test_frames_prepared_for_a_network_stay_prepared_when_recordings_are_joined() -> None:
    pytest.importorskip("torch")
    from qdcnn.direction.methods import get_method
    from qdcnn.experiments.evaluate_cross import _concatenate
    from qdcnn.models.preprocess import PreparedFrames
    from qdcnn.models.specs import PILOTNET_INPUT

    a = PreparedFrames(np.zeros((2, 66, 200, 3), np.uint8), PILOTNET_INPUT)
    b = PreparedFrames(np.ones((3, 66, 200, 3), np.uint8), PILOTNET_INPUT)
    joined = _concatenate([a, b], get_method("qdcnn-head"))
    assert isinstance(joined, PreparedFrames) and joined.spec == PILOTNET_INPUT
    assert joined.shape == (5, 66, 200, 3) and joined[2:].min() == 1
    raw = _concatenate([np.asarray(a), np.asarray(b)], get_method("qdcnn-head"))
    assert not isinstance(raw, PreparedFrames)  # raw frames are cropped and resized later


def test_a_test_recording_answered_with_one_class_gets_a_collapse_note() -> None:
    from qdcnn.experiments.evaluate_cross import Recording, _scored

    y = np.repeat([0, 1, 2], 20)
    test = Recording("drive", np.zeros((60, 2)), y)
    runs = np.stack([np.ones(60, dtype=np.int64), y])  # seed 0 says straight throughout
    result = _scored(get_method("lines-logreg"), test, runs, 1, [0, 1], ["a"], [], 0.1, [])
    assert [n for n in result.notes if n.startswith("collapsed")] == [
        "collapsed: 'straight' for 100.0% of the test recording's frames (seed 0; over 95% of "
        "frames holding two classes with 10% each or more)"
    ]
