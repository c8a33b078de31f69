"""Write synthetic scenes in the layouts of the real data sets qdcnn reads.

- :func:`write_udacity`: a Udacity simulator recording (``driving_log.csv`` + ``IMG/``).
- :func:`write_shadow_set`: a shadow-detection set (``images/`` + binary ``masks/``).
- :func:`write_carla`: an image folder with steering labels, like the Kaggle CARLA set.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from datetime import datetime, timedelta
from pathlib import Path
from typing import Literal

from qdcnn.data.images import write_image, write_mask
from qdcnn.data.synthetic import RoadScene
from qdcnn.errors import ParameterError

DEFAULT_START = datetime(2024, 1, 1, 12, 0, 0)


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


def udacity_name(kind: str, when: datetime) -> str:
    """Image file name of the simulator, e.g. ``center_2024_01_01_12_00_00_100.jpg``."""
    return f"{kind}_{when:%Y_%m_%d_%H_%M_%S}_{when.microsecond // 1000:03d}.jpg"


def write_udacity(
    scenes: Sequence[RoadScene],
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
    scenes : sequence of RoadScene
        Frames in recording order.
    out_dir : path-like
        Folder to create or fill.
    start : datetime, optional
        Time stamp of the first frame (default 2024-01-01 12:00:00).
    fps : float
        Frame rate, between 0.5 and 1000 (names have millisecond resolution).

    Returns
    -------
    Path
        The path of ``driving_log.csv``.
    """
    if not (isinstance(fps, int | float) and 0.5 <= float(fps) <= 1000.0):
        raise ParameterError("fps", fps, "a frame rate between 0.5 and 1000")
    root = Path(out_dir).resolve()
    img_dir = root / "IMG"
    img_dir.mkdir(parents=True, exist_ok=True)
    t0 = DEFAULT_START if start is None else start
    rows = []
    for i, scene in enumerate(scenes):
        when = t0 + timedelta(milliseconds=round(i * 1000.0 / float(fps)))
        paths = [img_dir / udacity_name(kind, when) for kind in ("center", "left", "right")]
        write_image(paths[0], scene.image)
        rows.append(
            ", ".join(
                [
                    *(str(p) for p in paths),
                    simulator_number(scene.steering),
                    simulator_number(scene.throttle),
                    "0",
                    simulator_number(scene.speed),
                ]
            )
        )
    log = root / "driving_log.csv"
    log.write_text("".join(r + "\n" for r in rows), encoding="utf-8")
    return log


def write_shadow_set(scenes: Sequence[RoadScene], out_dir: str | os.PathLike[str]) -> Path:
    """Write ``out_dir/images/scene_NNNNNN.png`` and matching single-channel 0/255
    ``out_dir/masks/scene_NNNNNN.png`` shadow masks; returns ``out_dir``."""
    root = Path(out_dir)
    for i, scene in enumerate(scenes):
        stem = f"scene_{i:06d}"
        write_image(root / "images" / f"{stem}.png", scene.image)
        write_mask(root / "masks" / f"{stem}.png", scene.shadow_mask)
    (root / "images").mkdir(parents=True, exist_ok=True)
    (root / "masks").mkdir(parents=True, exist_ok=True)
    return root


def write_carla(
    scenes: Sequence[RoadScene],
    out_dir: str | os.PathLike[str],
    *,
    labels: Literal["txt", "csv"] = "txt",
) -> Path:
    """Write an image folder with steering labels, like the Kaggle CARLA steering set.

    Images go to ``out_dir/images/000000.png``, ... (zero-padded so name order is frame
    order). Labels go to ``out_dir/steer_values.txt`` (one steering value per line, in
    image-name order) or, with ``labels="csv"``, to ``out_dir/labels.csv`` with the header
    ``image,steering`` and the image file name in the first column.

    Returns
    -------
    Path
        The label file.
    """
    if labels not in ("txt", "csv"):
        raise ParameterError("labels", labels, "'txt' or 'csv'")
    root = Path(out_dir)
    (root / "images").mkdir(parents=True, exist_ok=True)
    digits = max(6, len(str(max(len(scenes) - 1, 0))))
    names = []
    for i, scene in enumerate(scenes):
        name = f"{i:0{digits}d}.png"
        write_image(root / "images" / name, scene.image)
        names.append(name)
    values = [repr(float(s.steering)) for s in scenes]
    if labels == "txt":
        out = root / "steer_values.txt"
        out.write_text("".join(v + "\n" for v in values), encoding="utf-8")
    else:
        out = root / "labels.csv"
        out.write_text(
            "image,steering\n" + "".join(f"{n},{v}\n" for n, v in zip(names, values, strict=True)),
            encoding="utf-8",
        )
    return out
