"""Write synthetic scenes in the layouts of the real data sets qdcnn reads.

- :func:`write_udacity`: a Udacity simulator recording (``driving_log.csv`` + ``IMG/``).
- :func:`write_shadow_set`: a shadow-detection set (``images/`` + binary ``masks/``).
- :func:`write_carla`: an image folder with steering labels, like the Kaggle CARLA set.
- :func:`write_video`: an mp4 of the frames.

Every writer takes an iterable and writes one scene at a time, so a drive from
:func:`qdcnn.data.synthetic.iter_drive` is never held in memory; the ``*Writer`` classes
are the same writers as sinks, and :func:`write_layouts` feeds one stream of scenes to
several of them. Label files appear under their names only when complete.
"""

from __future__ import annotations

import math
import os
from abc import ABC, abstractmethod
from collections.abc import Iterable, Sequence, Sized
from datetime import datetime, timedelta
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from qdcnn._closing import FinishesOnExit
from qdcnn._fileio import AtomicTextFile
from qdcnn.data.images import write_image, write_mask
from qdcnn.data.synthetic import RoadScene
from qdcnn.errors import ParameterError

_DEFAULT_START = datetime(2024, 1, 1, 12, 0, 0)


def simulator_number(value: float) -> str:
    """Format a number as the Udacity simulator writes it (C# single, 7 significant digits).

    Examples
    --------
    >>> simulator_number(0.0), simulator_number(1.0), simulator_number(-0.3048072)
    ('0', '1', '-0.3048072')
    >>> simulator_number(8.02615e-05), simulator_number(30.190312)
    ('8.02615E-05', '30.19031')
    """
    if not math.isfinite(value):
        raise ParameterError("value", value, "a finite number")
    if value == 0:
        return "0"
    return format(value, ".7g").upper()


def _udacity_name(kind: str, when: datetime) -> str:
    """Image file name of the simulator, e.g. ``center_2024_01_01_12_00_00_100.jpg``."""
    return f"{kind}_{when:%Y_%m_%d_%H_%M_%S}_{when.microsecond // 1000:03d}.jpg"


def _check_fps(fps: float) -> float:
    if not (isinstance(fps, int | float) and 0.5 <= float(fps) <= 1000.0):
        raise ParameterError("fps", fps, "a frame rate between 0.5 and 1000")
    return float(fps)


class _TextSink:
    """Lines of a text file written as they come, moved into place when complete."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._file = AtomicTextFile(path)

    def write(self, line: str) -> None:
        self._file.write(line + "\n")

    def close(self) -> Path:
        return self._file.commit()

    def abort(self) -> None:
        self._file.abort()


class SceneSink(FinishesOnExit, ABC):
    """Base of the streaming writers: ``add`` scenes one by one, then ``close``.

    Used as a context manager, a sink closes on success and discards its unfinished
    label file on an exception (images already written stay).
    """

    @abstractmethod
    def add(self, scene: RoadScene) -> None:
        """Write one scene."""

    @abstractmethod
    def close(self) -> Path:
        """Finish the files and return the main output's path."""

    def abort(self) -> None:
        """Stop after an error; the default keeps what was written."""
        return None


class UdacityWriter(SceneSink):
    """Streaming form of :func:`write_udacity` (same arguments, same files)."""

    def __init__(
        self,
        out_dir: str | os.PathLike[str],
        *,
        start: datetime | None = None,
        fps: float = 10.0,
    ) -> None:
        self.fps = _check_fps(fps)
        self.root = Path(out_dir).resolve()
        self.img_dir = self.root / "IMG"
        self.img_dir.mkdir(parents=True, exist_ok=True)
        self.t0 = _DEFAULT_START if start is None else start
        self._log = _TextSink(self.root / "driving_log.csv")
        self._count = 0

    def add(self, scene: RoadScene) -> None:
        when = self.t0 + timedelta(milliseconds=round(self._count * 1000.0 / self.fps))
        paths = [self.img_dir / _udacity_name(kind, when) for kind in ("center", "left", "right")]
        write_image(paths[0], scene.image)
        values = (scene.steering, scene.throttle)
        self._log.write(
            ", ".join(
                [
                    *(str(p) for p in paths),
                    *(simulator_number(v) for v in values),
                    "0",
                    simulator_number(scene.speed),
                ]
            )
        )
        self._count += 1

    def close(self) -> Path:
        return self._log.close()

    def abort(self) -> None:
        self._log.abort()


def write_udacity(
    scenes: Iterable[RoadScene],
    out_dir: str | os.PathLike[str],
    *,
    start: datetime | None = None,
    fps: float = 10.0,
) -> Path:
    """Write scenes as a Udacity simulator recording.

    ``out_dir/driving_log.csv`` has no header and the simulator's columns ``center, left,
    right, steering, throttle, brake, speed``, separated by ``", "`` as the simulator does,
    with absolute image paths. Centre frames go to ``out_dir/IMG/center_<timestamp>.jpg``
    (JPEG quality 95), timestamps ``1/fps`` seconds apart from ``start``; the ``left_`` and
    ``right_`` names are listed but not written, as in the recordings qdcnn is developed on.

    Parameters
    ----------
    scenes : iterable of RoadScene
        Frames in recording order; an iterator (:func:`qdcnn.data.synthetic.iter_drive`)
        is written one scene at a time, never all in memory.
    out_dir : path-like
        Folder to create or fill.
    start : datetime, optional
        Time stamp of the first frame (default 2024-01-01 12:00:00).
    fps : float
        Frame rate, between 0.5 and 1000 (names have millisecond resolution).

    Returns
    -------
    Path
        The path of ``driving_log.csv`` (it appears when all rows are written).
    """
    return _drain(scenes, UdacityWriter(out_dir, start=start, fps=fps))


