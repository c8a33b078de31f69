"""detect_lanes: overlays and a CSV row per image, quoted, written as it goes."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from qdcnn.data.images import write_image
from qdcnn.data.synthetic import generate_scenes
from qdcnn.experiments.detect_lanes import DetectLanesSpec, detect_lanes
from qdcnn.runtime.reporting import Collector


@pytest.fixture(scope="module")
def default_model_result(tmp_path_factory: pytest.TempPathFactory):
    folder = tmp_path_factory.mktemp("frames")
    names = ["plain.png", "with,comma.png", 'quote"and\nnewline.png', "frame[left].png"]
    for name, scene in zip(names, generate_scenes("track2", len(names), seed=4), strict=True):
        write_image(folder / name, scene.image)
    (folder / "broken.png").write_bytes(b"\x89PNG not really")
    out = tmp_path_factory.mktemp("out")
    collected = Collector()
    result = detect_lanes(DetectLanesSpec((folder,), out), collected)
    return folder, out, names, result, collected


def test_every_good_image_gets_a_quoted_row_and_an_overlay(default_model_result) -> None:
    _, out, names, result, _ = default_model_result
    with open(out / "predictions.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert sorted(Path(r["file"]).name for r in rows) == sorted(names)
    for row in rows:
        assert row["direction"] in ("left", "straight", "right")
        probs = [float(row[k]) for k in ("p_left", "p_straight", "p_right")]
        assert sum(probs) == pytest.approx(1.0, abs=1e-6)
    assert all(Path(r.overlay).is_file() for r in result.records)
    assert [Path(f.file).name for f in result.failures] == ["broken.png"]
    assert result.exit_code == 1


def test_without_a_model_the_default_is_trained_and_said(default_model_result) -> None:
    *_, result, collected = default_model_result
    presets = "synthetic:track1:300 + synthetic:track2:300 + synthetic:rain:300"
    assert result.model.trained_on == presets
    cv = result.to_dict()["model_summary"]["cross_validation"]
    assert collected.notes == [
        f"no --model: the built-in model, image-split-uu trained on {presets}; 5-fold "
        f"contiguous CV accuracy {cv['accuracy']:.3f} (majority class "
        f"{cv['majority_baseline']:.3f})"
    ]
    assert result.to_dict()["model_summary"]["n"] == 900
