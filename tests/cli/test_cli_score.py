"""``qdcnn score``: JSON lines, the table, undefined scores and bad input."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from qdcnn.cli import app
from qdcnn.data.frames import load_frameset
from qdcnn.direction.features import compute_features
from qdcnn.direction.model import DirectionModel
from qdcnn.direction.scores import score

runner = CliRunner()
TRAIN, TEST = "synthetic:track2:200", "synthetic:track2:120"


def json_lines(text: str) -> list[dict]:
    return [json.loads(line) for line in text.splitlines() if line.strip()]


@pytest.fixture(scope="module")
def model_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A lane model from ``qdcnn train-direction`` on the seed-0 drive."""
    out = tmp_path_factory.mktemp("cli-score") / "uu.safetensors"
    args = ["train-direction", "--data", TRAIN, "--out", str(out), "--inner-folds", "2"]
    res = runner.invoke(app, [*args, "--seed", "0"])
    assert res.exit_code == 0, res.stderr
    return out


def test_json_rows_hold_the_metrics_of_the_models_predictions(model_file: Path) -> None:
    args = ["score", "--data", TEST, "--model", str(model_file), "--seed", "1", "--json"]
    res = runner.invoke(app, [*args, "--resamples", "200"])
    assert res.exit_code == 0, res.stderr
    row, summary = json_lines(res.stdout)
    model = DirectionModel.load(model_file)
    assert model.grouping is not None
    frames = load_frameset(TEST, seed=1)
    table = compute_features(frames, model.config, (model.grouping,))
    truth = frames.labels(model.config.labels)[table.readable]
    expected = score(truth, model.predict(table.features[model.grouping][table.readable]))
    assert {k: row[k] for k in expected.to_dict()} == json.loads(json.dumps(expected.to_dict()))
    assert row["dataset"] == TEST and row["model"] == str(model_file)
    low, high = row["balanced_accuracy_ci"]
    assert low <= row["balanced_accuracy"] <= high and len(row["accuracy_ci"]) == 2
    assert row["resamples"] == 200 and row["block"] >= 11
    assert summary == {
        "summary": True,
        "model": str(model_file),
        "method": "image-split-uu",
        "trained_on": TRAIN,
        "n_datasets": 1,
        "n_failed": 0,
        "failures": [],
    }


def test_the_table_leads_with_balanced_accuracy_and_says_how_it_was_obtained(
    model_file: Path,
) -> None:
    args = ["score", "--data", TEST, "--data", "synthetic:track1:60", "--model", str(model_file)]
    res = runner.invoke(app, [*args, "--seed", "1"], env={"COLUMNS": "140"})
    assert res.exit_code == 0, res.stderr
    header = next(line for line in res.stdout.splitlines() if "dataset" in line)
    assert header.index("balanced accuracy") < header.index("accuracy ")
    assert re.search(rf"{re.escape(TEST)} │ \d\.\d\d \[\d\.\d\d, \d\.\d\d\] │", res.stdout)
    line = re.search(
        rf"image-split-uu model {re.escape(str(model_file))} trained on {TRAIN}; scored on "
        rf"{TEST}, synthetic:track1:60; 95 % block-bootstrap interval, 1000 resamples of "
        r"(\d+-frame blocks|blocks of .+)$",
        res.stdout,
        re.MULTILINE,
    )
    assert line, res.stdout


def test_one_class_labels_leave_balanced_accuracy_undefined_with_exit_0(
    model_file: Path,
) -> None:
    args = ["score", "--data", TEST, "--model", str(model_file), "--label-threshold", "0.99"]
    res = runner.invoke(app, [*args, "--json"])
    assert res.exit_code == 0, res.stderr
    row, _ = json_lines(res.stdout)
    assert row["balanced_accuracy"] is None and row["balanced_accuracy_ci"] is None
    assert row["undefined"] == "all 120 test labels are 'straight'"
    res = runner.invoke(app, args, env={"COLUMNS": "140"})
    assert res.exit_code == 0 and "undefined" in res.stdout
    assert f"{TEST}: balanced accuracy undefined: all 120 test labels are 'straight'" in (
        res.stdout
    )


