"""How far the quantum direction methods go: the paper's features against named modes.

For every dataset and every mode this runs the six quantum methods (grouping x UU-dagger /
VQC) through :func:`qdcnn.experiments.evaluate.evaluate_features` (5 contiguous folds, gap
5, hyperparameters by the inner contiguous CV of the method registry), and, on the same rows and
folds, a classical upper bound: scikit-learn's ``HistGradientBoostingClassifier`` on the
mode's two columns and on every column of the feature table. It also times the per-frame
pipeline (``process_frame`` with image-split grouping + the UU decision) on one core.

Modes (every one but "paper" is a named option, not the paper's):

``paper``
    ``LaneConfig.udacity()`` (the paper's settings with 1 smoothing pass at 320x160),
    UU-dagger shadow removal, grey edges, the two slopes.
``slopes-rgb``
    Lane-evidence changes only: no shadow removal, colour Canny (``edge_channels="rgb"``),
    the two slopes and the paper's classifier grids.
``far-offsets``, ``road-centre``, ``vanishing-points``
    As ``slopes-rgb``, with the feature mode of that name
    (:attr:`qdcnn.config.GroupingConfig.FEATURE_MODES`) and the named modes' VQC grid.

Features are cached by :func:`qdcnn.direction.lane_data.load_lane_data`; the named
modes share one feature table (all their extras computed at once).

Usage::

    python benchmarks/direction_study.py [--data lake,mountain,track1,track2,rain]
        [--modes paper,slopes-rgb,far-offsets,road-centre,vanishing-points]
        [--frames 600] [--json study.json] [--no-timing] [--methods image-split-uu,...]
    python benchmarks/direction_study.py --ceilings [--data ...]   # bounds, no lane stage

``--data`` takes the short names below or any ``udacity:PATH``/``carla:PATH``/
``synthetic:PRESET[:N]`` spec. Results are printed as a Markdown table and written as
JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from sklearn.ensemble import HistGradientBoostingClassifier

from qdcnn.config import GroupingConfig, LaneConfig, PipelineConfig
from qdcnn.data.frames import FrameSet, load_frameset
from qdcnn.direction.lane_data import load_lane_data
from qdcnn.direction.methods import GROUPINGS, get_method, method_names
from qdcnn.direction.protocol import ContiguousKFold
from qdcnn.experiments.evaluate import evaluate_features
from qdcnn.pipeline import process_frame
from qdcnn.vision.grouping import mode_columns

LANE_METHODS = method_names(inputs="lanes")
SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
DATASETS = {
    "lake": f"udacity:{SHARED / 'udacity-lake-track'}",
    "mountain": f"udacity:{SHARED / 'udacity-mountain-track'}",
    "track1": "synthetic:track1",
    "track2": "synthetic:track2",
    "rain": "synthetic:rain",
}
NAMED_MODES = ("far-offsets", "road-centre", "vanishing-points")
MODES = ("paper", "slopes-rgb", *NAMED_MODES)
FOLDS, GAP = 5, 5


def paper_config() -> PipelineConfig:
    """The paper's pipeline at 320x160 (1 smoothing pass, see ``LaneConfig.udacity``)."""
    return replace(PipelineConfig(), lanes=LaneConfig.udacity())


def named_base_config() -> PipelineConfig:
    """No shadow removal, colour edges, and every named mode's extras in one table."""
    extras: tuple[str, ...] = ()
    for mode in NAMED_MODES:
        extras += tuple(e for e in GroupingConfig.FEATURE_MODES[mode][1] if e not in extras)
    return replace(
        PipelineConfig(),
        lanes=LaneConfig.udacity(remove_shadows=False, edge_channels="rgb"),
        grouping=GroupingConfig(extra_features=extras),
    )


def mode_config(mode: str) -> PipelineConfig:
    """The pipeline settings of a mode (module docstring)."""
    if mode == "paper":
        return paper_config()
    base = named_base_config()
    features = "slopes" if mode == "slopes-rgb" else mode
    return replace(base, grouping=replace(base.grouping, features=features))


def gbm_accuracy(X: np.ndarray, y: np.ndarray) -> float:
    """Mean accuracy of gradient boosting over the study's contiguous folds (NaN allowed)."""
    accs = []
    for train, test in ContiguousKFold(FOLDS, GAP).split(y):
        model = HistGradientBoostingClassifier(
            max_iter=150, learning_rate=0.05, max_leaf_nodes=15, l2_regularization=1.0
        )
        model.fit(X[train], y[train])
        accs.append(float(np.mean(model.predict(X[test]) == y[test])))
    return float(np.mean(accs))


