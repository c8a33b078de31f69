"""The qdcnn command line: JSON-only stdout, one-line errors, batches that go past bad files."""

from __future__ import annotations

import importlib.util
import json
import os
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from qdcnn.cli import app
from qdcnn.data import images as image_io
from qdcnn.data.images import read_mask, write_image, write_mask
from qdcnn.direction.model import DirectionModel

runner = CliRunner()


def json_lines(text: str) -> list[dict]:
    return [json.loads(line) for line in text.splitlines() if line.strip()]


def road(h: int = 160, w: int = 320, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = np.clip(rng.normal(150, 5, (h, w, 3)), 0, 255)
    img[h // 3 : 2 * h // 3, w // 4 : w // 2] *= 0.4
    return img.astype(np.uint8)


@pytest.fixture
def mixed_folder(tmp_path: Path) -> Path:
    """Good images of several kinds next to bad files."""
    d = tmp_path / "in"
    d.mkdir()
    write_image(d / "rgb.png", road())
    cv2.imwrite(str(d / "grey.png"), cv2.cvtColor(road(), cv2.COLOR_RGB2GRAY))
    cv2.imwrite(str(d / "rgba.png"), cv2.cvtColor(road(), cv2.COLOR_RGB2BGRA))
    cv2.imwrite(str(d / "deep16.png"), road().astype(np.uint16) * 257)
    write_image(d / "small.png", road(40, 30))
    write_image(d / "tiny.png", road(3, 3))
    (d / "corrupt.jpg").write_bytes(b"\xff\xd8\xff\xe0 this is not really a jpeg")
    (d / "empty.png").write_bytes(b"")
    (d / "notes.txt").write_text("not an image")
    (d / "sub").mkdir()
    return d


def test_detect_shadows_continues_past_bad_files(mixed_folder: Path, tmp_path: Path) -> None:
    out = tmp_path / "masks"
    res = runner.invoke(
        app, ["detect-shadows", str(mixed_folder), "--out", str(out), "--json", "--exact"]
    )
    assert res.exit_code == 1
    objs = json_lines(res.stdout)  # stdout holds only JSON
    summary = objs[-1]
    assert summary["summary"] is True
    done = {Path(o["file"]).name: o for o in objs if "seconds" in o}
    assert set(done) == {"rgb.png", "grey.png", "rgba.png", "deep16.png", "small.png"}
    errors = {Path(f["file"]).name: f["error"] for f in summary["failures"]}
    assert errors == {
        "corrupt.jpg": f"{mixed_folder / 'corrupt.jpg'}: not a readable image "
        "(corrupt or unsupported format)",
        "empty.png": f"{mixed_folder / 'empty.png'}: empty file (0 bytes)",
        "tiny.png": f"{mixed_folder / 'tiny.png'}: image size='3x3' is invalid: "
        "at least 4x4 pixels for downsample 4",
    }
    assert [Path(p).name for p in summary["skipped"]] == ["notes.txt"]
    for name, obj in done.items():
        assert obj["method"] == "uu" and obj["seconds"] > 0 and 0 <= obj["shadow_fraction"] <= 1
        mask = read_mask(obj["mask"])
        assert mask.shape == image_io.read_image(mixed_folder / name).shape[:2]
    # every error is one line on stderr, naming the file
    for name, message in errors.items():
        assert message in res.stderr.replace("\n", " ") or name in res.stderr
    # the finished masks are on disk despite the failures
    written = sorted(p.name for p in out.iterdir() if not p.name.startswith("."))
    assert written == sorted(f"{Path(n).stem}_mask.png" for n in done)


def test_unreadable_file_reports_permission(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    target = tmp_path / "locked.png"
    write_image(target, road())
    real = os.open

    def fake_open(path, *args, **kwargs):  # type: ignore[no-untyped-def]
        if Path(os.fsdecode(path)) == target:
            raise PermissionError(13, "Permission denied")
        return real(path, *args, **kwargs)

    monkeypatch.setattr(image_io.os, "open", fake_open)  # tests run as root: chmod cannot refuse
    res = runner.invoke(
        app, ["detect-shadows", str(target), "--out", str(tmp_path / "o"), "--json"]
    )
    assert res.exit_code == 1
    assert json_lines(res.stdout)[-1]["failures"] == [
        {"file": str(target), "error": f"{target}: cannot read: permission denied"}
    ]


def test_very_large_image_is_processed_and_oversized_one_rejected(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    big = tmp_path / "big.png"
    write_image(big, road(1500, 2600))
    res = runner.invoke(app, ["detect-shadows", str(big), "--out", str(tmp_path / "o"), "--json"])
    assert res.exit_code == 0, res.stderr
    assert read_mask(json_lines(res.stdout)[0]["mask"]).shape == (1500, 2600)
    monkeypatch.setattr(image_io, "MAX_PIXELS", 1000 * 1000)
    res = runner.invoke(app, ["detect-shadows", str(big), "--out", str(tmp_path / "o2"), "--json"])
    assert res.exit_code == 1
    assert json_lines(res.stdout)[-1]["failures"][0]["error"] == (
        f"{big}: image is 2600x1500, larger than 1000000 pixels"
    )


@pytest.mark.parametrize("method", ["uu", "uu-chroma", "ibt", "cbs", "lbp"])
def test_every_method_writes_binary_masks(method: str, tmp_path: Path) -> None:
    write_image(tmp_path / "a.png", road())
    res = runner.invoke(
        app,
        [
            "detect-shadows",
            str(tmp_path / "a.png"),
            "--out",
            str(tmp_path / "o"),
            "--method",
            method,
            "--json",
        ],
    )
    assert res.exit_code == 0, res.stderr
    mask = cv2.imread(str(tmp_path / "o" / "a_mask.png"), cv2.IMREAD_UNCHANGED)
    assert mask.shape == (160, 320) and set(np.unique(mask)) <= {0, 255}


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--method", "magic"], "method='magic' is invalid"),
        (["--backend", "gpu"], "backend='gpu' is invalid"),
        (["--shots", "0"], "shadow.shots=0 is invalid"),
        (["--threshold", "1.5"], "shadow.threshold=1.5 is invalid"),
        (["--centroid", "300"], "shadow.centroid=300.0 is invalid"),
    ],
)
def test_absurd_options_get_one_line_errors(args: list[str], message: str, tmp_path: Path) -> None:
    write_image(tmp_path / "a.png", road())
    res = runner.invoke(
        app, ["detect-shadows", str(tmp_path / "a.png"), "--out", str(tmp_path / "o"), *args]
    )
    assert res.exit_code == 2
    assert message in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_score_shadows_with_a_missing_ground_truth(tmp_path: Path) -> None:
    pred, gt = tmp_path / "pred", tmp_path / "gt"
    truth = np.zeros((20, 30), bool)
    truth[5:15, 5:15] = True
    write_mask(gt / "a.png", truth)
    write_mask(pred / "a_mask.png", truth)  # perfect
    guess = truth.copy()
    guess[5:15, 5:10] = False  # half the shadow missed, nothing false
    write_mask(gt / "b.png", truth)
    write_mask(pred / "b_mask.png", guess)
    write_mask(pred / "c_mask.png", truth)  # no ground truth for c
    res = runner.invoke(app, ["score-shadows", "--pred", str(pred), "--gt", str(gt), "--json"])
    assert res.exit_code == 1
    obj = json_lines(res.stdout)[0]
    # summed over the set: 150 of 200 shadow pixels found, no false positives
    assert obj["n"] == 2
    assert obj["shadow_error"] == pytest.approx(25.0)
    assert obj["nonshadow_error"] == pytest.approx(0.0)
    assert obj["ber"] == pytest.approx(12.5)
    assert obj["failures"] == [
        {
            "file": str(pred / "c_mask.png"),
            "error": f"{pred / 'c_mask.png'}: no ground-truth mask c.* in {gt}",
        }
    ]


def test_synth_then_detect_and_score_round_trip(tmp_path: Path) -> None:
    res = runner.invoke(
        app,
        [
            "synth",
            "--preset",
            "track2",
            "--n",
            "6",
            "--out",
            str(tmp_path / "s"),
            "--layout",
            "shadows",
            "--json",
        ],
    )
    assert res.exit_code == 0, res.stderr
    info = json_lines(res.stdout)[0]
    assert info["n"] == 6 and sum(info["directions"].values()) == 6
    res = runner.invoke(
        app,
        [
            "detect-shadows",
            str(tmp_path / "s" / "images"),
            "--out",
            str(tmp_path / "p"),
            "--method",
            "ibt",
            "--json",
        ],
    )
    assert res.exit_code == 0
    res = runner.invoke(
        app,
        [
            "score-shadows",
            "--pred",
            str(tmp_path / "p"),
            "--gt",
            str(tmp_path / "s" / "masks"),
            "--json",
        ],
    )
    assert res.exit_code == 0
    score = json_lines(res.stdout)[0]
    assert score["n"] == 6 and 0 <= score["ber"] <= 100


def test_synth_writes_loadable_udacity_and_carla_layouts(tmp_path: Path) -> None:
    from qdcnn.data.carla import load_carla
    from qdcnn.data.udacity import load_udacity

    res = runner.invoke(app, ["synth", "--preset", "rain", "--n", "5", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.stderr
    assert len(load_udacity(tmp_path / "udacity")) == 5
    assert len(load_carla(tmp_path / "carla")) == 5


def test_evaluate_rejects_bad_specs_and_single_class_data(tmp_path: Path) -> None:
    res = runner.invoke(app, ["evaluate", "--data", "ftp:somewhere"])
    assert res.exit_code == 2 and "data='ftp:somewhere' is invalid" in res.stderr
    res = runner.invoke(app, ["evaluate", "--data", "synthetic:track1:200", "--folds", "1"])
    assert res.exit_code == 2 and "folds=1 is invalid" in res.stderr
    res = runner.invoke(app, ["evaluate", "--data", "synthetic:track1:40", "--method", "best"])
    assert res.exit_code == 2 and "method='best' is invalid" in res.stderr
    # a recording whose steering is all straight cannot give a meaningful accuracy
    rec = tmp_path / "rec"
    (rec / "IMG").mkdir(parents=True)
    lines = []
    for i in range(12):
        name = f"center_2024_01_01_12_00_{i:02d}_000.jpg"
        write_image(rec / "IMG" / name, road(seed=i))
        lines.append(f"C:\\\\data\\\\IMG\\\\{name}, left.jpg, right.jpg, 0, 0, 0, 10")
    (rec / "driving_log.csv").write_text("\n".join(lines) + "\n")
    res = runner.invoke(
        app,
        [
            "evaluate",
            "--data",
            f"udacity:{rec}",
            "--method",
            "image-split-uu",
            "--folds",
            "2",
            "--no-cache",
        ],
    )
    assert res.exit_code == 2
    assert "all 12 labels are 'straight'" in res.stderr


def test_evaluate_prints_balanced_accuracy_with_intervals_and_the_baselines(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("COLUMNS", "200")
    args = ["evaluate", "--data", "synthetic:track2:120", "--method", "image-split-uu,kmeans-uu"]
    res = runner.invoke(app, [*args, "--folds", "2", "--paired"])
    assert res.exit_code == 0, res.stderr
    header = next(line for line in res.stdout.splitlines() if "method" in line)
    assert header.index("balanced accuracy") < header.index("accuracy ")
    assert re.search(r"image-split-uu +│ \d\.\d\d \[\d\.\d\d, \d\.\d\d\]", res.stdout)
    assert "majority (training)" in res.stdout and "chance" in res.stdout
    assert "its accuracy can fall below chance" in res.stdout
    assert re.search(r"kmeans-uu - image-split-uu: [+-]\d\.\d\d \[", res.stdout)
    res = runner.invoke(app, [*args, "--folds", "2", "--json"])
    row = json_lines(res.stdout)[0]
    for key in (
        "accuracy",
        "accuracy_std",
        "balanced_accuracy",
        "balanced_accuracy_ci",
        "accuracy_ci",
        "macro_f1",
        "per_class",
        "confusion",
        "predictions",
    ):
        assert key in row, key
    assert row["balanced_accuracy_ci"]["resamples"] == 1000


def test_evaluate_across_recordings_and_its_mistakes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    cross = ["evaluate", "--train", "synthetic:track2:120", "--method", "kmeans-uu"]
    res = runner.invoke(app, [*cross, "--test", "synthetic:track1:100", "--json"])
    assert res.exit_code == 0, res.stderr
    (row,) = json_lines(res.stdout)
    assert row["trained_on"] == ["synthetic-track2"] and row["tested_on"] == "synthetic-track1"
    res = runner.invoke(app, [*cross, "--test", "synthetic:track2:50"])
    assert res.exit_code == 2 and "shares 50 of its 50 frames" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    res = runner.invoke(app, [*cross, "--test", "synthetic:track1:100", "--seeds", "0"])
    assert res.exit_code == 2 and "seeds=0 is invalid" in res.stderr
    res = runner.invoke(app, cross)
    assert res.exit_code == 2 and "test='none' is invalid" in res.stderr
    two = ["--data", "synthetic:track1:120", "--data", "synthetic:track2:120"]
    res = runner.invoke(app, ["evaluate", *two])
    assert res.exit_code == 2 and "--protocol leave-one-out" in res.stderr
    res = runner.invoke(
        app, ["evaluate", *two, "--protocol", "leave-one-out", "--method", "kmeans-uu", "--json"]
    )
    assert res.exit_code == 0, res.stderr
    rows = json_lines(res.stdout)
    assert [(r["tested_on"], r["trained_on"]) for r in rows] == [
        ("synthetic-track1", ["synthetic-track2"]),
        ("synthetic-track2", ["synthetic-track1"]),
    ]


def test_evaluate_rejects_unknown_feature_modes_and_thread_counts() -> None:
    res = runner.invoke(app, ["evaluate", "--data", "synthetic:track1:40", "--features", "curves"])
    assert res.exit_code == 2
    assert "grouping.features='curves' is invalid: one of 'slopes', " in res.stderr
    res = runner.invoke(app, ["evaluate", "--data", "synthetic:track1:40", "--threads", "0"])
    assert res.exit_code == 2 and "threads=0 is invalid: a positive integer" in res.stderr
    res = runner.invoke(app, ["evaluate", "--data", "synthetic:track1:40", "--edges", "hsv"])
    assert res.exit_code == 2 and "edges='hsv' is invalid: 'grey' (the paper)" in res.stderr


def test_a_model_trained_on_a_feature_mode_detects_with_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    model = tmp_path / "model.pkl"
    res = runner.invoke(
        app,
        [
            "train-direction",
            "--data",
            "synthetic:track2:100",
            "--method",
            "kmeans-uu",
            "--features",
            "road-centre",
            "--edges",
            "rgb",
            "--no-shadow-removal",
            "--out",
            str(model),
            "--json",
        ],
    )
    assert res.exit_code == 0, res.stderr
    assert json.loads(res.stdout)["n"] == 100
    lanes = DirectionModel.load(model).config.lanes
    assert lanes.edge_channels == "rgb" and not lanes.remove_shadows
    drive = tmp_path / "drive"  # synth refuses a non-empty folder (the model is in tmp_path)
    res = runner.invoke(app, ["synth", "--preset", "track2", "--n", "3", "--out", str(drive)])
    assert res.exit_code == 0, res.stderr
    frames = drive / "udacity" / "IMG"
    res = runner.invoke(
        app,
        ["detect-lanes", str(frames), "--out", str(tmp_path / "lanes"), "--model", str(model)],
        catch_exceptions=False,
    )
    assert res.exit_code == 0, res.stderr
    res = runner.invoke(
        app,
        [
            "detect-lanes",
            str(frames),
            "--out",
            str(tmp_path / "l2"),
            "--model",
            str(model),
            "--json",
        ],
    )
    *rows, summary = [json.loads(line) for line in res.stdout.splitlines()]
    assert summary["summary"] and summary["n_images"] == 3 and len(rows) == 3
    for row in rows:
        assert len(row["features"]) == 4  # two slopes, then the two road-centre columns
        assert row["direction"] in ("left", "straight", "right")


@pytest.mark.base
def test_evaluate_all_leaves_out_what_cannot_run_here_and_says_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    args = ["evaluate", "--data", "synthetic:track2:200", "--method", "all", "--folds", "2"]
    monkeypatch.setattr("qdcnn.experiments.evaluate.has_torch", lambda: False)
    res = runner.invoke(app, [*args, "--json"])
    assert res.exit_code == 0, res.stderr
    assert "note: skipping dnn-pilotnet: torch is not installed" in res.stderr
    methods = [json.loads(line)["method"] for line in res.stdout.splitlines()]
    # the six paper lane methods and the two classical references (hog-logreg, lines-logreg)
    assert len(methods) == 8 and not any(m.startswith("dnn-") for m in methods)
    assert {"hog-logreg", "lines-logreg"} <= set(methods)
    if importlib.util.find_spec("torch") is None:
        return
    monkeypatch.setattr("qdcnn.experiments.evaluate.has_torch", lambda: True)
    monkeypatch.setattr("qdcnn.experiments.evaluate.has_gpu", lambda: False)
    res = runner.invoke(app, [*args, "--epochs", "1", "--threads", "1", "--json"])
    assert res.exit_code == 0, res.stderr
    assert "note: skipping dnn-resnet50: no GPU" in res.stderr
    *rows, paired = json_lines(res.stdout)
    methods = [row["method"] for row in rows]
    # each hybrid against its classical twin (and its head ablations) on the same frames
    assert [(c["a"], c["b"]) for c in paired["comparisons"]] == [
        ("qdcnn-head", "qdcnn-head-classical"),
        ("qdcnn-head", "qdcnn-head-noent"),
        ("qdcnn-head", "qdcnn-head-fixed"),
        ("qdcnn-head", "qdcnn-head-linear"),
        ("qdcnn-uuconv", "qdcnn-uuconv-classical"),
        ("qdcnn-quanv", "qdcnn-quanv-classical"),
    ]
    assert methods[7:] == [  # after the lane methods (lines-logreg last), in registry order
        "dnn-pilotnet",
        "qdcnn-head",
        "qdcnn-head-classical",
        "qdcnn-head-noent",
        "qdcnn-head-fixed",
        "qdcnn-head-linear",
        "qdcnn-uuconv",
        "qdcnn-uuconv-classical",
        "qdcnn-quanv",
        "qdcnn-quanv-classical",
        "hog-logreg",
    ]


def test_score_shadows_lists_ground_truth_without_a_prediction(tmp_path: Path) -> None:
    pred, gt = tmp_path / "pred", tmp_path / "gt"
    truth = np.zeros((20, 30), bool)
    truth[5:15, 5:15] = True
    for stem in ("a", "b", "c"):
        write_mask(gt / f"{stem}.png", truth)
    write_mask(pred / "a_mask.png", truth)
    res = runner.invoke(app, ["score-shadows", "--pred", str(pred), "--gt", str(gt), "--json"])
    assert res.exit_code == 1
    obj = json_lines(res.stdout)[0]
    assert obj["n"] == 1
    assert [Path(f["file"]).name for f in obj["failures"]] == ["b.png", "c.png"]
    assert "no prediction b_mask.png" in obj["failures"][0]["error"]


@pytest.mark.parametrize("command", ["detect-shadows", "detect-lanes"])
def test_an_empty_folder_and_an_out_that_is_a_file_are_one_line_errors(
    command: str, tmp_path: Path
) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    res = runner.invoke(app, [command, str(empty), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and f"{empty}: no image files found" in res.stderr
    write_image(tmp_path / "a.png", road())
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    res = runner.invoke(app, [command, str(tmp_path / "a.png"), "--out", str(blocker)])
    assert res.exit_code == 2
    assert f"{blocker}: exists and is not a folder" in res.stderr
    assert len(res.stderr.strip().splitlines()) <= 2  # a note on the default model may precede


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["bench", "shadows", "--frames", "0"], "frames=0 is invalid"),
        (["bench", "pipeline", "--frames", "0"], "frames=0 is invalid"),
        (["synth", "--out", "x", "--seed", "-1"], "seed=-1 is invalid"),
        (["evaluate", "--data", "synthetic:track1:40", "--gap", "-1"], "gap=-1 is invalid"),
        (["detect-lanes", ".", "--out", "x", "--seed", "-1"], "seed=-1 is invalid"),
    ],
)
def test_simple_mistakes_are_one_line_errors_not_tracebacks(args: list[str], message: str) -> None:
    res = runner.invoke(app, args)
    assert res.exit_code == 2, res.output
    assert message in res.stderr and "Traceback" not in res.stderr


def test_steering_in_degrees_is_recognised_and_said(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    from qdcnn.data.synthetic import generate_drive

    rec = tmp_path / "rec"
    (rec / "IMG").mkdir(parents=True)
    scenes = generate_drive("track2", 120, seed=3)
    lines = []
    for i, scene in enumerate(scenes):
        write_image(rec / "IMG" / f"{i:06d}.png", scene.image)
        wheel_deg = scene.steering * 25 * 15  # road-wheel degrees times a 15:1 steering ratio
        lines.append(f"IMG/{i:06d}.png,,,{wheel_deg:.1f},0,0,0")
    (rec / "driving_log.csv").write_text("\n".join(lines) + "\n")
    args = ["evaluate", "--data", f"udacity:{rec}", "--method", "image-split-uu", "--folds", "2"]
    res = runner.invoke(app, [*args, "--json"])
    assert res.exit_code == 0, res.stderr
    labels = json.loads(res.stdout.splitlines()[0])["labels"]
    assert labels["steering_unit"] == "deg" and labels["label_threshold"] == 18.75
    res = runner.invoke(app, [*args, "--steering-unit", "rad", "--label-threshold", "0.5"])
    assert res.exit_code == 2 and "is outside" in res.stderr  # degrees read as radians
    res = runner.invoke(app, [*args, "--label-threshold", "5"])
    assert res.exit_code == 0, res.stderr
    assert "labels: steering in deg" in res.stdout and "threshold 5 deg (given)" in res.stdout


def test_inputs_that_share_a_stem_get_distinct_outputs(tmp_path: Path) -> None:
    for sub in ("a", "b"):
        write_image(tmp_path / "in" / sub / "x.png", road(seed=1 if sub == "a" else 2))
    write_image(tmp_path / "in" / "a" / "x.jpg", road(seed=3))
    out = tmp_path / "masks"
    inputs = [str(tmp_path / "in" / "a"), str(tmp_path / "in" / "b")]
    res = runner.invoke(app, ["detect-shadows", *inputs, "--out", str(out), "--json", "--exact"])
    assert res.exit_code == 0, res.stderr
    *records, _summary = json_lines(res.stdout)
    masks = [Path(r["mask"]) for r in records]
    assert len(set(masks)) == 3 and all(m.is_file() for m in masks)
    assert "3 inputs share a file stem" in res.stderr
    again = runner.invoke(app, ["detect-shadows", *inputs, "--out", str(out), "--json", "--exact"])
    assert [r["mask"] for r in json_lines(again.stdout)[:-1]] == [str(m) for m in masks]


def test_a_symlink_in_out_is_replaced_not_followed(tmp_path: Path) -> None:
    write_image(tmp_path / "x.png", road())
    out = tmp_path / "masks"
    out.mkdir()
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    (out / "x_mask.png").symlink_to(victim)
    res = runner.invoke(app, ["detect-shadows", str(tmp_path / "x.png"), "--out", str(out)])
    assert res.exit_code == 0, res.stderr
    assert victim.read_text() == "keep me"
    assert not (out / "x_mask.png").is_symlink()


def test_detect_shadows_resumes_and_redoes_only_what_is_missing(tmp_path: Path) -> None:
    for i in range(4):
        write_image(tmp_path / "in" / f"f{i}.png", road(seed=i))
    out = tmp_path / "masks"
    args = ["detect-shadows", str(tmp_path / "in"), "--out", str(out), "--json"]  # 1024 shots
    first = json_lines(runner.invoke(app, args).stdout)[:-1]
    masks = {Path(r["mask"]).name: Path(r["mask"]).read_bytes() for r in first}
    (out / "f2_mask.png").unlink()
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.stderr
    again = json_lines(res.stdout)[:-1]
    assert [r["resumed"] for r in again] == [True, True, False, True]
    assert {Path(r["mask"]).name: Path(r["mask"]).read_bytes() for r in again} == masks
    forced = json_lines(runner.invoke(app, [*args, "--force"]).stdout)[:-1]
    assert not any(r["resumed"] for r in forced)
    changed = json_lines(runner.invoke(app, [*args, "--threshold", "0.9"]).stdout)[:-1]
    assert not any(r["resumed"] for r in changed)  # another setting: every record is stale


def test_a_second_run_into_a_locked_folder_refuses(tmp_path: Path) -> None:
    from qdcnn.outputs import OutputFolder

    write_image(tmp_path / "a.png", road())
    out = tmp_path / "masks"
    with OutputFolder(out):
        res = runner.invoke(app, ["detect-shadows", str(tmp_path / "a.png"), "--out", str(out)])
    assert res.exit_code == 2
    assert str(out) in res.stderr and len(res.stderr.strip().splitlines()) == 1


def test_train_direction_trains_on_several_recordings_together(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    data = ["--data", "synthetic:track1:60", "--data", "synthetic:track2:120"]
    out = tmp_path / "model.safetensors"
    res = runner.invoke(app, ["train-direction", *data, "--out", str(out), "--json"])
    assert res.exit_code == 0, res.stderr
    obj = json_lines(res.stdout)[0]
    assert obj["n"] == 180 and obj["data"] == "synthetic:track1:60 + synthetic:track2:120"


@pytest.mark.parametrize("command", ["detect-shadows", "detect-lanes", "run"])
@pytest.mark.parametrize("inside", [False, True])
def test_an_output_folder_in_the_input_folder_is_refused(
    command: str, inside: bool, tmp_path: Path
) -> None:
    frames = tmp_path / "frames"
    write_image(frames / "a.png", np.zeros((16, 32, 3), np.uint8))
    out = frames / "out" if inside else frames
    res = runner.invoke(app, [command, str(frames), "--out", str(out)])
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith("error: ") and len(res.stderr.splitlines()) == 1, res.stderr
    assert "input folder" in res.stderr
    assert sorted(p.name for p in frames.iterdir()) == ["a.png"]


def test_run_refuses_an_output_folder_inside_a_recording(tmp_path: Path) -> None:
    rec = tmp_path / "rec"
    res = runner.invoke(app, ["synth", "--n", "10", "--layout", "udacity", "--out", str(rec)])
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["run", f"udacity:{rec}", "--out", str(rec / "run")])
    assert res.exit_code == 2 and "lies inside the input folder" in res.stderr, res.output
    assert not (rec / "run").exists()
