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
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from qdcnn import __version__
from qdcnn.batch import Failure, run_batch
from qdcnn.config import PipelineConfig
from qdcnn.data.frames import FrameSet
from qdcnn.pipeline import GROUPINGS, FrameResult, process_frame
from qdcnn.quantum.sampling import as_generator
from qdcnn.vision.grouping import feature_names


@dataclass
class FeatureTable:
    """Per-frame lane features for several grouping methods.

    Attributes
    ----------
    features : dict of str to ndarray, shape (N, 2 + k)
        Slopes (then extra features) per frame; NaN where a line is missing or
        the frame was unreadable.
    status : dict of str to ndarray of str, shape (N,)
        ``ok``, ``one-line``, ``no-lines`` or ``unreadable`` per frame.
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

    def frames_without_lines(self, grouping: str) -> int:
        """Readable frames where fewer than two lines were found."""
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
    path = cache_dir() / f"features-{key}.npz"
    if use_cache and path.is_file():
        return _load(path, groupings)
    n = len(frames)
    width = len(feature_names(cfg.grouping.extra_features))
    feats = {g: np.full((n, width), np.nan) for g in groupings}
    status = {g: np.full(n, "unreadable", dtype="<U10") for g in groupings}
    readable = np.zeros(n, bool)
    rng = as_generator(cfg.seed)
    elapsed = 0.0

    def work(i: int) -> FrameResult:
        nonlocal elapsed
        image = frames.image(i)
        t0 = time.perf_counter()
        result = process_frame(image, cfg, groupings, rng=rng)
        elapsed += time.perf_counter() - t0
        return result

    failures: list[Failure] = []
    for outcome in run_batch(range(n), work, name=lambda i: frames.sources[i]):
        i = outcome.item
        if outcome.result is not None:
            readable[i] = True
            for g, lane in outcome.result.lanes.items():
                feats[g][i] = lane.features
                status[g][i] = lane.status
        elif outcome.failure is not None:
            failures.append(outcome.failure)
        if on_frame:
            on_frame(i)
    table = FeatureTable(feats, status, readable, failures, elapsed / max(int(readable.sum()), 1))
    if use_cache:
        _save(path, table, groupings)
    return table


def _save(path: Path, table: FeatureTable, groupings: Sequence[str]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    arrays: dict[str, NDArray[np.generic]] = {
        "readable": table.readable,
        "seconds": np.array(table.seconds_per_frame),
    }
    for g in groupings:
        arrays[f"features/{g}"] = table.features[g]
        arrays[f"status/{g}"] = table.status[g]
    arrays["failures"] = np.array([json.dumps(f.to_dict()) for f in table.failures], dtype=str)
    tmp = path.with_suffix(".tmp.npz")
    np.savez_compressed(tmp, **arrays)  # type: ignore[arg-type]
    tmp.replace(path)


def _load(path: Path, groupings: Sequence[str]) -> FeatureTable:
    with np.load(path) as data:
        failures = [Failure(**json.loads(s)) for s in data["failures"]]
        return FeatureTable(
            {g: data[f"features/{g}"] for g in groupings},
            {g: data[f"status/{g}"] for g in groupings},
            data["readable"],
            failures,
            float(data["seconds"]),
            cached=True,
        )
