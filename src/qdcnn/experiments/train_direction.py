"""``qdcnn train-direction``: train a registered method on a dataset and save the model."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from qdcnn.batch import Failure
from qdcnn.config import PipelineConfig
from qdcnn.data.labels import check_labels_usable
from qdcnn.direction.methods import (
    TrainingOptions,
    check_fit_settings,
    check_inner_search,
    get_method,
    option_notes,
)
from qdcnn.direction.model import DirectionModel, train_direction_model
from qdcnn.errors import InputError, ParameterError
from qdcnn.runtime.reporting import Reporter

if TYPE_CHECKING:
    from qdcnn.data.frames import FrameSet

__all__ = ["TrainDirectionResult", "TrainDirectionSpec", "train_direction"]


@dataclass(frozen=True)
class TrainDirectionSpec:
    """What ``qdcnn train-direction`` runs: ``data`` is one dataset spec or several,
    trained on together (each labelled with its own steering unit)."""

    data: str | tuple[str, ...]
    out: Path
    method: str = "image-split-uu"
    config: PipelineConfig = field(default_factory=PipelineConfig)
    inner_folds: int = 3
    gap: int = 5
    training: TrainingOptions = field(default_factory=TrainingOptions)
    use_cache: bool = True

    @property
    def specs(self) -> tuple[str, ...]:
        """The dataset specs trained on."""
        return (self.data,) if isinstance(self.data, str) else tuple(self.data)

    def __post_init__(self) -> None:
        if not self.specs:
            raise ParameterError("data", "none", "one dataset spec or more")
        method = get_method(self.method)
        check_fit_settings(self.gap, self.inner_folds, self.training)
        option_notes([method], self.training)  # one method: refused where they do nothing


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
    import numpy as np

    from qdcnn.data.frames import load_frameset

    report = reporter or Reporter()
    method = get_method(spec.method)
    cfg = spec.config
    sets = [
        load_frameset(d, seed=cfg.seed, steering_unit=cfg.labels.steering_unit) for d in spec.specs
    ]
    estimator, grid = method.estimator(spec.config, spec.training)
    if grid:  # a grid to search: before any work
        check_inner_search(sum(len(f) for f in sets), spec.inner_folds, spec.gap)
    if spec.training.from_model is not None:  # its trunk must fit: before any work
        estimator.read_trunk()
    parts = [_inputs(spec, frames, sets, report) for frames in sets]
    shapes = {np.shape(x)[1:] for x, _, _ in parts}
    if len(shapes) > 1:
        raise InputError(", ".join(spec.specs), f"inputs of different sizes {sorted(shapes)}")
    # one recording's frames pass as they are (prepared network inputs stay marked as such)
    inputs = parts[0][0] if len(parts) == 1 else np.concatenate([x for x, _, _ in parts])
    y = np.concatenate([labels for _, labels, _ in parts])
    failures = [f for _, _, fs in parts for f in fs]
    if method.inputs == "lanes":  # as before: frame methods were never checked here
        check_labels_usable(y, source=" + ".join(spec.specs))
    for f in failures:
        report.failure(f)
    with report.progress(1, f"training {method.name} on {len(y)} frames") as trained:
        model = train_direction_model(
            method,
            inputs,
            y,
            spec.config,
            " + ".join(spec.specs),
            inner_folds=spec.inner_folds,
            gap=spec.gap,
            options=spec.training,
        )
        trained()
    path = model.save(spec.out)
    return TrainDirectionResult(model, path, failures)


def _inputs(
    spec: TrainDirectionSpec, frames: FrameSet, train: list[FrameSet], report: Reporter
) -> tuple[Any, Any, list[Failure]]:
    """Readable inputs (lane features or frames), their labels and the failures of ``frames``
    (a percentile label threshold is taken from all of ``train``)."""
    from qdcnn.data.frames import stack_images
    from qdcnn.direction.frame_cache import method_inputs
    from qdcnn.direction.lane_data import load_lane_data

    method = get_method(spec.method)
    if method.inputs == "lanes":
        assert method.grouping is not None
        with report.progress(len(frames), f"lane features ({frames.name})") as advance:
            lanes = load_lane_data(
                frames,
                spec.config,
                (method.grouping,),
                use_cache=spec.use_cache,
                on_frame=advance,
                check_labels=False,
                train=train,
            )
        return lanes.features(method.grouping), lanes.y, lanes.failures
    if len(train) == 1:  # decoded and resized once per recording for a CNN (cached)
        images, readable, unreadable = method_inputs(
            method,
            spec.config,
            spec.training,
            frames,
            use_cache=spec.use_cache,
            on_note=report.note,
        )
    else:  # recordings of other frame sizes must still be refused together, as before
        images, readable, unreadable = stack_images(frames)
    problems = [Failure(p.source, str(p)) for p in frames.problems]
    labels = frames.labels(spec.config.labels, train=train)
    return images[readable], labels[readable], problems + unreadable