def time_pipeline(frames: FrameSet, config: PipelineConfig, n: int = 200) -> dict[str, float]:
    """Per-frame seconds of ``process_frame`` (image-split) + a fitted UU decision, one core.

    The UU rule is fitted on the timed frames' own features (the fit is not timed); the
    decision of each frame is one ``predict`` call on its feature row, as a live car would.
    """
    import cv2

    try:
        old_affinity = os.sched_getaffinity(0)
        os.sched_setaffinity(0, {min(old_affinity)})
    except (AttributeError, OSError):
        old_affinity = None
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        idx = np.linspace(0, len(frames) - 1, min(n, len(frames))).astype(int)
        images = [frames.image(int(i)) for i in idx]
        process_frame(images[0], config, ("image-split",), rng=0)  # warm-up (caches)
        rows, lane_times = [], []
        for image in images:
            t0 = time.perf_counter()
            result = process_frame(image, config, ("image-split",), rng=0)
            lane_times.append(time.perf_counter() - t0)
            rows.append(result.lanes["image-split"].features)
        X = np.vstack(rows)
        y = frames.labels(config.labels)[idx]
        clf, _ = get_method("image-split-uu").estimator(config)
        ok = np.isfinite(X).all(axis=1)
        decide_times = []
        if ok.sum() >= 3 and len(np.unique(y[ok])) > 1:
            clf.fit(X, y)
            for row in X:
                t0 = time.perf_counter()
                clf.predict(row[None, :])
                decide_times.append(time.perf_counter() - t0)
        lanes = statistics.median(lane_times)
        decide = statistics.median(decide_times) if decide_times else float("nan")
        return {"lanes_s": lanes, "decision_s": decide, "total_s": lanes + decide}
    finally:
        cv2.setNumThreads(threads)
        if old_affinity is not None:
            os.sched_setaffinity(0, old_affinity)


def study_dataset(
    spec: str, modes: list[str], methods: list[str], frames_default: int, timing: bool
) -> list[dict[str, Any]]:
    """All modes x methods on one dataset, plus the classical bounds and timing."""
    if spec.startswith("synthetic:") and spec.count(":") == 1:
        spec = f"{spec}:{frames_default}"
    frames = load_frameset(spec)
    out = []
    tables: dict[str, Any] = {}
    for mode in modes:
        cfg = mode_config(mode)
        table_key = "paper" if mode == "paper" else "named"
        if table_key not in tables:
            t0 = time.perf_counter()
            tables[table_key] = load_lane_data(frames, cfg, GROUPINGS)
            print(f"  features {frames.name}/{table_key}: {time.perf_counter() - t0:.0f} s")
        lanes = tables[table_key]
        table, keep, y = lanes.table, lanes.keep, lanes.y
        columns = mode_columns(cfg.grouping.features, cfg.grouping.extra_features)
        row: dict[str, Any] = {"dataset": frames.name, "mode": mode, "n": int(keep.sum())}
        for method in methods:
            grouping = get_method(method).grouping
            X = table.features[grouping][keep]
            res = evaluate_features(
                method,
                frames.name,
                X,
                y,
                config=cfg,
                folds=FOLDS,
                gap=GAP,
                frames_without_lines=table.frames_without_lines(grouping),
            )
            row[method] = res.accuracy
            row["majority"] = res.majority_baseline
            row.setdefault("chosen", {})[method] = res.extra["chosen_hyperparameters"]
        X_split = table.features["image-split"][keep]
        row["gbm_pair"] = gbm_accuracy(X_split[:, list(columns)], y)
        row["gbm_all"] = gbm_accuracy(X_split, y)
        if timing:
            row.update({f"time_{k}": v for k, v in time_pipeline(frames, cfg).items()})
        print(
            f"  {frames.name:24s} {mode:17s} "
            + " ".join(f"{m}={row[m]:.3f}" for m in methods)
            + f" gbm2={row['gbm_pair']:.3f} gbm_all={row['gbm_all']:.3f}",
            flush=True,
        )
        out.append(row)
    return out


