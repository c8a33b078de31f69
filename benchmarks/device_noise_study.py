"""How the quantum classifiers degrade under real devices' calibrated noise (issue 11, item 5).

For each fake backend (``device:NAME``), the same models as the noise grid of
``bench_noise.py`` -- per contiguous fold, a UU-dagger rule and a VQC trained once without
noise on ``--data``'s lane features -- classify their test frames with exact density-matrix
probabilities under the device's noise (native gates, the least-error default layout,
asymmetric readout); the UU-dagger shadow detector, its centroid trained on synthetic
scenes with masks, is scored (BER) on held-out scenes. Times are measured on this
machine, one thread: loading the calibration, and each noisy evaluation.

Usage::

    python benchmarks/device_noise_study.py [--devices FakeManilaV2,FakeSherbrooke,FakeTorino]
        [--data synthetic:track2:300] [--shadow-frames 12] [--json]
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from qdcnn.config import PAPER_SHADOW_THRESHOLDS as SHADOW_THRESHOLDS
from qdcnn.config import ShadowConfig
from qdcnn.data.frames import load_frameset
from qdcnn.data.splits import ContiguousKFold
from qdcnn.direction.features import compute_features
from qdcnn.direction.model import default_config
from qdcnn.experiments.noise import (
    fit_direction_model,
    predict_folds,
    split_train_test,
    synthetic_shadow_set,
)
from qdcnn.quantum.device import DeviceNoise
from qdcnn.quantum.noise import NoiseSpec
from qdcnn.vision.metrics import ConfusionCounts, confusion_counts, shadow_scores
from qdcnn.vision.shadow_training import train_shadow_model
from qdcnn.vision.shadows import detect_shadows_uu


def direction_rows(data: str, devices: dict[str, NoiseSpec | None], seed: int) -> list[dict]:
    cfg = replace(default_config(), seed=seed)
    frames = load_frameset(data, seed=seed)
    table = compute_features(frames, cfg, ("image-split",))
    keep = table.readable
    X = table.features["image-split"][keep]
    y = frames.labels(cfg.labels)[keep]
    splits = list(ContiguousKFold(5, gap=5).split(y))
    truth = np.concatenate([y[test] for _, test in splits])
    rows = []
    for method in ("uu", "vqc"):
        models = [
            (test, fit_direction_model(method, X[train], y[train], cfg, seed=seed))
            for train, test in splits
        ]
        for name, noise in devices.items():
            t0 = time.perf_counter()
            pred = predict_folds(models, X, noise)
            rows.append(
                {
                    "part": "direction",
                    "method": method,
                    "noise": name,
                    "accuracy": round(float(np.mean(pred == truth)), 4),
                    "frames": int(truth.size),
                    "seconds_measured": round(time.perf_counter() - t0, 3),
                }
            )
    return rows


def shadow_rows(frames: int, devices: dict[str, NoiseSpec | None], seed: int) -> list[dict]:
    images, masks = synthetic_shadow_set(frames, seed=seed)
    train, test = split_train_test(len(images))
    cfg = ShadowConfig(shots=None)
    model = train_shadow_model(images[train], masks[train], cfg, tuple(SHADOW_THRESHOLDS))
    rows = []
    for name, noise in devices.items():
        counts = ConfusionCounts(0, 0, 0, 0)
        t0 = time.perf_counter()
        for image, mask in zip(images[test], masks[test], strict=True):
            det = detect_shadows_uu(image, cfg, model=model, noise=noise)
            counts = counts + confusion_counts(det.mask, mask)
        scores = shadow_scores(counts)
        rows.append(
            {
                "part": "shadows",
                "method": "uu-shadow",
                "noise": name,
                "ber": round(scores.ber, 2),
                "frames": len(images[test]),
                "seconds_measured": round(time.perf_counter() - t0, 3),
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--devices", default="FakeManilaV2,FakeSherbrooke,FakeTorino")
    parser.add_argument("--data", default="synthetic:track2:300")
    parser.add_argument("--shadow-frames", type=int, default=12)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()

    devices: dict[str, NoiseSpec | None] = {"ideal": None}
    loads: list[dict[str, Any]] = []
    with threadpool_limits(1):
        for name in filter(None, args.devices.split(",")):
            t0 = time.perf_counter()
            dev = DeviceNoise.from_backend(name)
            devices[dev.label()] = dev
            loads.append(
                {
                    "part": "load",
                    "noise": dev.label(),
                    "qubits": dev.calibration.num_qubits,
                    "two_qubit_gate": dev.calibration.two_qubit_gate,
                    "seconds_measured": round(time.perf_counter() - t0, 3),
                }
            )
        rows = loads + direction_rows(args.data, devices, args.seed)
        rows += shadow_rows(args.shadow_frames, devices, args.seed)
    for row in rows:
        if args.json:
            print(json.dumps(row))
        else:
            print("  ".join(f"{k}={v}" for k, v in row.items()))


if __name__ == "__main__":
    main()
