"""Classical CNN baselines (PilotNet, ResNet-50) as direction classifiers, in plain PyTorch.

torch is the optional ``dnn`` extra: this package imports without it, and the
modules holding networks (``pilotnet``, ``resnet``, ``preprocess``, ``augment``,
``weights``) load it on import, raising :class:`qdcnn.errors.MissingExtraError`
when it is absent.
"""

from qdcnn.models.training import ARCHS, CNNDirectionClassifier, inference_fps

__all__ = ["ARCHS", "CNNDirectionClassifier", "inference_fps"]
