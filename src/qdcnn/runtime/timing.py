"""Measured timing helpers: medians of repeated runs with :func:`time.perf_counter`.

Everything here is a measurement on this machine. Estimated hardware times live
in :mod:`qdcnn.quantum.hardware_time` and carry ``kind = "estimate"``; results of
this module carry ``kind = "measured"``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Timing:
    """Median and spread of repeated measurements of one operation (seconds)."""

    name: str
    median_s: float
    min_s: float
    max_s: float
    repeats: int
    kind: str = "measured"

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def time_per_item(
    name: str, fn: Callable[[Any], object], items: list[Any], *, repeats: int = 3
) -> Timing:
    """Median over ``repeats`` passes of the mean time per item of ``fn(item)``."""
    fn(items[0])
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for item in items:
            fn(item)
        samples.append((time.perf_counter() - t0) / len(items))
    arr = np.asarray(samples)
    return Timing(name, float(np.median(arr)), float(arr.min()), float(arr.max()), repeats)
