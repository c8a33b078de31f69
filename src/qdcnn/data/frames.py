"""Datasets named on the command line: ``udacity:PATH``, ``carla:PATH``, ``synthetic:PRESET[:N]``.

A :class:`FrameSet` gives frames one at a time (read lazily from disk, or held
in memory for synthetic drives), the steering per frame and its timestamps, so
labels, features and CNN inputs all come from the same object.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from qdcnn.batch import Failure, run_batch
from qdcnn.config import LabelConfig
from qdcnn.data.images import read_image
from qdcnn.data.labels import direction_labels
from qdcnn.errors import InputError, ParameterError

DEFAULT_SYNTHETIC_FRAMES = 600


@dataclass
class FrameSet:
    """Frames with steering, from a recording or the synthetic generator.

    Attributes
    ----------
    name : str
        Short name for reports (folder name or ``synthetic-<preset>``).
    spec : str
        The specification it was loaded from.
    steering : ndarray of float64, shape (N,)
        Steering per frame (negative = left).
    timestamps : ndarray of float64 or None
        Seconds per frame.
    sources : list of str
        File path (or synthetic id) of each frame.
    problems : list of InputError
        Rows skipped while loading.
    """

    name: str
    spec: str
    steering: NDArray[np.float64]
    timestamps: NDArray[np.float64] | None
    sources: list[str]
    problems: list[InputError] = field(default_factory=list)
    images: list[NDArray[np.uint8]] | None = None
    paths: list[Path] | None = None

    def __len__(self) -> int:
        return len(self.sources)

    def image(self, i: int) -> NDArray[np.uint8]:
        """Frame ``i`` as RGB uint8 (raises :class:`InputError` for an unreadable file)."""
        if self.images is not None:
            return self.images[i]
        assert self.paths is not None
        return read_image(self.paths[i])

    def labels(self, config: LabelConfig | None = None) -> NDArray[np.int64]:
        """Direction labels from steering smoothed as ``config`` says."""
        cfg = config or LabelConfig()
        return direction_labels(
            self.steering,
            self.timestamps,
            window=cfg.window,
            max_gap_s=cfg.max_gap_s,
            threshold=cfg.threshold,
        )

    def fingerprint(self) -> str:
        """Identity of the data for caches: spec, frame names, sizes and modification times."""
        h = hashlib.sha256(self.spec.encode())
        h.update(self.steering.tobytes())
        for src in self.sources:
            h.update(src.encode())
            if self.paths is not None:
                try:
                    st = os.stat(src)
                    h.update(f"{st.st_size}:{st.st_mtime_ns}".encode())
                except OSError:
                    h.update(b"missing")
        return h.hexdigest()[:24]


def parse_spec(spec: str) -> tuple[str, str]:
    """Split ``KIND:VALUE`` and check the kind."""
    kind, sep, value = spec.partition(":")
    if not sep or not value or kind not in ("udacity", "carla", "synthetic"):
        raise ParameterError("data", spec, "udacity:PATH, carla:PATH or synthetic:PRESET[:N]")
    return kind, value


def load_frameset(spec: str, *, seed: int = 0) -> FrameSet:
    """Load a dataset from its specification.

    ``synthetic:PRESET[:N]`` renders a recording-like drive of ``N`` frames
    (default 600) with :func:`qdcnn.data.synthetic.generate_drive`.
    """
    kind, value = parse_spec(spec)
    if kind == "synthetic":
        from qdcnn.data.synthetic import PRESETS, generate_drive

        preset, _, count = value.partition(":")
        if preset not in PRESETS:
            raise ParameterError("data", spec, f"a synthetic preset in {', '.join(PRESETS)}")
        try:
            n = int(count) if count else DEFAULT_SYNTHETIC_FRAMES
        except ValueError:
            raise ParameterError("data", spec, "synthetic:PRESET[:N] with an integer N") from None
        if not 10 <= n <= 100_000:
            raise ParameterError("data", spec, "between 10 and 100000 synthetic frames")
        scenes = generate_drive(preset, n, seed=seed)
        times = np.arange(n) / 10.0
        return FrameSet(
            f"synthetic-{preset}",
            spec,
            np.array([s.steering for s in scenes]),
            times,
            [f"synthetic:{preset}:seed{seed}:frame{i}" for i in range(n)],
            images=[s.image for s in scenes],
        )
    from qdcnn.data.carla import load_carla
    from qdcnn.data.udacity import load_udacity

    rec = load_udacity(value) if kind == "udacity" else load_carla(value)
    return FrameSet(
        Path(value).resolve().name,
        spec,
        np.asarray(rec.steering, dtype=np.float64),
        rec.timestamps,
        [str(p) for p in rec.frames],
        list(rec.problems),
        paths=list(rec.frames),
    )


def stack_images(frames: FrameSet) -> tuple[NDArray[np.uint8], NDArray[np.bool_], list[Failure]]:
    """All frames as one ``(N, H, W, 3)`` array; unreadable frames are zero and listed."""
    first: NDArray[np.uint8] | None = None
    images: list[NDArray[np.uint8] | None] = []
    failures: list[Failure] = []
    for outcome in run_batch(range(len(frames)), frames.image, name=lambda i: frames.sources[i]):
        if outcome.result is not None and (first is None or outcome.result.shape == first.shape):
            first = outcome.result if first is None else first
            images.append(outcome.result)
        else:
            images.append(None)
            if outcome.failure is not None:
                failures.append(outcome.failure)
            else:
                shape = None if outcome.result is None else outcome.result.shape
                failures.append(
                    Failure(
                        frames.sources[outcome.item],
                        f"{frames.sources[outcome.item]}: frame size {shape} differs from "
                        f"the first frame's {None if first is None else first.shape}",
                    )
                )
    if first is None:
        return np.zeros((0, 1, 1, 3), np.uint8), np.zeros(len(frames), bool), failures
    readable = np.array([im is not None for im in images])
    stack = np.zeros((len(frames), *first.shape), np.uint8)
    for i, im in enumerate(images):
        if im is not None:
            stack[i] = im
    return stack, readable, failures
