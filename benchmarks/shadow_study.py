"""Shadow-detection study: UU-dagger modes against IBT, CBS and LBP on the synthetic presets.

For each preset (``track2``, ``track1``, ``rain``) three disjoint scene sets are generated:
training (seed 1), validation (seed 2) and test (seed 1000), ``--n`` scenes each at 320x160.
Trained models learn on the training set only; the number of centroids of the
multi-centroid models is chosen on the validation set (its BER is printed too); the
test set is used only for the final table. BER, shadow error and non-shadow error are
in percent with pixel counts summed over the set (:mod:`qdcnn.vision.metrics`).

Rows:

- ``ibt``, ``cbs``, ``lbp``: the classical baselines (:mod:`qdcnn.vision.baselines`).
- ``uu-calibrated``: paper mode, per-image centroid from the two-means start + propagation.
- ``uu-calibrated-k3``, ``uu-calibrated-k4``: the same with a 3- or 4-class multi-Otsu start
  (``ShadowConfig.calibration_classes``).
- ``uu-trained``: paper mode, one intensity centroid trained on the training masks
  (:func:`~qdcnn.vision.shadows.train_shadow_model`), threshold 0.97.
- ``uu-multi-i``: multi-centroid intensity model, ``k`` chosen on validation.
- ``uu-multi-ic``: multi-centroid intensity + chromaticity model (one UU-dagger circuit per
  feature and component, :func:`~qdcnn.vision.shadows.train_multi_shadow_model`).
- ``uu-multi-ic-1024``: the same model with 1024 shots per circuit instead of exact
  probabilities.
- ``uu-multi-ic-fine``: the same training on a finer block grid (downsample 2, 200 blocks
  per side: 2x2-pixel blocks at 320x160).
- ``bound-gbt-*``: not UU-dagger. A class-balanced gradient-boosted tree classifier
  (scikit-learn) trained on the same training blocks, on the same two features (``-ic``) or
  on a richer per-block set (``-rich``: mean R, G, B, intensity, c3, intensity standard
  deviation, intensity over its 25-block local maximum, block row), on the paper grid and
  the fine grid. Its decision region is free-form, so it shows how far band tests on these
  features could go at best.
- ``oracle-blocks``, ``oracle-blocks-fine``: every block decided by its ground-truth shadow
  fraction (>= 0.5), then expanded and median filtered: the floor of any block classifier
  on that grid.

Times are per 320x160 frame on one thread (OpenCV and BLAS limited to one thread),
exact probabilities unless the row says 1024 shots, averaged over the track2 test frames.

Usage::

    python benchmarks/shadow_study.py [--n 30] [--presets track2,track1,rain] [--no-lbp]
                                      [--json results.json]
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np
from numpy.typing import NDArray
from threadpoolctl import threadpool_limits  # type: ignore[import-untyped]

from qdcnn.config import ShadowConfig
from qdcnn.data.synthetic import generate_scenes
from qdcnn.errors import ParameterError
from qdcnn.vision.baselines import detect_cbs, detect_ibt, detect_lbp
from qdcnn.vision.metrics import ShadowScores, confusion_counts, shadow_scores
from qdcnn.vision.shadow_training import (
    block_shadow_fraction,
    train_multi_shadow_model,
    train_shadow_model,
)
from qdcnn.vision.shadows import (
    ShadowModel,
    binary_median,
    block_grid,
    block_means,
    detect_shadows_uu,
    expand_blocks,
    feature_input,
)

SEEDS = {"train": 1, "validation": 2, "test": 1000}
EXACT = ShadowConfig(shots=None)
FINE = replace(EXACT, downsample=2, grid=200)
MULTI_K = (1, 2, 3, 4)

Detector = Callable[[NDArray[np.uint8]], NDArray[np.bool_]]
Scene = tuple[NDArray[np.uint8], NDArray[np.bool_]]


@dataclass
class Row:
    name: str
    scores: ShadowScores | None
    note: str = ""


def load(preset: str, split: str, n: int) -> list[Scene]:
    return [(s.image, s.shadow_mask) for s in generate_scenes(preset, n, seed=SEEDS[split])]


def evaluate(detector: Detector, scenes: Sequence[Scene]) -> ShadowScores:
    return shadow_scores([confusion_counts(detector(im), gt) for im, gt in scenes])


def oracle_scores(scenes: Sequence[Scene], config: ShadowConfig) -> ShadowScores:
    counts = []
    for im, gt in scenes:
        geometry = block_grid(im.shape[:2], config.downsample, config.grid)
        blocks = block_shadow_fraction(gt, config) >= 0.5
        full = binary_median(expand_blocks(blocks, geometry).view(np.uint8), config.median_ksize)
        counts.append(confusion_counts(full.astype(bool), gt))
    return shadow_scores(counts)


def block_table(image: NDArray[np.uint8], config: ShadowConfig, rich: bool) -> NDArray[np.float64]:
    """Per-block features for the classifier bounds: intensity and c3 (as the UU model sees
    them); ``rich`` adds mean R, G, B, the intensity standard deviation in the block, the
    intensity over the local maximum of a 25-block window and the block row."""
    geometry = block_grid(image.shape[:2], config.downsample, config.grid)
    grey = feature_input(image, "intensity").astype(np.float64)
    cols = [block_means(grey, geometry, config.downsample)]
    cols.append(block_means(feature_input(image, "chromaticity"), geometry, config.downsample))
    if rich:
        rgb = image.astype(np.float64)
        cols += [block_means(rgb[..., c].copy(), geometry, config.downsample) for c in range(3)]
        var = block_means(grey * grey, geometry, config.downsample) - cols[0] ** 2
        cols.append(np.sqrt(np.maximum(var, 0.0)))
        local_max = cv2.dilate(cols[0].astype(np.float32), np.ones((25, 25), np.uint8))
        cols.append(cols[0] / (local_max + 1.0))
        rows = np.linspace(0.0, 1.0, geometry.grid_shape[0])[:, None]
        cols.append(np.broadcast_to(rows, geometry.grid_shape))
    return np.stack([c.ravel() for c in cols], axis=1)


def classifier_bound(train: Sequence[Scene], config: ShadowConfig, rich: bool) -> Detector:
    """A gradient-boosted tree classifier (class-balanced) on per-block features: a flexible
    decision region instead of the UU-dagger bands, to bound what the block features allow."""
    from sklearn.ensemble import HistGradientBoostingClassifier

    x = np.concatenate([block_table(im, config, rich) for im, _ in train])
    y = np.concatenate([block_shadow_fraction(gt, config).ravel() >= 0.5 for _, gt in train])
    clf = HistGradientBoostingClassifier(class_weight="balanced", random_state=0).fit(x, y)

    def detect(im: NDArray[np.uint8]) -> NDArray[np.bool_]:
        geometry = block_grid(im.shape[:2], config.downsample, config.grid)
        blocks = clf.predict(block_table(im, config, rich)).reshape(geometry.grid_shape)
        full = expand_blocks(blocks.astype(bool), geometry).view(np.uint8)
        return binary_median(full, config.median_ksize).astype(bool)

    return detect


def uu(config: ShadowConfig, model: ShadowModel | None = None, seed: int | None = None) -> Detector:
    rng = None if seed is None else np.random.default_rng(seed)
    return lambda im: detect_shadows_uu(im, config, model=model, rng=rng).mask


def pick_k(
    train: Sequence[Scene],
    validation: Sequence[Scene],
    config: ShadowConfig,
    features: tuple[str, ...],
    ks: Sequence[int],
) -> tuple[ShadowModel | None, dict[int, float]]:
    """Train one model per k on ``train``; return the one with the lowest validation BER."""
    images, masks = [s[0] for s in train], [s[1] for s in train]
    best: tuple[float, ShadowModel | None] = (np.inf, None)
    curve: dict[int, float] = {}
    for k in ks:
        try:
            model = train_multi_shadow_model(
                images, masks, config, features=features, n_centroids=k
            )
        except ParameterError:  # too few shadow blocks for k clusters
            continue
        curve[k] = evaluate(uu(config, model), validation).ber
        if curve[k] < best[0]:
            best = (curve[k], model)
    return best[1], curve


def frame_time(detector: Detector, frames: Sequence[NDArray[np.uint8]], repeats: int = 3) -> float:
    """Mean seconds per frame (best of ``repeats`` passes over ``frames``)."""
    for im in frames[:2]:
        detector(im)
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for im in frames:
            detector(im)
        best = min(best, (time.perf_counter() - t0) / len(frames))
    return float(best)


def fmt(scores: ShadowScores | None) -> str:
    if scores is None:
        return f"{'n/a':>20}"
    return f"{scores.ber:5.1f} ({scores.shadow_error:5.1f}/{scores.nonshadow_error:5.1f})"


def run_preset(
    preset: str, n: int, with_lbp: bool
) -> tuple[list[Row], dict[str, Detector], dict[str, object]]:
    train, validation, test = (load(preset, split, n) for split in ("train", "validation", "test"))
    images, masks = [s[0] for s in train], [s[1] for s in train]
    detectors: dict[str, Detector] = {"ibt": detect_ibt, "cbs": detect_cbs}
    if with_lbp:
        detectors["lbp"] = detect_lbp
    detectors["uu-calibrated"] = uu(EXACT)
    detectors["uu-calibrated-k3"] = uu(replace(EXACT, calibration_classes=3))
    detectors["uu-calibrated-k4"] = uu(replace(EXACT, calibration_classes=4))
    info: dict[str, object] = {}
    paper = train_shadow_model(images, masks, EXACT)
    detectors["uu-trained"] = uu(EXACT, paper)
    info["uu-trained"] = {"centroid": round(paper.centroid, 2), "threshold": paper.threshold}
    for name, cfg, features in (
        ("uu-multi-i", EXACT, ("intensity",)),
        ("uu-multi-ic", EXACT, ("intensity", "chromaticity")),
        ("uu-multi-ic-fine", FINE, ("intensity", "chromaticity")),
    ):
        ks = MULTI_K if len(features) > 1 else MULTI_K[:3]
        model, curve = pick_k(train, validation, cfg, features, ks)
        info[name] = {
            "validation_ber_by_k": {k: round(b, 2) for k, b in curve.items()},
            "k": None if model is None else len(model.centroids),
            "centroids": None if model is None else [list(np.round(c, 1)) for c in model.centroids],
            "thresholds": None
            if model is None
            else [list(np.round(t, 4)) for t in model.thresholds],
        }
        if model is not None:
            detectors[name] = uu(cfg, model)
            if name == "uu-multi-ic":
                detectors["uu-multi-ic-1024"] = uu(replace(cfg, shots=1024), model, seed=7)
    rows = [Row(name, evaluate(det, test)) for name, det in detectors.items()]
    bounds = {
        "bound-gbt-ic": classifier_bound(train, EXACT, rich=False),
        "bound-gbt-ic-fine": classifier_bound(train, FINE, rich=False),
        "bound-gbt-rich": classifier_bound(train, EXACT, rich=True),
        "bound-gbt-rich-fine": classifier_bound(train, FINE, rich=True),
    }
    note = "not UU: same training set, gradient-boosted trees"
    rows += [Row(name, evaluate(det, test), note) for name, det in bounds.items()]
    rows.append(Row("oracle-blocks", oracle_scores(test, EXACT), "needs ground truth"))
    rows.append(Row("oracle-blocks-fine", oracle_scores(test, FINE), "needs ground truth"))
    return rows, detectors, info


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=30, help="scenes per split")
    parser.add_argument("--presets", default="track2,track1,rain")
    parser.add_argument("--no-lbp", action="store_true", help="skip the slow LBP baseline")
    parser.add_argument("--json", default=None, help="also write the results here")
    args = parser.parse_args()

    cv2.setNumThreads(1)
    presets = [p.strip() for p in args.presets.split(",") if p.strip()]
    results: dict[str, dict[str, object]] = {}
    times: dict[str, float] = {}
    with threadpool_limits(limits=1):
        for preset in presets:
            rows, detectors, info = run_preset(preset, args.n, not args.no_lbp)
            results[preset] = {
                "rows": {r.name: None if r.scores is None else r.scores.to_dict() for r in rows},
                "models": info,
            }
            print(f"\n== {preset}: test set (seed {SEEDS['test']}, {args.n} scenes) ==")
            print(f"{'method':<22}{'BER (shadow/non-shadow err)':>30}")
            for r in rows:
                print(f"{r.name:<22}{fmt(r.scores):>30}  {r.note}")
            for name, item in info.items():
                print(f"  {name}: {item}")
            if preset == "track2":
                frames = [s.image for s in generate_scenes("track2", args.n, seed=SEEDS["test"])]
                times = {name: frame_time(det, frames) for name, det in detectors.items()}
    if times:
        print("\n== time per 320x160 frame, one thread (track2 test frames) ==")
        for name, seconds in times.items():
            print(f"{name:<22}{seconds * 1e3:9.2f} ms")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"results": results, "seconds_per_frame": times}, fh, indent=2, default=str)


if __name__ == "__main__":
    main()
