"""detect_lanes: overlays and a CSV row per image, quoted, written as it goes."""

from __future__ import annotations

import csv
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import pytest

from qdcnn import pipeline
from qdcnn.data.images import write_image
from qdcnn.data.synthetic import generate_scenes
from qdcnn.experiments.detect_lanes import DetectLanesSpec, detect_lanes
from qdcnn.experiments.run import RunSpec, run
from qdcnn.runtime.engine import RunOptions
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
        assert sum(probs) == pytest.approx(1.0, abs=1.5e-6)  # three values rounded to 1e-6
    assert all(Path(r.overlay).is_file() for r in result.records)
    assert [Path(f.file).name for f in result.failures] == ["broken.png"]
    assert result.exit_code == 1


def test_without_a_model_the_built_in_model_decides_and_is_said(default_model_result) -> None:
    *_, result, collected = default_model_result
    from qdcnn._optional import has_torch
    from qdcnn.direction.builtin import describe_default_model

    name = describe_default_model(result.model)
    assert collected.notes == [f"no --model: model: {name}"]
    assert result.to_dict()["model"] == name
    if has_torch():  # the built-in QDCNN model, shipped with the package
        assert result.model.method == "qdcnn-head"
        assert name.startswith("built-in qdcnn-head (trained on udacity-lake-track, ")
    else:
        assert result.model.method == "image-split-uu"
        presets = "synthetic:track1:300 + synthetic:track2:300 + synthetic:rain:300"
        assert result.model.trained_on == presets
        assert result.to_dict()["model_summary"]["n"] == 900


def test_a_lane_method_gets_its_built_in_lane_model_trained_and_said(tmp_path: Path) -> None:
    folder = tmp_path / "frames"
    for i, scene in enumerate(generate_scenes("track2", 2, seed=4)):
        write_image(folder / f"{i}.png", scene.image)
    collected = Collector()
    spec = DetectLanesSpec((folder,), tmp_path / "out", method="image-split-uu")
    result = detect_lanes(spec, collected)
    presets = "synthetic:track1:300 + synthetic:track2:300 + synthetic:rain:300"
    assert result.model.trained_on == presets
    cv = result.to_dict()["model_summary"]["cross_validation"]
    assert collected.notes == [
        f"no --model: model: built-in lane model image-split-uu trained on {presets}; 5-fold "
        f"contiguous CV accuracy {cv['accuracy']:.3f} (majority class "
        f"{cv['majority_baseline']:.3f})"
    ]
    assert result.to_dict()["model_summary"]["n"] == 900


#: Drawn roads (320x160, the built-in model's Udacity lane settings) with known lane statuses:
#: lines crossing inside the ROI, lines leaning the wrong way, a straight road
DRAWN = {
    "crossed": [(60, 159, 200, 72), (260, 159, 120, 72)],
    "wrong-side": [(100, 159, 40, 72), (220, 159, 280, 72)],
    "ok": [(60, 159, 140, 72), (260, 159, 180, 72)],
}


def drawn_road(lines: list[tuple[int, int, int, int]]) -> np.ndarray:
    img = np.full((160, 320, 3), 90, np.uint8)
    for x1, y1, x2, y2 in lines:
        cv2.line(img, (x1, y1), (x2, y2), (230, 230, 230), 3)
    return img


@pytest.fixture
def drawn_roads(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A folder ``<status>.png`` per drawn road; shadow removal off (they have no shadows,
    and on a flat grey road it would add edges of its own)."""
    monkeypatch.setattr(pipeline, "detect_shadows_uu", lambda *a, **k: SimpleNamespace(mask=None))
    folder = tmp_path / "drawn"
    for status, lines in DRAWN.items():
        write_image(folder / f"{status}.png", drawn_road(lines))
    return folder


def test_pairs_that_cannot_be_a_road_are_flagged_in_predictions(
    drawn_roads: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    collected = Collector()
    result = detect_lanes(DetectLanesSpec((drawn_roads,), out), collected)
    with open(out / "predictions.csv", newline="", encoding="utf-8") as fh:
        rows = {Path(r["file"]).stem: r for r in csv.DictReader(fh)}
    assert {name: r["status"] for name, r in rows.items()} == {s: s for s in DRAWN}
    # flagged frames keep the pipeline's decision
    assert all(r["direction"] in ("left", "straight", "right") for r in rows.values())
    assert {Path(r["file"]).stem: r["status"] for r in collected.results} == {s: s for s in DRAWN}
    assert result.exit_code == 0


def test_pairs_that_cannot_be_a_road_are_flagged_in_frames_csv(
    drawn_roads: Path, tmp_path: Path
) -> None:
    out = tmp_path / "run"
    result = run(RunSpec((str(drawn_roads),), out, options=RunOptions(overlay=False)))
    assert result.inputs[0].ok
    with open(out / "drawn" / "frames.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    # frames in name order: crossed, ok, wrong-side
    assert [r["lane_status"] for r in rows] == sorted(DRAWN)
    assert all(r["direction"] in ("left", "straight", "right") for r in rows)