class ShadowSetWriter(SceneSink):
    """Streaming form of :func:`write_shadow_set`."""

    def __init__(self, out_dir: str | os.PathLike[str]) -> None:
        self.root = Path(out_dir)
        (self.root / "images").mkdir(parents=True, exist_ok=True)
        (self.root / "masks").mkdir(parents=True, exist_ok=True)
        self._count = 0

    def add(self, scene: RoadScene) -> None:
        stem = f"scene_{self._count:06d}"
        write_image(self.root / "images" / f"{stem}.png", scene.image)
        write_mask(self.root / "masks" / f"{stem}.png", scene.shadow_mask)
        self._count += 1

    def close(self) -> Path:
        return self.root


def write_shadow_set(scenes: Iterable[RoadScene], out_dir: str | os.PathLike[str]) -> Path:
    """Write ``out_dir/images/scene_NNNNNN.png`` and matching single-channel 0/255
    ``out_dir/masks/scene_NNNNNN.png`` shadow masks, one scene at a time; returns ``out_dir``."""
    return _drain(scenes, ShadowSetWriter(out_dir))


class CarlaWriter(SceneSink):
    """Streaming form of :func:`write_carla`.

    ``count`` (when known) sets the zero-padding of the names, at least 6 digits, so that
    name order is frame order; without it, names have 6 digits and more than 10**6 scenes
    are refused.
    """

    def __init__(
        self,
        out_dir: str | os.PathLike[str],
        *,
        labels: Literal["txt", "csv"] = "txt",
        count: int | None = None,
    ) -> None:
        if labels not in ("txt", "csv"):
            raise ParameterError("labels", labels, "'txt' or 'csv'")
        self.root = Path(out_dir)
        (self.root / "images").mkdir(parents=True, exist_ok=True)
        self.digits = max(6, len(str(max((count or 0) - 1, 0))))
        self.labels = labels
        name = "steer_values.txt" if labels == "txt" else "labels.csv"
        self._out = _TextSink(self.root / name)
        if labels == "csv":
            self._out.write("image,steering")
        self._count = 0

    def add(self, scene: RoadScene) -> None:
        if self._count >= 10**self.digits:
            raise ParameterError(
                "scenes", f"<more than {10**self.digits}>", "a sequence (len) or count=N"
            )
        name = f"{self._count:0{self.digits}d}.png"
        write_image(self.root / "images" / name, scene.image)
        value = repr(float(scene.steering))
        self._out.write(value if self.labels == "txt" else f"{name},{value}")
        self._count += 1

    def close(self) -> Path:
        return self._out.close()

    def abort(self) -> None:
        self._out.abort()


def write_carla(
    scenes: Iterable[RoadScene],
    out_dir: str | os.PathLike[str],
    *,
    labels: Literal["txt", "csv"] = "txt",
) -> Path:
    """Write an image folder with steering labels, like the Kaggle CARLA steering set.

    Images go to ``out_dir/images/000000.png``, ... (zero-padded so name order is frame
    order). Labels go to ``out_dir/steer_values.txt`` (one steering value per line, in
    image-name order) or, with ``labels="csv"``, to ``out_dir/labels.csv`` with the header
    ``image,steering`` and the image file name in the first column. An iterator of scenes
    is written one at a time (names then have 6 digits, see :class:`CarlaWriter`).

    Returns
    -------
    Path
        The label file.
    """
    count = len(scenes) if isinstance(scenes, Sized) else None
    return _drain(scenes, CarlaWriter(out_dir, labels=labels, count=count))


class VideoSceneWriter(SceneSink):
    """Scenes (or RGB frames) streamed into a video by :class:`qdcnn.data.video.VideoWriter`."""

    def __init__(
        self, path: str | os.PathLike[str], *, fps: float = 10.0, encoder: str = "auto"
    ) -> None:
        from qdcnn.data.video import VideoWriter

        self.path = Path(path)
        self._writer = VideoWriter(self.path, _check_fps(fps), encoder=encoder)  # type: ignore[arg-type]

    def add(self, scene: RoadScene | NDArray[np.uint8]) -> None:
        self._writer.write(scene.image if isinstance(scene, RoadScene) else scene)

    def close(self) -> Path:
        self.result = self._writer.close()
        return self.path

    def abort(self) -> None:
        self._writer.abort()


def write_video(
    frames: Iterable[RoadScene | NDArray[np.uint8]],
    path: str | os.PathLike[str],
    fps: float = 10.0,
    *,
    encoder: str = "auto",
) -> Path:
    """Write scenes or RGB uint8 frames as a video, one at a time (never all in memory).

    Parameters
    ----------
    frames : iterable of RoadScene or ndarray
        For example ``iter_drive("track2", 10_000)``.
    path : path-like
        ``.mp4`` (or ``.mov``, ``.mkv``, ``.avi``); it appears when complete.
    fps : float
        Frame rate.
    encoder : {"auto", "libx264", "mpeg4", "opencv"}
        See :class:`qdcnn.data.video.VideoWriter`.

    Returns
    -------
    Path
        ``path``.
    """
    return _drain(frames, VideoSceneWriter(path, fps=fps, encoder=encoder))  # type: ignore[arg-type]


def write_layouts(scenes: Iterable[RoadScene], sinks: Sequence[SceneSink]) -> list[Path]:
    """Stream each scene into every sink in one pass (one rendering for several layouts)."""
    try:
        for scene in scenes:
            for sink in sinks:
                sink.add(scene)
    except BaseException:
        for sink in sinks:
            sink.abort()
        raise
    return [sink.close() for sink in sinks]


def _drain(scenes: Iterable[RoadScene], sink: SceneSink) -> Path:
    return write_layouts(scenes, [sink])[0]
