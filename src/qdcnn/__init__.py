"""qdcnn: the QDCNN paper as software.

UU-dagger shadow detection with classical baselines, lane features and quantum
direction classifiers, quantum noise studies and classical CNN baselines for
road images. Stages are pure functions on NumPy arrays; :class:`PipelineConfig`
joins them and its defaults are the paper's settings.
"""

from typing import TYPE_CHECKING

from qdcnn._lazy import attach
from qdcnn.errors import InputError, MissingExtraError, ParameterError, QdcnnError

if TYPE_CHECKING:
    from qdcnn.config import PipelineConfig

# PipelineConfig loads on first use, so ``import qdcnn.cli`` (``qdcnn --help``) needs no NumPy.
__getattr__ = attach(__name__, {"config": ["PipelineConfig"]})[0]

__all__ = [
    "InputError",
    "MissingExtraError",
    "ParameterError",
    "PipelineConfig",
    "QdcnnError",
]

__version__ = "0.1.0"
