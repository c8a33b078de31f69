"""The built-in QDCNN model: shipped, checked by its SHA-256, chosen when torch is installed."""

from __future__ import annotations

import hashlib
import shutil
from pathlib import Path

import numpy as np
import pytest

from conftest import shared_recording
from qdcnn.config import PipelineConfig
from qdcnn.direction import builtin
from qdcnn.direction.builtin import (
    QDCNN_FILE,
    QDCNN_SHA256,
    builtin_model,
    builtin_qdcnn_model,
    uses_builtin_qdcnn,
)
from qdcnn.errors import InputError

SMALL = ("synthetic:track1:100", "synthetic:rain:100")


@pytest.mark.base
def test_the_shipped_file_is_the_one_the_code_names() -> None:
    data = QDCNN_FILE.read_bytes()
    assert hashlib.sha256(data).hexdigest() == QDCNN_SHA256
    assert len(data) <= 5 * 1024 * 1024


@pytest.mark.base
def test_a_missing_file_is_an_error_naming_it(tmp_path: Path) -> None:
    gone = tmp_path / "qdcnn-head.safetensors"
    with pytest.raises(InputError) as err:
        builtin_qdcnn_model(gone)
    assert str(err.value) == (
        f"{gone}: the built-in QDCNN model file is missing (reinstall qdcnn, or give --model)"
    )


@pytest.mark.base
def test_an_altered_file_is_an_error_never_a_fallback(tmp_path: Path) -> None:
    copy = tmp_path / "qdcnn-head.safetensors"
    shutil.copyfile(QDCNN_FILE, copy)
    data = bytearray(copy.read_bytes())
    data[-1] ^= 0x01  # one bit of one weight
    copy.write_bytes(bytes(data))
    digest = hashlib.sha256(bytes(data)).hexdigest()
    with pytest.raises(InputError) as err:
        builtin_qdcnn_model(copy)
    assert str(err.value) == (
        f"{copy}: the built-in QDCNN model file is altered: its SHA-256 is {digest[:16]}..., "
        f"the package's is {QDCNN_SHA256[:16]}... (reinstall qdcnn, or give --model)"
    )


@pytest.mark.base
def test_the_lane_model_decides_without_torch(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path))
    monkeypatch.setattr(builtin, "has_torch", lambda: False)
    monkeypatch.setattr(builtin, "DEFAULT_TRAINING_DATA", SMALL)

    def refuse(*_: object) -> None:
        raise AssertionError("the QDCNN file was read without torch")

    monkeypatch.setattr(builtin, "builtin_qdcnn_model", refuse)
    assert not uses_builtin_qdcnn(None, 0, None)
    model, name = builtin_model(None, 0)
    assert model.method == "image-split-uu"
    assert name.startswith("built-in lane model image-split-uu trained on synthetic:")
    assert name.endswith("(torch is not installed)")


