"""The built-in model's benchmark scripts: their comparisons and their refusals."""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sklearn.metrics import balanced_accuracy_score

BENCHMARKS = Path(__file__).parents[1] / "benchmarks"


def _benchmark(name: str) -> Any:
    """A benchmark script imported as a module (its sibling imports found too)."""
    sys.path.insert(0, str(BENCHMARKS))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(BENCHMARKS))


@pytest.fixture(scope="module")
def scripts() -> tuple[Any, Any]:
    return _benchmark("builtin_paired"), _benchmark("train_builtin")


def results_file(path: Path, labels: np.ndarray, runs: np.ndarray) -> Path:
    row = {"test_labels": labels.tolist(), "predictions": runs.tolist()}
    path.write_text(json.dumps({"leave_one_out_rows": {"road": [row]}}))
    return path


def _noisy(
    rng: np.random.Generator, labels: np.ndarray, runs: int, *, right: float, shift: int
) -> np.ndarray:
    """``runs`` predictions of ``labels``, each right with probability ``right``."""
    wrong = (labels + shift) % 3
    return np.where(rng.random((runs, labels.size)) < right, labels, wrong)


def test_paired_difference_of_files_scored_with_several_seeds(
    scripts: tuple[Any, Any], tmp_path: Path
) -> None:
    paired, _ = scripts
    rng = np.random.default_rng(0)
    labels = np.repeat(rng.integers(0, 3, 40), 10)
    three = _noisy(rng, labels, 3, right=0.7, shift=1)
    one = _noisy(rng, labels, 1, right=0.5, shift=2)
    a = results_file(tmp_path / "a.json", labels, three)
    b = results_file(tmp_path / "b.json", labels, one)
    (row,) = paired.paired_rows(a, b)
    mean_a = np.mean([balanced_accuracy_score(labels, run) for run in three])
    assert row["value"] == pytest.approx(mean_a - balanced_accuracy_score(labels, one[0]))
    assert row["interval"]["low"] < row["value"] < row["interval"]["high"]


def test_a_nested_file_is_paired_by_its_outer_scores(
    scripts: tuple[Any, Any], tmp_path: Path
) -> None:
    paired, _ = scripts
    labels = np.repeat(np.arange(30) % 3, 10)
    (chosen,) = _noisy(np.random.default_rng(1), labels, 1, right=0.8, shift=1)
    outer = {"test_labels": labels.tolist(), "predictions": [chosen.tolist()]}
    nested = {"outer": {"road": {"chosen": "edges", "outer": outer}, "unfinished": {"inner": {}}}}
    a = tmp_path / "nested.json"
    a.write_text(json.dumps(nested))
    b = results_file(tmp_path / "b.json", labels, labels[None])
    (row,) = paired.paired_rows(a, b)
    assert row["left_out"] == "road"
    assert row["value"] == pytest.approx(balanced_accuracy_score(labels, chosen) - 1.0)


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
            ["--synthetic", "track1:0"],
            "--synthetic 'track1:0': give PRESET:N items, a preset in "
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
    return _benchmark("builtin_nested")


RECORDINGS = ["lake", "real", "mountain", "night"]
SETUP = {"epochs": 15, "synthetic": ["synthetic:track1:150"], "data_root": "/data"}


def _setup(*candidates: str, **changes: Any) -> dict[str, Any]:
    return {"candidates": list(candidates), **SETUP, **changes}


class _FakeFrames:
    """A recording that says which frame sets its labels were resolved on."""

    def __init__(self, name: str, seen: list[tuple[str, list[str]]]) -> None:
        self.name, self.spec, self.seen = name, f"udacity:{name}", seen

    def __len__(self) -> int:
        return 30

    def labels(self, _config: Any, *, train: list[Any]) -> np.ndarray:
        self.seen.append((self.name, [fs.name for fs in train]))
        return np.arange(30) % 3


def _fake_scores(nested_script: Any, calls: list[tuple[list[str], str, str]]) -> Any:
    """A stand-in for training: what trained and tested, scored by a fixed table."""
    table = {"plain": 0.4, "edges": 0.5, "standardised": 0.6}

    def left_out_score(parts: list[Any], _method: str) -> tuple[None, dict[str, Any]]:
        variant = nested_script.tb.VARIANT
        (candidate,) = [c for c, v in nested_script.CANDIDATES.items() if v == variant]
        *train, test = [p.name for p in parts]
        calls.append((train, test, candidate))
        bonus = 0.3 if (candidate, test) == ("plain", "night") else 0.0  # plain wins one road
        return None, {"balanced_accuracy": table[candidate] + bonus, "method": "qdcnn-head"}

    return left_out_score


