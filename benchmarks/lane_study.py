"""The lane stage on real dashcam frames and on the synthetic ``dashcam`` preset (issue 15).

Three things, each a part (``--parts``):

``camera``
    Auto ROI against the synthetic preset's exact camera: for ``--drives`` dashcam drives
    (``--drive-frames`` frames each, ``--size``), :func:`qdcnn.vision.camera.estimate_camera`
    on every frame of the drive; the horizon error is the estimate minus the median true
    horizon of those frames (fraction of the height), and the share of drives within 5 %.
``lines``
    Fitted lines against the true markings on synthetic dashcam frames: for every frame
    with two fitted lines, the mean horizontal distance (pixels, and fraction of the width)
    between each fitted line and the true marking of its side over the rows the marking is
    visible in the ROI's lower half, per lane-evidence mode.
``overlays``
    ``docs/lanes-real-before-after.jpg`` and ``docs/lanes-synthetic-dashcam.jpg``: frames of
    the real sample (and of a synthetic dashcam drive) with the lane overlay of today's
    ``udacity`` settings (before), of ``auto`` (the paper's evidence in the estimated ROI)
    and of ``auto-marks-filter-inner`` (after), each 320x240, with the camera drawn.
``ceiling``
    A bound that does not depend on the lane stage: HOG features of the grey lower part of
    each frame (below 42 % of the height, resized to 128x56, 8 orientations, 8x8 cells)
    with an L2 logistic regression (C = 0.01), on the same folds and labels.
``direction``
    Direction accuracy of the six quantum methods (5 contiguous folds, gap 5, inner CV, as
    :func:`qdcnn.experiments.evaluate.evaluate_features`) per dataset and mode, with the
    majority class and, as a classical reference, a logistic regression on the two lines'
    angles and bottom intercepts (NaN set to the training mean).

Datasets (``--data``): ``real`` (``../shared/data/real-dashcam-sample``: 1,000 frames,
640x480, steering-wheel angle in radians), ``lake``, ``mountain`` (Udacity simulator),
``synth`` (a ``dashcam`` drive rendered at 640x480, written once as JPEG files under the
cache folder and read back like a recording). Labels: steering smoothed over +-5 frames,
threshold 0.05 in the recording's own unit. For the real sample that is 0.05 rad of the
steering wheel (about 3 degrees; with a typical 15:1 steering ratio about 0.2 degrees at
the road wheels), the threshold the issue's baseline (majority 0.51) was measured with;
it was not chosen for accuracy. The simulator recordings are in [-1, 1] as the README's
tables.

Modes (``--modes``): ``udacity`` (today's ``--lanes udacity``: the fixed Udacity ROI),
``paper-dashcam`` (the ``dashcam`` preset, fixed ROI), ``auto`` (the paper's pipeline with
the ROI estimated per recording: UU-dagger shadow removal, grey Canny, the two slopes),
and named options on top of ``auto``: ``auto-marks`` (white/yellow marks in Lab, no shadow
removal), ``auto-marks-filter`` (+ segments 20-80 degrees and pointing at the vanishing
point within 30 % of the width), ``-inner`` (+ innermost lines), ``-track`` (+ EMA
tracking), ``auto-min10`` (the paper's evidence without segments flatter than 10 degrees),
each with the feature mode ``--features`` (default: the paper's slopes; ``road-centre``
etc.). ``--eval-seed`` changes the classifiers' seed (VQC starting points), not the lanes.

Usage::

    python benchmarks/lane_study.py --parts camera,lines,direction [--data real,synth,lake,mountain]
        [--modes auto,auto-marks] [--features slopes,road-centre] [--json lane_study.json]

Features are cached under ``$QDCNN_CACHE`` (default ``~/.cache/qdcnn``), keyed by the data,
the settings and the package source.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn.config import GroupingConfig, LabelConfig, LaneConfig, PipelineConfig
from qdcnn.data.frames import FrameSet, load_frameset
from qdcnn.direction.features import cache_dir, code_fingerprint
from qdcnn.direction.methods import get_method, method_names
from qdcnn.direction.protocol import ContiguousKFold, majority_baseline
from qdcnn.experiments.evaluate import evaluate_features
from qdcnn.pipeline import auto_lanes, process_recording, recording_sample
from qdcnn.vision.camera import CameraGeometry, estimate_camera
from qdcnn.vision.grouping import GROUPINGS, feature_names

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
REAL = {
    "real": SHARED / "real-dashcam-sample",
    "lake": SHARED / "udacity-lake-track",
    "mountain": SHARED / "udacity-mountain-track",
}
FOLDS, GAP = 5, 5
LABELS = LabelConfig(threshold=0.05)
EXTRAS = ("angles", "intercepts", "far-offsets", "road-centre", "vanishing-point-offset")
MODES = (
    "udacity",
    "paper-dashcam",
    "auto",
    "auto-marks",
    "auto-marks-filter",
    "auto-marks-filter-track",
)


# ----------------------------------------------------------------------------- data


def synthetic_recording(n: int, seed: int, size: tuple[int, int]) -> FrameSet:
    """A dashcam drive written once as JPEG frames, then read back lazily like a recording."""
    w, h = size
    folder = cache_dir() / f"dashcam-drive-{n}-{seed}-{w}x{h}"
    meta = folder / "steering.json"
    if not meta.is_file():
        from qdcnn.data.synthetic import generate_drive

        folder.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        scenes = generate_drive("dashcam", n, seed=seed, width=w, height=h)
        for i, scene in enumerate(scenes):
            bgr = cv2.cvtColor(scene.image, cv2.COLOR_RGB2BGR)
            cv2.imwrite(str(folder / f"{i:05d}.jpg"), bgr, [cv2.IMWRITE_JPEG_QUALITY, 92])
        truth = {
            "steering": [s.steering for s in scenes],
            "horizon": [s.horizon for s in scenes],
            "vanishing_point": [list(s.vanishing_point) for s in scenes],
        }
        meta.write_text(json.dumps(truth))
        print(f"  rendered {n} dashcam frames in {time.perf_counter() - t0:.0f} s", flush=True)
    truth = json.loads(meta.read_text())
    paths = [folder / f"{i:05d}.jpg" for i in range(n)]
    return FrameSet(
        f"synthetic-dashcam-{w}x{h}",
        f"synthetic-dashcam:{n}:{seed}:{w}x{h}",
        np.asarray(truth["steering"], dtype=np.float64),
        np.arange(n) / 10.0,
        [str(p) for p in paths],
        paths=paths,
    )


def load(name: str, synth_frames: int) -> FrameSet:
    if name == "synth":
        return synthetic_recording(synth_frames, 0, (640, 480))
    return load_frameset(f"udacity:{REAL[name]}")


# ----------------------------------------------------------------------------- modes


def mode_config(
    mode: str, frames: FrameSet, features: str
) -> tuple[PipelineConfig, CameraGeometry | None]:
    """Settings of a mode (module docstring), with the camera estimated when it is auto."""
    grouping = GroupingConfig.for_features(features, extra_features=EXTRAS)
    if mode == "udacity":
        return PipelineConfig(lanes=LaneConfig.udacity(), grouping=grouping), None
    if mode == "paper-dashcam":
        return PipelineConfig(lanes=LaneConfig.dashcam(), grouping=grouping), None
    lanes = LaneConfig.dashcam()
    if "marks" in mode:
        lanes = replace(lanes, marks="lab", remove_shadows=False)
    if "filter" in mode:
        lanes = replace(lanes, min_segment_angle=20.0, max_segment_angle=80.0, vp_tolerance=0.3)
    if "min10" in mode:
        lanes = replace(lanes, min_segment_angle=10.0)
    if "inner" in mode:
        grouping = replace(grouping, inner_lines=True)
    if "track" in mode:
        grouping = replace(grouping, track="ema", track_alpha=0.5, track_hold=5)
    sample = [frames.image(i) for i in recording_sample(len(frames))]
    return auto_lanes(sample, PipelineConfig(lanes=lanes, grouping=grouping))


def lane_table(
    frames: FrameSet, config: PipelineConfig, camera: CameraGeometry | None
) -> dict[str, Any]:
    """Features and statuses of every frame for the three groupings (cached)."""
    payload = json.dumps(
        {"data": frames.fingerprint(), "config": config.to_dict(), "code": code_fingerprint()},
        sort_keys=True,
        default=str,
    )
    path = cache_dir() / f"lane-study-{hashlib.sha256(payload.encode()).hexdigest()[:32]}.npz"
    if path.is_file():
        with np.load(path) as data:
            return {k: data[k] for k in data.files}
    images = (frames.image(i) for i in range(len(frames)))
    out: dict[str, Any] = {}
    t0 = time.perf_counter()
    rows: dict[str, list[NDArray[np.float64]]] = {g: [] for g in GROUPINGS}
    status: dict[str, list[str]] = {g: [] for g in GROUPINGS}
    for result in process_recording(images, config, GROUPINGS, camera=camera, rng=config.seed):
        for g, lanes in result.lanes.items():
            rows[g].append(lanes.features)
            status[g].append(lanes.status)
    for g in GROUPINGS:
        out[f"features/{g}"] = np.vstack(rows[g])
        out[f"status/{g}"] = np.array(status[g])
    out["seconds"] = np.array(time.perf_counter() - t0)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **out)
    return out


def logistic_reference(X: NDArray[np.float64], y: NDArray[np.int64]) -> float:
    """Logistic regression on the lines' angles and bottom intercepts (classical, not quantum)."""
    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    names = feature_names(EXTRAS)
    cols = [names.index(n) for n in ("angle_left", "angle_right")]
    cols += [names.index(n) for n in ("intercept_left", "intercept_right")]
    Z = X[:, cols]
    accs = []
    for train, test in ContiguousKFold(FOLDS, GAP).split(y):
        mean = np.nanmean(Z[train], axis=0)
        fill = np.where(np.isnan(mean), 0.0, mean)
        A, B = (
            np.where(np.isnan(Z[train]), fill, Z[train]),
            np.where(np.isnan(Z[test]), fill, Z[test]),
        )
        model = make_pipeline(StandardScaler(), LogisticRegression(C=1.0, max_iter=2000))
        model.fit(A, y[train])
        accs.append(float(np.mean(model.predict(B) == y[test])))
    return float(np.mean(accs))