def test_with_torch_the_qdcnn_model_decides_unless_lanes_are_asked_for(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    pytest.importorskip("torch")
    monkeypatch.setattr(builtin, "has_torch", lambda: True)
    assert uses_builtin_qdcnn(None, 0, None)
    assert uses_builtin_qdcnn(None, 3, PipelineConfig(seed=3))
    assert not uses_builtin_qdcnn("kmeans-uu", 0, None)  # --method: its lane model
    assert not uses_builtin_qdcnn(None, 0, PipelineConfig().with_lane_options(edges="rgb"))
    model, name = builtin_model(None, 0)
    assert model.method == "qdcnn-head"
    recordings = model.summary["builtin"]["training"]["recordings"]
    assert {"udacity-lake-track", "real-dashcam-sample"} <= set(recordings)
    assert name.startswith("built-in qdcnn-head (trained on udacity-lake-track, ")
    assert name.endswith(f"; sha256 {QDCNN_SHA256[:12]})")


def test_the_header_says_what_it_was_trained_on_and_how_it_scored() -> None:
    pytest.importorskip("torch")
    import json

    info = builtin_qdcnn_model().summary["builtin"]
    assert info["seed"] == 0 and len(info["commit"]) == 40
    assert "qdcnn-head" in info["recipe"] and info["training"]["frames"] > 1000
    recordings = info["training"]["recordings"]
    assert sum(r["frames"] for r in recordings.values()) == info["training"]["frames"]
    for name, scores in info["leave_one_out"].items():  # those that finished in time
        assert name in recordings and set(scores) == {"qdcnn-head", "hog-logreg", "lines-logreg"}
        for row in scores.values():
            ci = row["balanced_accuracy_ci"]
            assert ci["low"] <= row["balanced_accuracy"] <= ci["high"] and ci["level"] == 0.95
    # the results file says the same as the header, and names this file by its digest
    results = Path(__file__).resolve().parents[2] / "docs" / "results" / "builtin-model.json"
    saved = json.loads(results.read_text())
    assert saved["builtin"] == info and saved["model"]["sha256"] == QDCNN_SHA256


def test_its_decisions_cover_all_three_classes_on_synthetic_frames() -> None:
    pytest.importorskip("torch")
    from qdcnn.data.frames import load_frameset, stack_images

    model = builtin_qdcnn_model()
    predictions = []
    for spec in ("synthetic:track1:120", "synthetic:track2:120", "synthetic:rain:120"):
        images, _, _ = stack_images(load_frameset(spec, seed=5))
        predictions.append(model.predict(images))
    counts = np.bincount(np.concatenate(predictions), minlength=3)
    assert counts.min() >= 0.02 * counts.sum(), counts  # every class, not a stray frame


@pytest.mark.realdata
def test_its_decisions_cover_all_three_classes_on_the_real_sample() -> None:
    pytest.importorskip("torch")
    from qdcnn.data.frames import load_frameset, stack_images

    frames = load_frameset(f"udacity:{shared_recording('real-dashcam-sample')}")
    images, readable, _ = stack_images(frames)
    counts = np.bincount(builtin_qdcnn_model().predict(images[readable]), minlength=3)
    assert counts.min() >= 0.02 * counts.sum(), counts  # every class, not a stray frame


@pytest.mark.base
@pytest.mark.parametrize("torch_installed", [True, False])
def test_run_and_detect_lanes_say_which_model_decided(
    torch_installed: bool, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import json

    from typer.testing import CliRunner

    from qdcnn.cli import app
    from qdcnn.data.images import write_image
    from qdcnn.data.synthetic import generate_scenes
    from qdcnn.experiments.detect_lanes import DetectLanesSpec, detect_lanes
    from qdcnn.runtime.reporting import Collector

    if torch_installed:
        pytest.importorskip("torch")
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(builtin, "has_torch", lambda: torch_installed)
    monkeypatch.setattr(builtin, "DEFAULT_TRAINING_DATA", SMALL)
    args = ["run", "synthetic:track2:12", "--out", str(tmp_path / "run"), "--no-video", "--json"]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.stderr
    name = json.loads(res.stdout.splitlines()[-1])["model"]
    expected = "built-in qdcnn-head (" if torch_installed else "built-in lane model image-split-uu"
    assert name.startswith(expected)
    assert f"note: no --model: model: {name}" in res.stderr
    folder = tmp_path / "images"
    folder.mkdir()
    for i, scene in enumerate(generate_scenes("track2", 3, seed=1)):
        write_image(folder / f"{i}.png", scene.image)
    collector = Collector()
    result = detect_lanes(DetectLanesSpec((folder,), tmp_path / "lanes"), collector)
    assert result.to_dict()["model"] == name and len(result.records) == 3
    assert collector.notes == [f"no --model: model: {name}"]


@pytest.mark.base
@pytest.mark.parametrize("command", ["run", "detect-lanes", "score"])
@pytest.mark.parametrize("problem", ["missing", "altered"])
def test_commands_refuse_a_missing_or_altered_built_in_file_in_one_line(
    command: str, problem: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from typer.testing import CliRunner

    from qdcnn.cli import app

    bad = tmp_path / "qdcnn-head.safetensors"
    if problem == "altered":
        bad.write_bytes(QDCNN_FILE.read_bytes()[:-1])  # truncated by one byte
    monkeypatch.setattr(builtin, "QDCNN_FILE", bad)
    monkeypatch.setattr(builtin, "has_torch", lambda: True)
    out = tmp_path / "out"
    args = {
        "run": ["run", "synthetic:track1:10", "--out", str(out), "--no-video"],
        "detect-lanes": ["detect-lanes", str(QDCNN_FILE.parent), "--out", str(out)],
        "score": ["score", "--data", "synthetic:track1:10"],
    }[command]
    if command == "detect-lanes":  # a folder with one image
        from qdcnn.data.images import write_image
        from qdcnn.data.synthetic import generate_scenes

        (tmp_path / "img").mkdir()
        write_image(tmp_path / "img" / "a.png", generate_scenes("track1", 1, seed=0)[0].image)
        args[1] = str(tmp_path / "img")
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 2, res.output
    lines = [line for line in res.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"error: {bad}: the built-in QDCNN model file")
    assert f"is {problem}" in lines[0]
    assert not out.exists()


def test_a_built_in_ensemble_says_how_many_networks_decide() -> None:
    from types import SimpleNamespace

    from qdcnn.direction.builtin import describe_default_model

    summary = {"builtin": {"training": {"recordings": {"udacity-lake-track": {}}}}}
    for networks, said in ((3, ", the mean of 3 networks"), (1, "")):
        model = SimpleNamespace(
            method="qdcnn-head",
            trained_on="x",
            summary=summary,
            estimator=SimpleNamespace(ensemble=networks),
        )
        assert describe_default_model(model).startswith(  # type: ignore[arg-type]
            f"built-in qdcnn-head{said} (trained on udacity-lake-track; sha256 "
        )
