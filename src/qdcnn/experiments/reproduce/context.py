"""What the sections of one reproduce run share: loaded datasets, settings, figures, progress.

Each dataset is loaded once (frames, then the lane features of each pipeline mode) and
a dataset that fails to load is remembered with its reason, so every section that
needs it reports the same one-line error in its own place and goes on with the others.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn.config import PipelineConfig
from qdcnn.data.frames import FrameSet, load_frameset
from qdcnn.direction.lane_data import LaneData, load_lane_data
from qdcnn.direction.methods import GROUPINGS
from qdcnn.errors import QdcnnError
from qdcnn.experiments.reproduce.model import Section
from qdcnn.experiments.reproduce.spec import DatasetEntry, Profile, ReproduceSpec
from qdcnn.runtime.reporting import Reporter, StageReporter

__all__ = ["DatasetUnavailable", "RunContext", "StageReporter", "named_options_config"]

#: The pipeline modes every accuracy table shows: the paper's, and the named options.
MODES: tuple[str, ...] = ("paper", "named")


def named_options_config(config: PipelineConfig) -> PipelineConfig:
    """The direction study's best named options (not the paper's) on top of ``config``.

    Road-centre features, colour Canny and no shadow removal
    (``qdcnn evaluate --features road-centre --edges rgb --no-shadow-removal``).
    """
    return config.with_lane_options(features="road-centre", edges="rgb", shadow_removal=False)


class DatasetUnavailable(QdcnnError):
    """A dataset (or one of its pipeline modes) that could not be loaded, with the reason."""

    def __init__(self, entry: DatasetEntry, reason: str) -> None:
        self.entry = entry
        self.reason = reason
        super().__init__(f"{entry.title} ({entry.spec}): {reason}")


@dataclass
class RunContext:
    """State shared by the sections of one run.

    Attributes
    ----------
    spec : ReproduceSpec
    reporter : Reporter
    configs : dict of str to PipelineConfig
        ``"paper"`` (the paper's pipeline) and ``"named"`` (the named options).
    sections : dict of str to Section
        Sections finished so far (later ones read earlier ones' ``data``).
    """

    spec: ReproduceSpec
    reporter: Reporter
    configs: dict[str, PipelineConfig]
    sections: dict[str, Section] = field(default_factory=dict)
    _frames: dict[str, FrameSet | DatasetUnavailable] = field(default_factory=dict)
    _lanes: dict[tuple[str, str], LaneData | DatasetUnavailable] = field(default_factory=dict)
    _shadow_set: Any = None
    _total_frames: dict[str, int] = field(default_factory=dict)

    @classmethod
    def create(cls, spec: ReproduceSpec, reporter: Reporter) -> RunContext:
        paper = replace(PipelineConfig(), seed=spec.seed)
        return cls(spec, reporter, {"paper": paper, "named": named_options_config(paper)})

    @property
    def profile(self) -> Profile:
        return self.spec.profile

    @property
    def out(self) -> Path:
        return self.spec.out

    @property
    def datasets(self) -> tuple[DatasetEntry, ...]:
        return self.spec.datasets()

    # ------------------------------------------------------------ datasets

    def frames(self, entry: DatasetEntry) -> FrameSet:
        """The frames of ``entry`` (the profile's first frames of a recording)."""
        if entry.key not in self._frames:
            try:
                frames = load_frameset(entry.spec, seed=self.spec.seed)
                self._total_frames[entry.key] = len(frames)
                self._frames[entry.key] = _first_frames(frames, self.profile.max_frames)
            except QdcnnError as exc:
                self._frames[entry.key] = DatasetUnavailable(entry, f"failed to load: {exc}")
        loaded = self._frames[entry.key]
        if isinstance(loaded, DatasetUnavailable):
            raise loaded
        return loaded

    def lane_data(self, entry: DatasetEntry, mode: str = "paper") -> LaneData:
        """Labels and lane features (all three groupings) of ``entry`` under ``mode``."""
        key = (entry.key, mode)
        if key not in self._lanes:
            frames = self.frames(entry)
            try:
                with self.reporter.progress(
                    len(frames), f"lane features, {entry.key} ({frames.name}), {mode} pipeline"
                ) as advance:
                    self._lanes[key] = load_lane_data(
                        frames,
                        self.configs[mode],
                        GROUPINGS,
                        use_cache=self.spec.use_cache,
                        on_frame=advance,
                    )
            except QdcnnError as exc:
                self._lanes[key] = DatasetUnavailable(entry, f"no usable lane data: {exc}")
        loaded = self._lanes[key]
        if isinstance(loaded, DatasetUnavailable):
            raise loaded
        return loaded

    def dataset_info(self) -> list[dict[str, Any]]:
        """What was loaded of each dataset (report.json)."""
        info = []
        for entry in self.datasets:
            d: dict[str, Any] = entry.to_dict() | {"title": entry.title}
            loaded = self._frames.get(entry.key)
            if isinstance(loaded, DatasetUnavailable):
                d["error"] = loaded.reason
            elif loaded is not None:
                d.update(
                    name=loaded.name,
                    n_frames=len(loaded),
                    n_frames_recorded=self._total_frames.get(entry.key, len(loaded)),
                    skipped_rows=len(loaded.problems),
                )
            info.append(d)
        return info

    def shadow_set(self) -> tuple[str, list[NDArray[np.uint8]], list[NDArray[np.bool_]], int]:
        """Name, images and masks of the shadow set, and how many images failed to load."""
        if self._shadow_set is None:
            self._shadow_set = self._load_shadow_set()
        if isinstance(self._shadow_set, QdcnnError):
            raise self._shadow_set
        name, images, masks, n_failed = self._shadow_set
        return name, images, masks, n_failed

    def _load_shadow_set(self) -> Any:
        from qdcnn.data.shadow_set import load_shadow_set
        from qdcnn.experiments.noise import synthetic_shadow_set

        if self.spec.shadow_set is None:
            images, masks = synthetic_shadow_set(
                self.profile.shadow_scenes, seed=self.spec.seed + 1000
            )
            return "synthetic track2 scenes", images, masks, 0
        try:
            images, masks, failures = load_shadow_set(self.spec.shadow_set)
        except QdcnnError as exc:
            return exc
        for f in failures:
            self.reporter.failure(f)
        return self.spec.shadow_set.resolve().name, images, masks, len(failures)

    # ------------------------------------------------------------ figures

    def save_figure(self, fig: Any, name: str) -> str:
        """Write a matplotlib figure to ``figures/<name>.png``; the path relative to the report."""
        from qdcnn.experiments.noise.plot import save_figure

        rel = f"figures/{name}.png"
        save_figure(fig, self.out / rel, dpi=110)
        return rel


def _first_frames(frames: FrameSet, n: int | None) -> FrameSet:
    """The first ``n`` frames of a recording (all of a synthetic drive, sized by its spec)."""
    if n is None or len(frames) <= n or frames.images is not None:
        return frames
    return FrameSet(
        frames.name,
        frames.spec,
        frames.steering[:n],
        None if frames.timestamps is None else frames.timestamps[:n],
        frames.sources[:n],
        list(frames.problems),
        None,
        None if frames.paths is None else frames.paths[:n],
    )
