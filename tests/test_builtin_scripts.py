"""The built-in model's benchmark scripts: their comparisons and their refusals."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sklearn.metrics import balanced_accuracy_score

BENCHMARKS = Path(__file__).parents[1] / "benchmarks"


@pytest.fixture(scope="module")
def scripts() -> tuple[Any, Any]:
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import builtin_paired
        import train_builtin
    finally:
        sys.path.remove(str(BENCHMARKS))
    return builtin_paired, train_builtin


def results_file(path: Path, labels: np.ndarray, runs: np.ndarray) -> Path:
    row = {"test_labels": labels.tolist(), "predictions": runs.tolist()}
    path.write_text(json.dumps({"leave_one_out_rows": {"road": [row]}}))
    return path


def test_paired_difference_of_files_scored_with_several_seeds(
    scripts: tuple[Any, Any], tmp_path: Path
) -> None:
    paired, _ = scripts
    rng = np.random.default_rng(0)
    labels = np.repeat(rng.integers(0, 3, 40), 10)
    three = np.where(rng.random((3, labels.size)) < 0.7, labels, (labels + 1) % 3)
    one = np.where(rng.random((1, labels.size)) < 0.5, labels, (labels + 2) % 3)
    a = results_file(tmp_path / "a.json", labels, three)
    b = results_file(tmp_path / "b.json", labels, one)
    (row,) = paired.paired_rows(a, b)
    mean_a = np.mean([balanced_accuracy_score(labels, run) for run in three])
    assert row["value"] == pytest.approx(mean_a - balanced_accuracy_score(labels, one[0]))
    assert row["interval"]["low"] < row["value"] < row["interval"]["high"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--seeds", "3"], "--no-final and --seeds: give --results (not the shipped file)"),
        (["--no-final"], "--no-final and --seeds: give --results (not the shipped file)"),
        (["--seeds", "0", "--results", "x.json"], "--seeds 0: give at least 1"),
        (["--edge-frames"], "a recipe variant: give --model and --results (not the shipped files)"),
        (["--edge-frames", "--no-final"], "a recipe variant: give --results"),
        (
            ["--edge-frames", "--plain-frames"],
            "--plain-frames, --edge-frames and --with-edges: give one of them",
        ),
        (
            ["--edge-frames", "--with-edges"],
            "--plain-frames, --edge-frames and --with-edges: give one of them",
        ),
        (
            ["--skip-final", "--no-final", "--results", "x.json"],
            "--skip-final and --no-final: give one of them",
        ),
        (["--ensemble", "0", "--results", "x.json"], "--ensemble 0: give 1 to 9 networks"),
        (
            ["--ensemble", "3"],
            "a recipe variant: give --model and --results (not the shipped files)",
        ),
        (["--tta"], "a recipe variant: give --model and --results (not the shipped files)"),
        (
            ["--synthetic", "track1:150,dashcam:150"],
            "a recipe variant: give --model and --results (not the shipped files)",
        ),
        (
            ["--synthetic", "track9:150"],
            "--synthetic 'track9:150': give PRESET:N items, a preset in "
            "('track1', 'track2', 'rain', 'dashcam')",
        ),
        (
            ["--synthetic", "track1"],
            "--synthetic 'track1': give PRESET:N items, a preset in "
            "('track1', 'track2', 'rain', 'dashcam')",
        ),
        (
            ["--synthetic", "rain:10,rain:20"],
            "--synthetic 'rain:10,rain:20': each preset once",
        ),
    ],
)
def test_train_builtin_refuses_to_overwrite_the_shipped_scores(
    scripts: tuple[Any, Any],
    argv: list[str],
    message: str,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    _, train = scripts
    monkeypatch.setattr(sys, "argv", ["train_builtin.py", *argv])
    monkeypatch.setattr(train, "VARIANT", {})  # main() fills it in
    with pytest.raises(SystemExit) as stop:
        train.main()
    assert stop.value.code == 2
    assert capsys.readouterr().err.strip().endswith(f"error: {message}")


def test_the_edge_variant_trains_with_edge_frames_instead_of_standardised_ones(
    scripts: tuple[Any, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    _, train = scripts
    monkeypatch.setattr(train, "VARIANT", {"standardise_frames": False, "edge_frames": True})
    options = train.training_options()
    assert options.edge_frames and not options.standardise_frames and options.params == {}
    monkeypatch.setattr(train, "VARIANT", {"edge_frames": True})  # --with-edges
    options = train.training_options()
    assert options.edge_frames and options.standardise_frames
    monkeypatch.setattr(train, "VARIANT", {})
    options = train.training_options()
    assert options.standardise_frames and not options.edge_frames


def test_the_recipe_is_one_network_and_an_ensemble_is_a_variant(
    scripts: tuple[Any, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    _, train = scripts
    monkeypatch.setattr(train, "VARIANT", {})
    assert train.training_options().params == {} and train.ENSEMBLE == 1
    monkeypatch.setattr(train, "VARIANT", {"ensemble": 3, "max_shift": 0.1})
    assert train.training_options().params == {"max_shift": 0.1, "ensemble": 3}


def test_the_mirror_averaged_variant_reaches_the_estimator(
    scripts: tuple[Any, Any], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    _, train = scripts
    _run_to_the_data(
        train, ["--tta", "--no-final", "--results", str(tmp_path / "r.json")], monkeypatch
    )
    assert train.training_options().params == {"tta": True}


def test_a_variant_scored_without_a_final_model_needs_only_its_results_path(
    scripts: tuple[Any, Any], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    _, train = scripts
    argv = ["--edge-frames", "--no-final", "--results", str(tmp_path / "r.json")]
    _run_to_the_data(train, argv, monkeypatch)
    assert train.VARIANT == {"standardise_frames": False, "edge_frames": True}


def test_the_synthetic_variant_chooses_the_data_not_the_estimator(
    scripts: tuple[Any, Any], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    _, train = scripts
    argv = ["--synthetic", "track1:150, dashcam:40", "--no-final"]
    loaded = _run_to_the_data(train, [*argv, "--results", str(tmp_path / "r.json")], monkeypatch)
    assert loaded == ("synthetic:track1:150", "synthetic:dashcam:40")
    assert train.VARIANT == {"synthetic": ["synthetic:track1:150", "synthetic:dashcam:40"]}
    assert train.training_options().params == {}


def test_the_recipe_trains_on_its_own_synthetic_drives(
    scripts: tuple[Any, Any], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    _, train = scripts
    loaded = _run_to_the_data(
        train, ["--no-final", "--results", str(tmp_path / "r.json")], monkeypatch
    )
    assert loaded == train.SYNTHETIC and train.VARIANT == {}


def _run_to_the_data(
    train: Any, argv: list[str], monkeypatch: pytest.MonkeyPatch
) -> tuple[str, ...]:
    """``train_builtin.main()`` with ``argv``, stopped where it would load the recordings."""
    pytest.importorskip("torch")
    monkeypatch.setattr(sys, "argv", ["train_builtin.py", *argv])
    monkeypatch.setattr(train, "VARIANT", {})
    monkeypatch.setattr(train, "SEEDS", train.SEEDS)
    monkeypatch.setattr(train, "load_sets", _past_the_checks)
    with pytest.raises(_PastTheChecks) as stop:
        train.main()
    return stop.value.synthetic


class _PastTheChecks(RuntimeError):
    def __init__(self, synthetic: tuple[str, ...]) -> None:
        super().__init__("past the argument checks")
        self.synthetic = synthetic


def _past_the_checks(_root: Path, synthetic: tuple[str, ...]) -> None:
    raise _PastTheChecks(synthetic)


@pytest.fixture(scope="module")
def nested_script() -> Any:
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import builtin_nested
    finally:
        sys.path.remove(str(BENCHMARKS))
    return builtin_nested


RECORDINGS = ["lake", "real", "mountain", "night"]


def _fake_scores(calls: list[tuple[list[str], str, str]]) -> Any:
    """A stand-in for training: records what trained and tested, scores by a fixed table."""
    table = {"plain": 0.4, "edges": 0.5, "standardised": 0.6}

    def score(_sets: Any, train: list[str], test: str, candidate: str) -> dict[str, Any]:
        calls.append((list(train), test, candidate))
        bonus = 0.3 if (candidate, test) == ("plain", "night") else 0.0  # plain wins one road
        return {"balanced_accuracy": table[candidate] + bonus, "method": "qdcnn-head"}

    return score


def test_the_nested_choice_never_sees_the_outer_recording(
    nested_script: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls: list[tuple[list[str], str, str]] = []
    monkeypatch.setattr(nested_script, "score", _fake_scores(calls))
    monkeypatch.setattr(nested_script.tb, "RECORDINGS", dict.fromkeys(RECORDINGS))
    sets = dict.fromkeys([*RECORDINGS, "synthetic-track1"])
    entries = list(nested_script.nested(sets, "lake", ["plain", "edges", "standardised"], {}))
    *inner, outer = calls
    assert len(inner) == 9 and len(entries) == 10
    assert all("lake" not in train and test != "lake" for train, test, _ in inner)
    assert all(test not in train and len(train) == 2 for train, test, _ in inner)
    entry = entries[-1]
    assert entry["inner_mean"] == pytest.approx({"plain": 0.5, "edges": 0.5, "standardised": 0.6})
    assert entry["chosen"] == "standardised"
    assert outer == (["real", "mountain", "night"], "lake", "standardised")
    assert entry["outer"]["method_variant"] == "standardised"


def test_a_nested_choice_breaks_ties_by_the_candidates_order(nested_script: Any) -> None:
    assert nested_script.choose({"plain": 0.5, "edges": 0.5}) == "plain"
    assert nested_script.choose({"edges": 0.5, "plain": 0.5}) == "edges"
    assert nested_script.choose({"edges": 0.5, "plain": 0.51}) == "plain"


def test_a_stopped_nested_run_goes_on_where_it_stopped(
    nested_script: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls: list[tuple[list[str], str, str]] = []
    monkeypatch.setattr(nested_script, "score", _fake_scores(calls))
    monkeypatch.setattr(nested_script.tb, "RECORDINGS", dict.fromkeys(RECORDINGS))
    sets = dict.fromkeys(RECORDINGS)
    saved = {"candidates": ["edges", "standardised"], "inner": {"edges": {"real": 0.9}}}
    *_, entry = nested_script.nested(sets, "lake", ["edges", "standardised"], saved)
    assert ("real", "edges") not in [(test, c) for _, test, c in calls]
    assert len(calls) == 5 + 1 and entry["inner"]["edges"]["real"] == 0.9
    calls.clear()  # all done: nothing trains again
    assert list(nested_script.nested(sets, "lake", ["edges", "standardised"], entry)) == []
    assert not calls


def test_a_nested_recipe_is_set_only_while_it_trains(nested_script: Any) -> None:
    before = dict(nested_script.tb.VARIANT)
    with nested_script.recipe({"edge_frames": True}):
        assert nested_script.tb.VARIANT == {"edge_frames": True}
    assert nested_script.tb.VARIANT == before


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["--candidates", "plain,colour"],
            "--candidates: colour not in plain, standardised, edges, with-edges",
        ),
        (["--candidates", "plain"], "--candidates: give at least two recipes to choose from"),
        (
            ["--outer", "my-road"],
            "--outer: my-road not in udacity-lake-track, udacity-mountain-track, "
            "udacity-dark-mountain-track, real-dashcam-sample",
        ),
    ],
)
def test_builtin_nested_refuses_what_it_cannot_choose(
    nested_script: Any,
    argv: list[str],
    message: str,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
) -> None:
    monkeypatch.setattr(
        sys, "argv", ["builtin_nested.py", *argv, "--results", str(tmp_path / "n.json")]
    )
    with pytest.raises(SystemExit) as stop:
        nested_script.main()
    assert stop.value.code == 2
    assert capsys.readouterr().err.strip().endswith(f"error: {message}")