def direction_part(
    datasets: list[str],
    modes: list[str],
    features: list[str],
    methods: list[str],
    n_synth: int,
    eval_seed: int = 0,
) -> list[dict[str, Any]]:
    rows = []
    for name in datasets:
        frames = load(name, n_synth)
        y = frames.labels(LABELS)
        majority = majority_baseline(y, list(ContiguousKFold(FOLDS, GAP).split(y)))
        print(
            f"{name}: {len(frames)} frames, classes {np.bincount(y, minlength=3).tolist()}, "
            f"majority {majority:.3f}",
            flush=True,
        )
        for mode in modes:
            for feat in features:
                cfg, camera = mode_config(mode, frames, feat)
                if camera is not None and feat == features[0]:
                    print(f"  {mode}: {camera.describe()}", *camera.notes, flush=True)
                t0 = time.perf_counter()
                table = lane_table(frames, cfg, camera)
                row: dict[str, Any] = {
                    "dataset": name,
                    "mode": mode,
                    "features": feat,
                    "majority": majority,
                    "lane_seconds": float(table["seconds"]),
                    "camera": None if camera is None else camera.to_dict(),
                }
                for method in methods:
                    grouping = get_method(method).grouping
                    X = table[f"features/{grouping}"]
                    res = evaluate_features(
                        method,
                        name,
                        X,
                        y,
                        config=replace(cfg, seed=eval_seed),
                        folds=FOLDS,
                        gap=GAP,
                        frames_without_lines=int(np.sum(table[f"status/{grouping}"] != "ok")),
                    )
                    row[method] = res.accuracy
                    row[f"{method}_std"] = res.accuracy_std
                row["logistic"] = logistic_reference(table["features/image-split"], y)
                row["two_lines"] = float(np.mean(table["status/image-split"] == "ok"))
                print(
                    f"  {mode:24s} {feat:12s} "
                    + " ".join(f"{m}={row[m]:.3f}" for m in methods)
                    + f" LR={row['logistic']:.3f} ok={row['two_lines']:.2f}"
                    + f" ({time.perf_counter() - t0:.0f} s)",
                    flush=True,
                )
                rows.append(row)
    return rows


