"""Noise sweeps: moved to :mod:`qdcnn.experiments.noise` (this name re-exports it)."""

from qdcnn._validation import check_probability
from qdcnn.config import PAPER_SHADOW_THRESHOLDS as SHADOW_THRESHOLDS
from qdcnn.experiments.noise import *  # noqa: F403
from qdcnn.experiments.noise import __all__ as _noise_all
from qdcnn.quantum.noise import PAPER_CHANNELS

__all__ = [*_noise_all, "PAPER_CHANNELS", "SHADOW_THRESHOLDS", "check_probability"]
