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
from qdcnn.data.labels import DirectionLabels, SteeringUnit, label_directions
from qdcnn.errors import InputError, ParameterError

_DEFAULT_SYNTHETIC_FRAMES = 600
#: Most bytes of frames a synthetic dataset spec renders into memory (10,000 320x160 frames).
_MAX_SYNTHETIC_BYTES = 10_000 * 320 * 160 * 3


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
    unit: SteeringUnit = field(default_factory=SteeringUnit)

    def __len__(self) -> int:
        return len(self.sources)

    def image(self, i: int) -> NDArray[np.uint8]:
        """Frame ``i`` as RGB uint8 (raises :class:`InputError` for an unreadable file)."""
        if self.images is not None:
            return self.images[i]
        assert self.paths is not None
        return read_image(self.paths[i])

    def labels(self, config: LabelConfig | None = None) -> NDArray[np.int64]:
        """Direction labels from steering smoothed as ``config`` says (see :meth:`label_info`)."""
        return self.label_info(config).labels

    def label_info(self, config: LabelConfig | None = None) -> DirectionLabels:
        """Labels with the unit and threshold that produced them.

        The steering unit is the one decided when the recording was loaded; the threshold
        is ``config.threshold`` in that unit, or the unit's default when it is ``None``.
        """
        cfg = config or LabelConfig()
        return label_directions(
            self.steering,
            self.timestamps,
            unit=self.unit,
            threshold=cfg.threshold,
            window=cfg.window,
            max_gap_s=cfg.max_gap_s,
        )

    def fingerprint(self) -> str:
        """Identity of the data for caches: spec, frame names, sizes and modification times."""
        h = hashlib.sha256(os.fsencode(self.spec))
        h.update(self.steering.tobytes())
        for src in self.sources:
            h.update(os.fsencode(src))
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


def load_frameset(spec: str, *, seed: int = 0, steering_unit: str = "auto") -> FrameSet:
    """Load a dataset from its specification.

    ``synthetic:PRESET[:N]`` renders a recording-like drive of ``N`` frames at the
    preset's natural size (320x160; 640x480 for ``dashcam``; default 600 frames, at most
    :data:`_MAX_SYNTHETIC_BYTES` of them, held in memory) with
    :func:`qdcnn.data.synthetic.generate_drive`; its steering is in [-1, 1]. Recordings
    are read lazily; ``steering_unit`` says the unit of their steering (``"auto"``:
    decided from the recording, :func:`qdcnn.data.labels.infer_steering_unit`).
    """
    kind, value = parse_spec(spec)
    if kind == "synthetic":
        from qdcnn.data.synthetic import PRESETS, generate_drive
        from qdcnn.data.synthetic_world import STYLES

        preset, _, count = value.partition(":")
        if preset not in PRESETS:
            raise ParameterError("data", spec, f"a synthetic preset in {', '.join(PRESETS)}")
        try:
            n = int(count) if count else _DEFAULT_SYNTHETIC_FRAMES
        except ValueError:
            raise ParameterError("data", spec, "synthetic:PRESET[:N] with an integer N") from None
        width, height = STYLES[preset].size  # the preset's natural frame size
        most = _MAX_SYNTHETIC_BYTES // (width * height * 3)
        if not 10 <= n <= most:
            raise ParameterError(
                "data",
                spec,
                f"between 10 and {most} synthetic {preset} frames (they are held in memory; "
                "for longer drives write them with 'qdcnn synth --n N --out DIR' and use "
                "udacity:DIR/udacity)",
            )
        scenes = generate_drive(preset, n, seed=seed, width=width, height=height)
        times = np.arange(n) / 10.0
        return FrameSet(
            f"synthetic-{preset}",
            spec,
            np.array([s.steering for s in scenes]),
            times,
            [f"synthetic:{preset}:seed{seed}:frame{i}" for i in range(n)],
            images=[s.image for s in scenes],
            unit=SteeringUnit("norm", "norm", "the synthetic generator steers in [-1, 1]"),
        )
    from qdcnn.data.carla import load_carla
    from qdcnn.data.udacity import load_udacity

    loader = load_udacity if kind == "udacity" else load_carla
    rec = loader(value, steering_unit=steering_unit)
    return FrameSet(
        Path(value).resolve().name,
        spec,
        np.asarray(rec.steering, dtype=np.float64),
        rec.timestamps,
        [str(p) for p in rec.frames],
        list(rec.problems),
        paths=list(rec.frames),
        unit=rec.unit,
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
