"""Trained direction models: a fitted classifier plus the pipeline settings that made its features.

Saved with :mod:`pickle` (scikit-learn's own persistence format for estimators)
inside a small header that names the method and qdcnn version, so a wrong file
gets a clear error instead of an unpickling traceback.
"""

from __future__ import annotations

import os
import pickle
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from qdcnn import __version__
from qdcnn.config import GroupingConfig, LaneConfig, PipelineConfig
from qdcnn.data.labels import DIRECTIONS
from qdcnn.errors import InputError, ParameterError
from qdcnn.experiments.evaluate import QUANTUM_METHODS, make_classifier

KIND = "qdcnn-direction-model"


@dataclass
class DirectionModel:
    """A fitted quantum direction classifier and the pipeline settings of its features."""

    method: str
    config: PipelineConfig
    estimator: Any
    trained_on: str

    @property
    def grouping(self) -> str:
        return QUANTUM_METHODS[self.method][0]

    def predict(self, features: NDArray[np.float64]) -> NDArray[np.int64]:
        return np.asarray(self.estimator.predict(np.atleast_2d(features)), dtype=np.int64)

    def save(self, path: str | os.PathLike[str]) -> Path:
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        payload = {
            "kind": KIND,
            "version": __version__,
            "method": self.method,
            "config": self.config,
            "estimator": self.estimator,
            "trained_on": self.trained_on,
        }
        p.write_bytes(pickle.dumps(payload))
        return p

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> DirectionModel:
        p = Path(path)
        if not p.is_file():
            raise InputError(p, "model file not found")
        try:
            payload = pickle.loads(p.read_bytes())
        except Exception as exc:  # unpickling can raise almost anything on a wrong file
            raise InputError(p, f"not a qdcnn direction model ({type(exc).__name__})") from None
        if not isinstance(payload, dict) or payload.get("kind") != KIND:
            raise InputError(p, f"not a qdcnn direction model (missing kind '{KIND}')")
        return cls(
            payload["method"], payload["config"], payload["estimator"], payload["trained_on"]
        )


def default_config() -> PipelineConfig:
    """Settings for 320x160 frames: the paper's, with one smoothing pass (see LaneConfig)."""
    return replace(PipelineConfig(), lanes=LaneConfig.udacity())


def with_lane_options(
    config: PipelineConfig,
    *,
    features: str = "slopes",
    edges: str = "grey",
    shadow_removal: bool = True,
) -> PipelineConfig:
    """``config`` with a feature mode, Canny's input and shadow removal set.

    The options of ``qdcnn evaluate`` and ``train-direction`` (``--features``, ``--edges``,
    ``--[no-]shadow-removal``); the defaults are the paper's.
    """
    if edges not in ("grey", "rgb"):
        raise ParameterError("edges", edges, "'grey' (the paper) or 'rgb' (colour Canny)")
    channels: Literal["grey", "rgb"] = "rgb" if edges == "rgb" else "grey"
    lanes = replace(config.lanes, edge_channels=channels, remove_shadows=shadow_removal)
    return replace(config, lanes=lanes, grouping=GroupingConfig.for_features(features))


def train_direction_model(
    method: str,
    features: NDArray[np.float64],
    labels: NDArray[np.int64],
    config: PipelineConfig,
    trained_on: str,
) -> DirectionModel:
    """Fit the classifier of ``method`` on lane features (its fixed, default hyperparameters)."""
    _, kind = QUANTUM_METHODS[method]
    estimator, _ = make_classifier(kind, config, seed=config.seed)
    estimator.fit(features, labels)
    return DirectionModel(method, config, estimator, trained_on)


def direction_name(index: int) -> str:
    return DIRECTIONS[int(index)]