# ----------------------------------------------------------------------------- ground truth


def camera_part(drives: int, n: int, size: tuple[int, int], hood: bool) -> dict[str, Any]:
    from qdcnn.data.synthetic import generate_drive

    errors, x_errors, fallbacks = [], [], 0
    w, h = size
    for seed in range(drives):
        scenes = generate_drive("dashcam", n, seed=1000 + seed, width=w, height=h, hood=hood)
        geometry = estimate_camera([s.image for s in scenes])
        true_y = float(np.median([s.horizon for s in scenes])) / (h - 1)
        true_x = float(np.median([s.vanishing_point[0] for s in scenes])) / (w - 1)
        errors.append(geometry.horizon - true_y)
        x_errors.append(geometry.vanishing_point[0] - true_x)
        fallbacks += geometry.source != "estimated"
    e = np.abs(errors)
    out = {
        "drives": drives,
        "frames": n,
        "size": list(size),
        "hood": hood,
        "within_5pct": float(np.mean(e <= 0.05)),
        "median_abs_error": float(np.median(e)),
        "max_abs_error": float(e.max()),
        "median_abs_vp_x_error": float(np.median(np.abs(x_errors))),
        "fallbacks": fallbacks,
    }
    print("camera", json.dumps(out), flush=True)
    return out


