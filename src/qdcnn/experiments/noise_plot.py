"""Noise-sweep figures: moved to :mod:`qdcnn.experiments.noise.plot` (re-exported here)."""

from qdcnn.experiments.noise.plot import *  # noqa: F403
from qdcnn.experiments.noise.plot import __all__ as __all__
