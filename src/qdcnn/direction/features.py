"""Lane features of every frame of a dataset, computed once and cached on disk.

The three groupings share one pass of shadow removal, edge detection and Hough
per frame. Unreadable frames are skipped and listed. Results are cached under
``$QDCNN_CACHE`` (default ``~/.cache/qdcnn``) keyed by the data's fingerprint,
the pipeline settings and the package's source code, so a second evaluation or a
noise sweep of the same data starts at once, and a code change never reuses
features the old code computed.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn import __version__
from qdcnn.batch import Failure, run_batch
from qdcnn.config import PipelineConfig
from qdcnn.data.frames import FrameSet
from qdcnn.direction import feature_cache
from qdcnn.pipeline import FrameResult, process_frame
from qdcnn.quantum.sampling import as_generator
from qdcnn.vision.grouping import GROUPINGS, feature_names


@dataclass
class FeatureTable:
    """Per-frame lane features for several grouping methods.

    Attributes
    ----------
    features : dict of str to ndarray, shape (N, 2 + k)
        Slopes (then extra features) per frame; NaN where a line is missing or
        the frame was unreadable.
    status : dict of str to ndarray of str, shape (N,)
        ``ok``, ``one-line``, ``no-lines``, ``crossed``, ``wrong-side`` (two lines that
        cannot border a road, :func:`qdcnn.vision.grouping.pair_status`) or ``unreadable``
        per frame.
    readable : ndarray of bool, shape (N,)
        Frames that could be read.
    failures : list of Failure
        The unreadable frames and why.
    seconds_per_frame : float
        Measured pipeline time per readable frame (reading excluded).
    """

    features: dict[str, NDArray[np.float64]]
    status: dict[str, NDArray[np.str_]]
    readable: NDArray[np.bool_]
    failures: list[Failure] = field(default_factory=list)
    seconds_per_frame: float = float("nan")
    cached: bool = False
    camera: dict[str, Any] | None = None

    def frames_without_lines(self, grouping: str) -> int:
        """Readable frames without two lines that can border a road (status not "ok")."""
        return int(np.sum(self.readable & (self.status[grouping] != "ok")))


def cache_dir() -> Path:
    return Path(os.environ.get("QDCNN_CACHE", Path.home() / ".cache" / "qdcnn"))


@cache
def code_fingerprint(root: Path = Path(__file__).resolve().parents[1]) -> str:
    """Hash of every ``.py`` file of the package under ``root``.

    Part of the cache key, so features computed by another version of the code,
    released or not, are never read back.
    """
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(path.relative_to(root).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:24]


def _cache_key(frames: FrameSet, config: PipelineConfig, groupings: Sequence[str]) -> str:
    payload = json.dumps(
        {
            "data": frames.fingerprint(),
            "config": config.to_dict(),
            "groupings": list(groupings),
            "version": __version__,
            "code": code_fingerprint(),
        },
        sort_keys=True,
        default=str,
    )
    return hashlib.sha256(payload.encode()).hexdigest()[:32]


def compute_features(
    frames: FrameSet,
    config: PipelineConfig | None = None,
    groupings: Sequence[str] = GROUPINGS,
    *,
    use_cache: bool = True,
    on_frame: Callable[[int], None] | None = None,
) -> FeatureTable:
    """Lane features of every frame for each grouping method.

    Parameters
    ----------
    frames : FrameSet
        The dataset.
    config : PipelineConfig, optional
        Pipeline settings.
    groupings : sequence of str
        Grouping methods.
    use_cache : bool
        Read and write the on-disk cache.
    on_frame : callable, optional
        Called with the index of every finished frame (progress bars).
    """
    cfg = config or PipelineConfig()
    key = _cache_key(frames, cfg, groupings)
    path = feature_cache.entry_path(cache_dir(), key)
    n = len(frames)
    width = len(feature_names(cfg.grouping.extra_features))
    cached = _load(path, groupings, n, width) if use_cache else None
    run_cfg, camera = _camera_config(frames, cfg)
    if cached is not None:
        cached.camera = _camera_summary(camera)
        return cached
    feats = {g: np.full((n, width), np.nan) for g in groupings}
    status = {g: np.full(n, "unreadable", dtype="<U10") for g in groupings}
    readable = np.zeros(n, bool)
    failures: list[Failure] = []
    elapsed = 0.0
    for i, result, seconds in _frame_results(frames, run_cfg, groupings, camera, failures):
        readable[i] = True
        elapsed += seconds
        for g, lane in result.lanes.items():
            feats[g][i] = lane.features
            status[g][i] = lane.status
        if on_frame:
            on_frame(i)
    table = FeatureTable(feats, status, readable, failures, elapsed / max(int(readable.sum()), 1))
    table.camera = _camera_summary(camera)
    if use_cache:
        _save(path, table, groupings)
    return table


def _camera_summary(camera: Any) -> dict[str, Any] | None:
    """What ``--lanes auto`` chose: the geometry, its one-line description and notes."""
    if camera is None:
        return None
    return {**camera.to_dict(), "description": camera.describe()}


def _camera_config(frames: FrameSet, config: PipelineConfig) -> tuple[PipelineConfig, Any]:
    """``config`` with the ROI estimated from ``frames`` when ``lanes.camera == "auto"``."""
    if config.lanes.camera != "auto":
        return config, None
    from qdcnn.pipeline import auto_lanes, recording_sample

    sample = []
    for outcome in run_batch(recording_sample(len(frames)), frames.image):
        if outcome.result is not None:
            sample.append(outcome.result)
    if not sample:
        return config, None
    return auto_lanes(sample, config)


def _frame_results(
    frames: FrameSet,
    config: PipelineConfig,
    groupings: Sequence[str],
    camera: Any,
    failures: list[Failure],
) -> Iterator[tuple[int, FrameResult, float]]:
    """``(index, result, seconds)`` of every readable frame, in order; failures collected.

    Without tracking or an estimated camera each frame is independent
    (:func:`qdcnn.pipeline.process_frame`); otherwise the frames go through
    :func:`qdcnn.pipeline.process_recording`, which tracks lines across frames and
    falls back to the preset for frames of another size.
    """
    from qdcnn.pipeline import process_recording

    rng = as_generator(config.seed)
    order: list[int] = []
    reading = [0.0]  # seconds spent reading the frame last yielded (excluded from the times)

    def images() -> Iterator[NDArray[np.uint8]]:
        t0 = time.perf_counter()
        for outcome in run_batch(
            range(len(frames)), frames.image, name=lambda i: frames.sources[i]
        ):
            if outcome.result is not None:
                order.append(outcome.item)
                reading[0] = time.perf_counter() - t0
                yield outcome.result
            elif outcome.failure is not None:
                failures.append(outcome.failure)
            t0 = time.perf_counter()

    if config.grouping.track == "none" and camera is None:
        results: Iterator[FrameResult] = (
            process_frame(image, config, groupings, rng=rng) for image in images()
        )
    else:
        results = process_recording(images(), config, groupings, camera=camera, rng=rng)
    while True:
        t0 = time.perf_counter()
        try:
            result = next(results)
        except StopIteration:
            return
        yield order[-1], result, time.perf_counter() - t0 - reading[0]


def _save(path: Path, table: FeatureTable, groupings: Sequence[str]) -> None:
    entry = feature_cache.CachedFeatures(
        table.features, table.status, table.readable, table.failures, table.seconds_per_frame
    )
    feature_cache.write_entry(path, entry, groupings)


def _load(path: Path, groupings: Sequence[str], n: int, width: int) -> FeatureTable | None:
    """The cached table, or ``None`` for a miss (a bad entry is reported and removed)."""
    entry = feature_cache.read_entry(path, groupings, n, width)
    if entry is None:
        return None
    return FeatureTable(
        entry.features,
        entry.status,
        entry.readable,
        entry.failures,
        entry.seconds_per_frame,
        cached=True,
    )
