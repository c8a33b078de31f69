"""``qdcnn train-direction``: train a registered method on a dataset and save the model."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from qdcnn.batch import Failure
from qdcnn.config import PipelineConfig
from qdcnn.direction.methods import (
    TrainingOptions,
    check_fit_settings,
    check_inner_search,
    get_method,
)
from qdcnn.direction.model import DirectionModel, train_direction_model
from qdcnn.runtime.reporting import Reporter

__all__ = ["TrainDirectionResult", "TrainDirectionSpec", "train_direction"]


@dataclass(frozen=True)
class TrainDirectionSpec:
    """What ``qdcnn train-direction`` runs."""

    data: str
    out: Path
    method: str = "image-split-uu"
    config: PipelineConfig = field(default_factory=PipelineConfig)
    inner_folds: int = 3
    gap: int = 5
    training: TrainingOptions = field(default_factory=TrainingOptions)
    use_cache: bool = True

    def __post_init__(self) -> None:
        get_method(self.method)
        check_fit_settings(self.gap, self.inner_folds, self.training)


@dataclass
class TrainDirectionResult:
    """The trained model, where it went, and the frames left out."""

    model: DirectionModel
    path: Path
    failures: list[Failure]

    @property
    def exit_code(self) -> int:
        return 1 if self.failures else 0

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": str(self.path),
            "method": self.model.method,
            "data": self.model.trained_on,
            **self.model.summary,
            "failures": [f.to_dict() for f in self.failures],
        }


def train_direction(
    spec: TrainDirectionSpec, reporter: Reporter | None = None
) -> TrainDirectionResult:
    """Train ``spec.method`` on every readable frame of ``spec.data`` and save it."""
    from qdcnn.data.frames import load_frameset, stack_images
    from qdcnn.direction.lane_data import load_lane_data

    report = reporter or Reporter()
    method = get_method(spec.method)
    frames = load_frameset(
        spec.data, seed=spec.config.seed, steering_unit=spec.config.labels.steering_unit
    )
    if method.estimator(spec.config, spec.training)[1]:  # a grid to search: before any work
        check_inner_search(len(frames), spec.inner_folds, spec.gap)
    if method.inputs == "lanes":
        assert method.grouping is not None
        with report.progress(len(frames), f"lane features ({frames.name})") as advance:
            lanes = load_lane_data(
                frames, spec.config, (method.grouping,), use_cache=spec.use_cache, on_frame=advance
            )
        inputs: Any = lanes.features(method.grouping)
        y, failures = lanes.y, lanes.failures
    else:
        images, readable, unreadable = stack_images(frames)
        inputs, y = images[readable], frames.labels(spec.config.labels)[readable]
        failures = [Failure(p.source, str(p)) for p in frames.problems] + unreadable
    for f in failures:
        report.failure(f)
    with report.progress(1, f"training {method.name} on {len(y)} frames") as trained:
        model = train_direction_model(
            method,
            inputs,
            y,
            spec.config,
            spec.data,
            inner_folds=spec.inner_folds,
            gap=spec.gap,
            options=spec.training,
        )
        trained()
    path = model.save(spec.out)
    return TrainDirectionResult(model, path, failures)
