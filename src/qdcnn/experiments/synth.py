"""``qdcnn synth``: a synthetic drive with exact ground truth, in the layouts real data use."""

from __future__ import annotations

import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from qdcnn._validation import check_bool, check_choice, check_int, check_seed
from qdcnn.data.labels import DIRECTIONS
from qdcnn.errors import InputError
from qdcnn.outputs import LOCK_NAME, OutputFolder

__all__ = ["LAYOUTS", "SynthResult", "SynthSpec", "run_synth"]

#: Layouts ``synth`` writes: Udacity log + IMG/, shadow set images/ + masks/, CARLA-style.
LAYOUTS: tuple[str, ...] = ("udacity", "shadows", "carla")


@dataclass(frozen=True)
class SynthSpec:
    """What ``qdcnn synth`` renders and where.

    ``layout`` is one of :data:`LAYOUTS` or ``"all"`` (each in a sub-folder of ``out``);
    ``video`` also writes the drive as ``out/video/<preset>.mp4``. A non-empty ``out`` is
    refused unless ``force``, which replaces everything it holds.
    """

    out: Path
    preset: str = "track1"
    n: int = 100
    seed: int = 0
    width: int = 320
    height: int = 160
    layout: str = "all"
    video: bool = False
    force: bool = False

    def __post_init__(self) -> None:
        from qdcnn.data.synthetic import PRESETS

        check_choice("preset", self.preset, PRESETS)
        check_int("n", self.n, 1, 1_000_000)
        check_seed("seed", self.seed)
        check_int("width", self.width, 16, 7680)
        check_int("height", self.height, 16, 4320)
        check_choice("layout", self.layout, (*LAYOUTS, "all"))
        check_bool("video", self.video)
        check_bool("force", self.force)

    @property
    def layouts(self) -> tuple[str, ...]:
        return LAYOUTS if self.layout == "all" else (self.layout,)


@dataclass
class SynthResult:
    """Where each layout went and what the drive holds."""

    spec: SynthSpec
    written: dict[str, str]
    directions: dict[str, int]
    mean_shadow_fraction: float
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {
            "preset": self.spec.preset,
            "n": self.spec.n,
            "seed": self.spec.seed,
            "size": [self.spec.width, self.spec.height],
            "written": self.written,
            "directions": self.directions,
            "mean_shadow_fraction": self.mean_shadow_fraction,
            **self.extra,
        }


def run_synth(spec: SynthSpec) -> SynthResult:
    """Render the drive of ``spec`` and stream it into each requested layout.

    Scenes are rendered and written one at a time, so memory does not grow with ``n``. The
    output folder is locked while it is written (a second run into it is refused), and
    temporary files of a killed run are removed.
    """
    folder = _locked_output(spec)
    try:
        return _write_drive(spec)
    finally:
        folder.close()


def _locked_output(spec: SynthSpec) -> OutputFolder:
    """``spec.out`` opened and locked: empty, or emptied when ``spec.force``."""
    if spec.out.exists() and not spec.out.is_dir():
        raise InputError(spec.out, "exists and is not a folder")
    folder = OutputFolder(spec.out).open()
    try:
        held = [p for p in spec.out.iterdir() if p.name != LOCK_NAME]
        if held and not spec.force:
            raise InputError(
                spec.out, "folder exists and is not empty: use --force to replace what it holds"
            )
        for path in held:
            _remove(path)
    except BaseException:
        folder.close()
        raise
    return folder


def _remove(path: Path) -> None:
    try:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()
    except OSError as exc:
        raise InputError(path, f"cannot remove it: {exc.strerror or exc}") from None


def _write_drive(spec: SynthSpec) -> SynthResult:
    from qdcnn.data.synthetic import iter_drive
    from qdcnn.data.writers import (
        CarlaWriter,
        SceneSink,
        ShadowSetWriter,
        UdacityWriter,
        VideoSceneWriter,
        write_layouts,
    )

    nested = len(spec.layouts) > 1 or spec.video
    sinks: dict[str, SceneSink] = {}
    for layout in spec.layouts:
        target = spec.out / layout if nested else spec.out
        if layout == "udacity":
            sinks[layout] = UdacityWriter(target)
        elif layout == "shadows":
            sinks[layout] = ShadowSetWriter(target)
        else:
            sinks[layout] = CarlaWriter(target, count=spec.n)
    if spec.video:
        sinks["video"] = VideoSceneWriter(spec.out / "video" / f"{spec.preset}.mp4")
    tally = _Tally()
    scenes = iter_drive(spec.preset, spec.n, seed=spec.seed, width=spec.width, height=spec.height)
    paths = write_layouts(tally.count(scenes), list(sinks.values()))
    written = {name: str(path) for name, path in zip(sinks, paths, strict=True)}
    return SynthResult(spec, written, tally.directions(), tally.shadow / max(spec.n, 1))


class _Tally:
    """Directions and shadow fraction of the scenes streaming past."""

    def __init__(self) -> None:
        self.counts = np.zeros(len(DIRECTIONS), dtype=np.int64)
        self.shadow = 0.0

    def count(self, scenes: Any) -> Any:
        for scene in scenes:
            self.counts[scene.direction] += 1
            self.shadow += float(scene.shadow_mask.mean())
            yield scene

    def directions(self) -> dict[str, int]:
        return {name: int(c) for name, c in zip(DIRECTIONS, self.counts, strict=True)}
