"""``qdcnn synth``: a synthetic drive with exact ground truth, in the layouts real data use."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from qdcnn._validation import check_choice, check_int, check_seed
from qdcnn.data.labels import DIRECTIONS

__all__ = ["LAYOUTS", "SynthResult", "SynthSpec", "run_synth"]

#: Layouts ``synth`` writes: Udacity log + IMG/, shadow set images/ + masks/, CARLA-style.
LAYOUTS: tuple[str, ...] = ("udacity", "shadows", "carla")


@dataclass(frozen=True)
class SynthSpec:
    """What ``qdcnn synth`` renders and where.

    ``layout`` is one of :data:`LAYOUTS` or ``"all"`` (each in a sub-folder of ``out``).
    """

    out: Path
    preset: str = "track1"
    n: int = 100
    seed: int = 0
    width: int = 320
    height: int = 160
    layout: str = "all"

    def __post_init__(self) -> None:
        from qdcnn.data.synthetic import PRESETS

        check_choice("preset", self.preset, PRESETS)
        check_int("n", self.n, 1, 1_000_000)
        check_seed("seed", self.seed)
        check_int("width", self.width, 16, 7680)
        check_int("height", self.height, 16, 4320)
        check_choice("layout", self.layout, (*LAYOUTS, "all"))

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
    """Render the drive of ``spec`` and write it in each requested layout."""
    from qdcnn.data.synthetic import generate_drive
    from qdcnn.data.writers import write_carla, write_shadow_set, write_udacity

    scenes = generate_drive(
        spec.preset, spec.n, seed=spec.seed, width=spec.width, height=spec.height
    )
    writers = {"udacity": write_udacity, "shadows": write_shadow_set, "carla": write_carla}
    written = {}
    for layout in spec.layouts:
        target = spec.out / layout if len(spec.layouts) > 1 else spec.out
        written[layout] = str(writers[layout](scenes, target))
    counts = np.bincount([s.direction for s in scenes], minlength=len(DIRECTIONS))
    return SynthResult(
        spec,
        written,
        {name: int(c) for name, c in zip(DIRECTIONS, counts, strict=True)},
        float(np.mean([s.shadow_mask.mean() for s in scenes])),
    )
