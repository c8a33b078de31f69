"""qdcnn: the QDCNN paper as software.

UU-dagger shadow detection with classical baselines, lane features and quantum
direction classifiers, quantum noise studies and classical CNN baselines for
road images. Stages are pure functions on NumPy arrays; :class:`PipelineConfig`
joins them and its defaults are the paper's settings.
"""

from qdcnn.config import PipelineConfig
from qdcnn.errors import InputError, MissingExtraError, ParameterError, QdcnnError

__all__ = [
    "InputError",
    "MissingExtraError",
    "ParameterError",
    "PipelineConfig",
    "QdcnnError",
]

__version__ = "0.1.0"
