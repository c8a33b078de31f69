"""A fast, deterministic frame processor and test clips for the video runner's tests.

Imported by the tests and by the subprocesses they kill (``sys.path`` gets this folder).
"""

from __future__ import annotations

import os
import signal
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn.errors import InputError
from qdcnn.runtime.chunks import FrameOutcome

CLASSES = ("left", "straight", "right")


class HalvesProcessor:
    """Direction from the brightness of the two image halves (brighter side wins).

    ``fail_at``: frame indices that raise an InputError. ``kill_at`` with ``marker``: the
    process running frame ``kill_at`` kills itself with SIGKILL the first time (the marker
    file records that it happened).
    """

    classes: tuple[str, ...] | None = CLASSES

    def __init__(
        self,
        *,
        fail_at: tuple[int, ...] = (),
        kill_at: int | None = None,
        marker: str | None = None,
        version: int = 1,
    ) -> None:
        self.fail_at, self.kill_at, self.marker, self.version = fail_at, kill_at, marker, version

    def settings(self) -> dict[str, Any]:
        return {"processor": "halves", "version": self.version, "fail_at": list(self.fail_at)}

    def process(self, image: NDArray[np.uint8], index: int) -> FrameOutcome:
        if index in self.fail_at:
            raise InputError(f"frame {index}", "cannot be processed")
        if index == self.kill_at and self.marker and not os.path.exists(self.marker):
            Path(self.marker).write_text(f"killed at frame {index} by pid {os.getpid()}\n")
            os.kill(os.getpid(), signal.SIGKILL)
        w = image.shape[1]
        d = (float(image[:, w // 2 :].mean()) - float(image[:, : w // 2].mean())) / 255.0
        z = np.array([-8 * d - 0.05, 0.0, 8 * d - 0.05])
        p = np.exp(z - z.max())
        p /= p.sum()
        label = int(np.argmax(p))
        dark = float(np.count_nonzero(image.mean(axis=2) < 60)) / (image.shape[0] * w)
        status = "ok" if abs(d) > 0.02 else "no-lines"
        return FrameOutcome(CLASSES[label], tuple(float(v) for v in p), dark, status, d)

    def draw(
        self, image: NDArray[np.uint8], outcome: FrameOutcome, decision: str | None
    ) -> NDArray[np.uint8]:
        out = image.copy()
        cv2.putText(out, decision or "-", (2, 12), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (255, 255, 0))
        return out


class BatchHalvesProcessor(HalvesProcessor):
    """The same decisions through ``process_batch`` (errors returned, not raised)."""

    def __init__(self, **kw: Any) -> None:
        super().__init__(**kw)
        self.batches: list[int] = []

    def process_batch(
        self, images: list[NDArray[np.uint8]], indices: list[int]
    ) -> list[FrameOutcome | InputError]:
        self.batches.append(len(images))
        out: list[FrameOutcome | InputError] = []
        for image, index in zip(images, indices, strict=True):
            try:
                out.append(self.process(image, index))
            except InputError as exc:
                out.append(exc)
        return out


def clip_frame(i: int, w: int = 64, h: int = 48) -> NDArray[np.uint8]:
    """Frame ``i`` of the test clip: the brighter half changes often, so votes matter."""
    rng = np.random.default_rng([7, i])
    left, right = rng.integers(20, 236, 2)
    img = np.empty((h, w, 3), np.uint8)
    img[:, : w // 2] = left
    img[:, w // 2 :] = right
    img[h // 3 : h // 2, 4 : w - 4] = 10  # a dark band ("shadow")
    return img


def write_clip(path: Path, n: int = 50, w: int = 64, h: int = 48, **kw: Any) -> Path:
    from qdcnn.data.video import VideoWriter

    with VideoWriter(path, 10.0, keyframe_interval=6, **kw) as writer:
        for i in range(n):
            writer.write(clip_frame(i, w, h))
    return path


class ListSource:
    """A frame source held in memory (``__len__``, ``image(i)``, ``timestamps``)."""

    def __init__(self, n: int, name: str = "memory") -> None:
        self.name = name
        self.spec = f"memory:{n}"
        self.frames = [clip_frame(i) for i in range(n)]
        self.timestamps = np.arange(n) * 0.05

    def __len__(self) -> int:
        return len(self.frames)

    def image(self, i: int) -> NDArray[np.uint8]:
        return self.frames[i]

    def fingerprint(self) -> str:
        return f"list-{len(self.frames)}"
