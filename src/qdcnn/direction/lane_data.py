"""One recipe from a dataset to what a direction method trains on.

Load the frames (:func:`qdcnn.data.frames.load_frameset`), label them from smoothed
steering, compute (or read back from the cache) the lane features of every frame,
keep the readable frames, and refuse labels that cannot support an accuracy. Every
command and benchmark that evaluates or trains a direction method starts here.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from qdcnn.batch import Failure
from qdcnn.config import PipelineConfig
from qdcnn.data.frames import FrameSet, load_frameset
from qdcnn.data.labels import check_labels_usable
from qdcnn.direction.features import FeatureTable, compute_features

__all__ = ["LaneData", "load_lane_data"]


@dataclass
class LaneData:
    """A dataset's frames, labels and lane features, restricted to readable frames.

    Attributes
    ----------
    frames : FrameSet
        All frames of the dataset.
    table : FeatureTable
        Lane features of every frame, per grouping.
    labels : ndarray of int64, shape (N,)
        Direction label of every frame (readable or not).
    config : PipelineConfig
        The settings that made the features and labels.
    """

    frames: FrameSet
    table: FeatureTable
    labels: NDArray[np.int64]
    config: PipelineConfig

    @property
    def keep(self) -> NDArray[np.bool_]:
        """Frames that could be read."""
        return self.table.readable

    @property
    def y(self) -> NDArray[np.int64]:
        """Labels of the readable frames."""
        return self.labels[self.keep]

    def features(self, grouping: str) -> NDArray[np.float64]:
        """Lane features ``(n_readable, F)`` of one grouping."""
        return self.table.features[grouping][self.keep]

    def camera_notes(self) -> list[str]:
        """What ``--lanes auto`` estimated (ROI, horizon) and its notes, one line each;
        none for the other lane presets."""
        camera = self.table.camera
        if camera is None:
            return []
        return [f"{self.frames.name}: {line}" for line in (camera["description"], *camera["notes"])]

    @property
    def failures(self) -> list[Failure]:
        """Skipped rows of the recording, then unreadable frames, each with its reason."""
        skipped = [Failure(p.source, str(p)) for p in self.frames.problems]
        return skipped + list(self.table.failures)


def load_lane_data(
    data: str | FrameSet,
    config: PipelineConfig | None = None,
    groupings: Sequence[str] = ("image-split",),
    *,
    seed: int = 0,
    use_cache: bool = True,
    on_frame: Callable[[int], None] | None = None,
) -> LaneData:
    """Frames, labels and lane features of ``data`` (a dataset spec or a loaded FrameSet).

    Raises
    ------
    InputError
        The dataset cannot be loaded, or its readable frames' labels hold fewer than two
        classes (a constant guess would score 1.0).
    """
    cfg = config or PipelineConfig()
    frames = (
        data
        if isinstance(data, FrameSet)
        else load_frameset(data, seed=seed, steering_unit=cfg.labels.steering_unit)
    )
    labels = frames.labels(cfg.labels)
    table = compute_features(
        frames, cfg, tuple(sorted(set(groupings))), use_cache=use_cache, on_frame=on_frame
    )
    check_labels_usable(labels[table.readable], source=frames.spec)
    return LaneData(frames, table, labels, cfg)