def test_bad_models_and_missing_data_exit_2_with_one_line_and_nothing_on_stdout(
    model_file: Path, tmp_path: Path
) -> None:
    corrupt = tmp_path / "corrupt.safetensors"
    corrupt.write_bytes(b"garbage")
    cases = [
        (["--model", str(tmp_path / "none.safetensors")], "file not found"),
        (["--model", str(corrupt)], str(corrupt)),
        (["--model", str(model_file), "--data", "udacity:/nope"], "/nope: file not found"),
        (["--model", str(model_file), "--block", "2"], "block=2 is invalid"),
    ]
    for extra, message in cases:
        res = runner.invoke(app, ["score", "--data", TEST, *extra, "--json"])
        assert res.exit_code == 2, (extra, res.stderr)
        assert res.stdout == "" and res.stderr.startswith("error: ")
        assert len(res.stderr.splitlines()) == 1 and message in res.stderr


def test_a_dataset_that_fails_to_load_gives_exit_1_and_the_others_are_scored(
    model_file: Path, tmp_path: Path
) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    args = ["score", "--data", f"udacity:{empty}", "--data", TEST, "--model", str(model_file)]
    res = runner.invoke(app, [*args, "--json"])
    assert res.exit_code == 1
    failure, row, summary = json_lines(res.stdout)
    assert failure["file"] == f"udacity:{empty}" and "empty folder" in failure["error"]
    assert row["dataset"] == TEST
    assert summary["n_failed"] == 1 and summary["n_datasets"] == 1


@pytest.mark.slow
@pytest.mark.base
@pytest.mark.parametrize("torch_installed", [True, False])
def test_without_model_the_built_in_model_decides_and_is_named(
    torch_installed: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    from qdcnn._optional import has_torch

    if torch_installed and not has_torch():
        pytest.skip("the QDCNN model needs torch")
    monkeypatch.setattr("qdcnn.direction.builtin.has_torch", lambda: torch_installed)
    res = runner.invoke(app, ["score", "--data", "synthetic:track1:60", "--json"])
    assert res.exit_code == 0, res.stderr
    row, summary = json_lines(res.stdout)
    expected = (
        "built-in qdcnn-head (trained on "
        if torch_installed
        else ("built-in lane model image-split-uu trained on synthetic:")
    )
    assert row["model"].startswith(expected)
    assert summary["model"] == row["model"]
    assert f"note: no --model: model: {row['model']}" in res.stderr


def test_each_row_or_frame_left_out_is_one_note_naming_it(model_file: Path, tmp_path: Path) -> None:
    rec = tmp_path / "rec"
    res = runner.invoke(app, ["synth", "--n", "30", "--layout", "udacity", "--out", str(rec)])
    assert res.exit_code == 0, res.output
    log = rec / "driving_log.csv"
    lines = log.read_text().splitlines()
    fields = lines[3].split(",")
    fields[3] = "abc"
    lines[3] = ",".join(fields)
    log.write_text("\n".join(lines) + "\n")
    Path(lines[5].split(",")[0].strip()).write_bytes(b"")
    args = ["score", "--data", f"udacity:{rec}", "--model", str(model_file), "--json"]
    res = runner.invoke(app, [*args, "--resamples", "50"])
    assert res.exit_code == 0, res.stderr
    notes = [line for line in res.stderr.splitlines() if "not scored" in line]
    assert len(notes) == 2 and all(n.startswith("note: ") for n in notes), res.stderr
    assert "driving_log.csv:row 4: steering 'abc' is not a number" in notes[0]
    assert "empty file (0 bytes)" in notes[1]
    assert json_lines(res.stdout)[0]["skipped_frames"] == 2