def _fake_world(
    nested_script: Any, monkeypatch: pytest.MonkeyPatch
) -> tuple[dict[str, Any], list[Any], list[Any]]:
    calls: list[tuple[list[str], str, str]] = []
    seen: list[tuple[str, list[str]]] = []
    monkeypatch.setattr(nested_script.tb, "left_out_score", _fake_scores(nested_script, calls))
    monkeypatch.setattr(nested_script.tb, "RECORDINGS", {n: ("", 3) for n in RECORDINGS})
    names = [*RECORDINGS, "synthetic-track1"]
    return {n: _FakeFrames(n, seen) for n in names}, calls, seen


def test_the_nested_choice_never_sees_the_outer_recording(
    nested_script: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    sets, calls, seen = _fake_world(nested_script, monkeypatch)
    setup = _setup("plain", "edges", "standardised")
    entries = list(nested_script.nested(sets, "lake", setup, {}))
    *inner, outer = calls
    assert len(inner) == 9 and len(entries) == 10
    assert all("lake" not in train and test != "lake" for train, test, _ in inner)
    assert all(test not in train and "synthetic-track1" in train for train, test, _ in inner)
    assert all(len(train) == 3 for train, _, _ in inner)  # two recordings and the preset
    assert len(seen) == 9 * 4 + 5  # every part of every run labelled, on its training sets
    assert not any("lake" in train for _, train in seen)
    assert [name for name, _ in seen].count("lake") == 1  # as the outer test, once
    entry = entries[-1]
    assert entry["inner_mean"] == pytest.approx({"plain": 0.5, "edges": 0.5, "standardised": 0.6})
    assert entry["chosen"] == "standardised"
    assert outer == (["real", "mountain", "night", "synthetic-track1"], "lake", "standardised")
    assert entry["outer"]["method_variant"] == "standardised"
    assert nested_script.tb.VARIANT == {}


def test_a_nested_choice_breaks_ties_by_the_candidates_order(nested_script: Any) -> None:
    assert nested_script.choose({"plain": 0.5, "edges": 0.5}) == "plain"
    assert nested_script.choose({"edges": 0.5, "plain": 0.5}) == "edges"
    assert nested_script.choose({"edges": 0.5, "plain": 0.51}) == "plain"


def test_a_stopped_nested_run_goes_on_where_it_stopped(
    nested_script: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    sets, calls, _ = _fake_world(nested_script, monkeypatch)
    setup = _setup("edges", "standardised")
    saved = {"setup": setup, "inner": {"edges": {"real": 0.9}}}
    *_, entry = nested_script.nested(sets, "lake", setup, saved)
    assert ("real", "edges") not in [(test, c) for _, test, c in calls]
    assert len(calls) == 5 + 1 and entry["inner"]["edges"]["real"] == 0.9
    assert entry["chosen"] == "edges"  # (0.9 + 0.5 + 0.5) / 3 > 0.6
    calls.clear()  # all done: nothing trains again
    assert list(nested_script.nested(sets, "lake", setup, entry)) == []
    assert not calls


def test_a_nested_run_with_other_candidates_keeps_only_what_still_holds(
    nested_script: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    sets, calls, _ = _fake_world(nested_script, monkeypatch)
    *_, first = nested_script.nested(sets, "lake", _setup("edges", "standardised"), {})
    calls.clear()
    assert first["chosen"] == "standardised"
    *_, entry = nested_script.nested(sets, "lake", _setup("edges", "plain"), first)
    assert [c for _, _, c in calls] == ["plain"] * 3 + ["edges"]  # the choice changed
    assert set(entry["inner"]) == {"plain", "edges"} and entry["chosen"] == "edges"  # a tie
    calls.clear()
    assert list(nested_script.nested(sets, "lake", _setup("edges", "plain"), entry)) == []
    assert not calls and entry["outer"]["method_variant"] == "edges"
    stale = nested_script.nested(sets, "lake", _setup("edges", "plain", epochs=1), entry)
    assert len(list(stale)) == 7  # trained with other epochs: everything again


def test_a_nested_recipe_is_set_only_while_it_trains(
    nested_script: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(nested_script.tb, "VARIANT", {"standardise_frames": False})
    with nested_script.recipe({}):
        assert nested_script.tb.training_options().standardise_frames
    with pytest.raises(KeyError), nested_script.recipe({"edge_frames": True}):
        assert nested_script.tb.training_options().edge_frames
        raise KeyError("stopped")
    assert nested_script.tb.VARIANT == {"standardise_frames": False}


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