def line_errors(
    scenes: list[Any], config: PipelineConfig, grouping: str = "image-split"
) -> dict[str, float]:
    """Mean |x_fit - x_true| per side over the visible rows of the lower ROI (pixels)."""
    h, w = scenes[0].image.shape[:2]
    per_frame, found = [], 0
    for result, scene in zip(
        process_recording((s.image for s in scenes), config, (grouping,), rng=0),
        scenes,
        strict=True,
    ):
        lanes = result.lanes[grouping]
        if lanes.status != "ok":
            continue
        found += 1
        dists = []
        for line, truth in zip(lanes.lines, scene.lane_lines, strict=True):
            assert line is not None
            if len(truth) < 2:
                continue
            ys, xs = truth[:, 1], truth[:, 0]
            lower = ys >= 0.6 * (h - 1)
            if lower.sum() < 2:
                continue
            dists.append(float(np.mean(np.abs(line[0] * ys[lower] + line[1] - xs[lower]))))
        if dists:
            per_frame.append(float(np.mean(dists)))
    d = np.asarray(per_frame)
    return {
        "frames": len(scenes),
        "two_lines": found / len(scenes),
        "median_px": float(np.median(d)) if d.size else float("nan"),
        "p90_px": float(np.percentile(d, 90)) if d.size else float("nan"),
        "within_2pct_width": float(np.mean(d <= 0.02 * w)) if d.size else float("nan"),
    }


def lines_part(n: int, size: tuple[int, int], modes: list[str]) -> dict[str, Any]:
    from qdcnn.data.synthetic import generate_drive

    w, h = size
    scenes = generate_drive("dashcam", n, seed=2000, width=w, height=h)
    frames = FrameSet(
        "synth-lines",
        "synth-lines",
        np.zeros(n),
        None,
        [str(i) for i in range(n)],
        images=[s.image for s in scenes],
    )
    out = {}
    for mode in modes:
        cfg, _ = mode_config(mode, frames, "slopes")
        out[mode] = line_errors(scenes, cfg)
        print("lines", mode, json.dumps(out[mode]), flush=True)
    return out


def overlay_grid(
    frames: FrameSet, indices: list[int], modes: list[str], labels: NDArray[np.int64] | None
) -> NDArray[np.uint8]:
    """Rows: frames; columns: modes; each tile the lane overlay at 320x240."""
    from qdcnn.data.labels import DIRECTIONS
    from qdcnn.pipeline import process_frame
    from qdcnn.vision.overlays import draw_lane_overlay

    configs = [mode_config(mode, frames, "slopes") for mode in modes]
    rows = []
    for i in indices:
        image = frames.image(i)
        tiles = []
        for mode, (cfg, camera) in zip(modes, configs, strict=True):
            result = process_frame(image, cfg, ("image-split",), rng=0)
            truth = None if labels is None else f"{mode}: label {DIRECTIONS[labels[i]]}"
            tile = draw_lane_overlay(
                image,
                result.segments,
                result.lanes["image-split"],
                truth,
                roi=cfg.lanes.roi,
                camera=camera,
            )
            tiles.append(cv2.resize(tile, (320, 240), interpolation=cv2.INTER_AREA))
        rows.append(np.hstack(tiles))
    return np.vstack(rows)


