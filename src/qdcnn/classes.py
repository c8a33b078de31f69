"""The three direction classes, with the indices every part of qdcnn uses.

0 = left, 1 = straight, 2 = right. A module of its own at the bottom of the package, so
that the quantum classifiers and the data labels name the classes the same way without
one importing the other.
"""

from __future__ import annotations

DIRECTIONS: tuple[str, str, str] = ("left", "straight", "right")
LEFT, STRAIGHT, RIGHT = 0, 1, 2
