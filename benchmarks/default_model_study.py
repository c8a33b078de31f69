"""Which lane method generalises best: the choice of the built-in default model.

Every lane method of the registry (the paper's pipeline) is scored two ways:

* **across presets**: trained on two synthetic presets of track1 / track2 / rain and
  tested on the third (three rounds);
* **on recordings**: trained on all three presets (the training data of the built-in
  default, ``qdcnn.direction.builtin.DEFAULT_TRAINING_DATA``) and tested,
  unchanged, on every recording in ``../shared/data`` that is present.

Each score is accuracy minus the test set's majority-class share (a constant guess
scores 0). The default is the method with the highest mean of the two means. Nothing is
tuned: the methods, their settings and the pipeline are the registry's.

    python benchmarks/default_model_study.py [--frames 300] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from qdcnn.config import PipelineConfig
from qdcnn.direction.lane_data import load_lane_data
from qdcnn.direction.methods import get_method, method_names
from qdcnn.direction.model import train_direction_model

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"
RECORDINGS = ["udacity-lake-track", "udacity-mountain-track", "udacity-dark-mountain-track"]
PRESETS = ("track1", "track2", "rain")


def features(spec: str, config: PipelineConfig, grouping: str) -> tuple[Any, Any]:
    lanes = load_lane_data(spec, config, (grouping,))
    return lanes.features(grouping), lanes.y


def over_majority(model: Any, x: Any, y: Any) -> dict[str, float]:
    acc = float(np.mean(model.predict(x) == y))
    majority = float(np.max(np.bincount(y, minlength=3)) / len(y))
    return {"accuracy": acc, "majority": majority, "over_majority": acc - majority}


def score_method(name: str, frames: int, recordings: list[str]) -> dict[str, Any]:
    config = PipelineConfig()
    grouping = get_method(name).grouping
    assert grouping is not None
    data = {p: features(f"synthetic:{p}:{frames}", config, grouping) for p in PRESETS}
    row: dict[str, Any] = {"method": name, "presets": {}, "recordings": {}}
    for held in PRESETS:
        train = [p for p in PRESETS if p != held]
        x = np.concatenate([data[p][0] for p in train])
        y = np.concatenate([data[p][1] for p in train])
        model = train_direction_model(name, x, y, config, "+".join(train))
        row["presets"][held] = over_majority(model, *data[held])
    x = np.concatenate([data[p][0] for p in PRESETS])
    y = np.concatenate([data[p][1] for p in PRESETS])
    model = train_direction_model(name, x, y, config, "+".join(PRESETS))
    for rec in recordings:
        row["recordings"][rec] = over_majority(
            model, *features(f"udacity:{SHARED / rec}", config, grouping)
        )
    means = [
        np.mean([v["over_majority"] for v in row[k].values()])
        for k in ("presets", "recordings")
        if row[k]
    ]
    row["score"] = float(np.mean(means))
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    recordings = [r for r in RECORDINGS if (SHARED / r / "driving_log.csv").is_file()]
    rows = []
    for name in method_names(inputs="lanes"):
        row = score_method(name, args.frames, recordings)
        rows.append(row)
        cells = "  ".join(
            f"{v['accuracy']:.3f}" for v in [*row["presets"].values(), *row["recordings"].values()]
        )
        print(f"{name:16s} {cells}  score {row['score']:+.3f}", flush=True)
    best = max(rows, key=lambda r: r["score"])
    print(f"best: {best['method']} (score {best['score']:+.3f})")
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "best": best["method"]}, indent=1))


if __name__ == "__main__":
    main()
