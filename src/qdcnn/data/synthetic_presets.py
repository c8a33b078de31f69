"""The names of the synthetic presets (:mod:`qdcnn.data.synthetic`), on their own.

They are here rather than beside the generator so that naming them (the ``synth --preset``
help) loads neither NumPy nor OpenCV.
"""

from __future__ import annotations

PRESETS: tuple[str, ...] = ("track1", "track2", "rain", "dashcam")
