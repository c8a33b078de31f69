"""Direction classes and labels from recorded steering.

Class indices are fixed across qdcnn: 0 = left, 1 = straight, 2 = right.
Steering follows Udacity's convention: in [-1, 1], negative is left.
"""

from __future__ import annotations

DIRECTIONS: tuple[str, str, str] = ("left", "straight", "right")
LEFT, STRAIGHT, RIGHT = 0, 1, 2