def overlays_part(out: Path, n_synth: int) -> None:
    modes = ["udacity", "auto", "auto-marks-filter-inner"]
    out.mkdir(parents=True, exist_ok=True)
    real = load("real", n_synth)
    grid = overlay_grid(real, [0, 250, 540, 870], modes, real.labels(LABELS))
    quality = [cv2.IMWRITE_JPEG_QUALITY, 85]
    path = out / "lanes-real-before-after.jpg"
    cv2.imwrite(str(path), cv2.cvtColor(grid, cv2.COLOR_RGB2BGR), quality)
    synth = load("synth", n_synth)
    grid = overlay_grid(synth, [40, 200, 400], modes, synth.labels(LABELS))
    path = out / "lanes-synthetic-dashcam.jpg"
    cv2.imwrite(str(path), cv2.cvtColor(grid, cv2.COLOR_RGB2BGR), quality)
    print("overlays written to", out, flush=True)


def ceiling_part(datasets: list[str], n_synth: int) -> dict[str, Any]:
    from skimage.feature import hog
    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    out = {}
    for name in datasets:
        frames = load(name, n_synth)
        y = frames.labels(LABELS)
        rows = []
        for i in range(len(frames)):
            grey = cv2.cvtColor(frames.image(i), cv2.COLOR_RGB2GRAY)
            lower = grey[int(0.42 * grey.shape[0]) :]
            small = cv2.resize(lower, (128, 56), interpolation=cv2.INTER_AREA)
            rows.append(hog(small, orientations=8, pixels_per_cell=(8, 8), cells_per_block=(1, 1)))
        H = np.asarray(rows)
        accs = []
        for train, test in ContiguousKFold(FOLDS, GAP).split(y):
            model = make_pipeline(StandardScaler(), LogisticRegression(C=0.01, max_iter=3000))
            model.fit(H[train], y[train])
            accs.append(float(np.mean(model.predict(H[test]) == y[test])))
        out[name] = {"hog_logistic": float(np.mean(accs)), "folds": accs}
        print("ceiling", name, json.dumps(out[name]), flush=True)
    return out


def markdown(rows: list[dict[str, Any]], methods: list[str]) -> str:
    head = ["dataset", "mode", "features", *methods, "majority", "LR (classical)", "two lines"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [r["dataset"], r["mode"], r["features"]]
        cells += [f"{r[m]:.3f}" for m in methods]
        cells += [f"{r['majority']:.3f}", f"{r['logistic']:.3f}", f"{r['two_lines']:.2f}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default="camera,lines,direction")
    parser.add_argument("--data", default="real,synth,lake,mountain")
    parser.add_argument("--modes", default=",".join(MODES))
    parser.add_argument("--features", default="slopes")
    parser.add_argument("--methods", default=",".join(method_names(inputs="lanes")))
    parser.add_argument("--synth-frames", type=int, default=600)
    parser.add_argument(
        "--eval-seed", type=int, default=0, help="seed of the classifiers (not of the lanes)"
    )
    parser.add_argument("--drives", type=int, default=40)
    parser.add_argument("--drive-frames", type=int, default=30)
    parser.add_argument("--size", default="320x240", help="frame size of the camera part")
    parser.add_argument("--json", default="lane_study.json")
    parser.add_argument("--docs", default=str(Path(__file__).resolve().parents[1] / "docs"))
    args = parser.parse_args()
    size = tuple(int(v) for v in args.size.split("x"))
    assert len(size) == 2
    results: dict[str, Any] = {}
    parts = args.parts.split(",")
    modes = args.modes.split(",")
    if "camera" in parts:
        results["camera"] = [
            camera_part(args.drives, args.drive_frames, (size[0], size[1]), hood)
            for hood in (False, True)
        ]
    if "lines" in parts:
        results["lines"] = lines_part(60, (640, 480), [m for m in modes if m != "udacity"])
    if "ceiling" in parts:
        results["ceiling"] = ceiling_part(args.data.split(","), args.synth_frames)
    if "overlays" in parts:
        overlays_part(Path(args.docs), args.synth_frames)
    if "direction" in parts:
        methods = args.methods.split(",")
        rows = direction_part(
            args.data.split(","),
            modes,
            args.features.split(","),
            methods,
            args.synth_frames,
            args.eval_seed,
        )
        results["direction"] = rows
        print()
        print(markdown(rows, methods))
    Path(args.json).write_text(json.dumps(results, indent=1, default=str))


if __name__ == "__main__":
    main()