def ceilings(spec: str, frames_default: int) -> dict[str, float]:
    """Bounds that do not depend on the lane stage, same folds and labels.

    - ``hog_logistic``: HOG of the grey road band (rows 60-139, resized to 128x40) with an
      L2 logistic regression (C = 0.01): how much of the label any image classifier can
      get from one frame without trying hard.
    - synthetic only: gradient boosting on the exact ``lane_lines`` of the generator (x at
      9 rows per line) and on the true road curvature ``d`` frames ahead of the car
      (``curvature_ahead_d``): the label is the steering at the car, while a frame shows
      the road 3 m and more ahead.
    """
    import cv2
    from skimage.feature import hog
    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    if spec.startswith("synthetic:") and spec.count(":") == 1:
        spec = f"{spec}:{frames_default}"
    frames = load_frameset(spec)
    y = frames.labels()
    hogs = []
    for i in range(len(frames)):
        grey = cv2.cvtColor(frames.image(i), cv2.COLOR_RGB2GRAY)[60:140]
        hogs.append(
            hog(
                cv2.resize(grey, (128, 40)),
                orientations=8,
                pixels_per_cell=(8, 8),
                cells_per_block=(1, 1),
            )
        )
    H = np.asarray(hogs)
    accs = []
    for train, test in ContiguousKFold(FOLDS, GAP).split(y):
        model = make_pipeline(StandardScaler(), LogisticRegression(C=0.01, max_iter=2000))
        model.fit(H[train], y[train])
        accs.append(float(np.mean(model.predict(H[test]) == y[test])))
    out = {"hog_logistic": float(np.mean(accs))}
    if spec.startswith("synthetic:"):
        from qdcnn.data.synthetic import generate_drive

        _, preset, count = spec.split(":")
        scenes = generate_drive(preset, int(count), seed=0)
        rows = np.linspace(70, 150, 9)
        lanes = []
        for scene in scenes:
            values: list[float] = []
            for k in range(2):
                line = scene.lane_lines[k] if len(scene.lane_lines) > k else np.zeros((0, 2))
                if len(line) < 2:
                    values += [np.nan] * rows.size
                    continue
                order = np.argsort(line[:, 1])
                ys, xs = line[order, 1], line[order, 0]
                inside = (rows >= ys.min()) & (rows <= ys.max())
                values += list(np.where(inside, np.interp(rows, ys, xs), np.nan))
            lanes.append(values)
        L = np.asarray(lanes)
        out["exact_lane_lines_gbm"] = gbm_accuracy(L[:, np.isfinite(L).sum(axis=0) > 10], y)
        curvature = np.array([scene.curvature for scene in scenes])
        for d in (0, 3, 6, 10):
            ahead = np.r_[curvature[d:], np.full(d, curvature[-1])]
            out[f"curvature_ahead_{d}"] = gbm_accuracy(ahead[:, None], y)
    return out


def markdown(rows: list[dict[str, Any]]) -> str:
    """The accuracy table (and per-frame times when measured) as Markdown."""
    head = ["dataset", "mode", *LANE_METHODS, "majority", "GBM 2 cols", "GBM all"]
    timed = any("time_total_s" in r for r in rows)
    if timed:
        head.append("ms/frame (1 core)")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [r["dataset"], r["mode"]]
        cells += [f"{r[m]:.3f}" if m in r else "-" for m in LANE_METHODS]
        cells += [f"{r['majority']:.3f}", f"{r['gbm_pair']:.3f}", f"{r['gbm_all']:.3f}"]
        if timed:
            cells.append(f"{1e3 * r.get('time_total_s', float('nan')):.2f}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=",".join(DATASETS))
    parser.add_argument("--modes", default=",".join(MODES))
    parser.add_argument("--frames", type=int, default=600, help="frames per synthetic preset")
    parser.add_argument("--json", default="direction_study.json")
    parser.add_argument("--no-timing", action="store_true")
    parser.add_argument(
        "--ceilings", action="store_true", help="only the lane-independent bounds (ceilings())"
    )
    parser.add_argument(
        "--methods", default=",".join(LANE_METHODS), help="quantum methods to evaluate"
    )
    args = parser.parse_args()
    modes = args.modes.split(",")
    methods = args.methods.split(",")
    if any(m not in LANE_METHODS for m in methods):
        parser.error(f"methods must be among {', '.join(LANE_METHODS)}")
    unknown = [m for m in modes if m not in MODES]
    if unknown:
        parser.error(f"unknown modes {unknown}; choose from {', '.join(MODES)}")
    if args.ceilings:
        bounds = {}
        for name in args.data.split(","):
            bounds[name] = ceilings(DATASETS.get(name, name), args.frames)
            print(name, json.dumps(bounds[name]), flush=True)
        Path(args.json).write_text(json.dumps(bounds, indent=1))
        return
    rows: list[dict[str, Any]] = []
    for name in args.data.split(","):
        spec = DATASETS.get(name, name)
        print(f"{name}: {spec}", flush=True)
        rows += study_dataset(spec, modes, methods, args.frames, not args.no_timing)
        Path(args.json).write_text(
            json.dumps({"platform": platform.platform(), "rows": rows}, indent=1, default=str)
        )
    print()
    print(markdown(rows))


if __name__ == "__main__":
    main()
