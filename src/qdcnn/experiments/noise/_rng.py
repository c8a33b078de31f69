"""The shot generator of one sweep point: fixed by the seed and the point's name."""

from __future__ import annotations

import zlib

import numpy as np


def point_rng(seed: int, *parts: object) -> np.random.Generator:
    """A generator determined by the seed and a noise setting's name (order-independent).

    Examples
    --------
    >>> def draw():
    ...     return point_rng(0, "uu", "image-split", "bit-flip", 0.1).integers(1 << 30)
    >>> bool(draw() == draw())
    True
    """
    key = zlib.crc32("|".join(map(str, parts)).encode())
    return np.random.default_rng([int(seed), key])
