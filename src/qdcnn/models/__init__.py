"""Direction classifiers on road frames with CNNs (PilotNet, ResNet-50), in plain PyTorch.

torch is the optional ``dnn`` extra. This package and the modules
:mod:`~qdcnn.models.training` (the estimator), :mod:`~qdcnn.models.networks`
(the registry of networks), :mod:`~qdcnn.models.samples` (context windows,
side-camera views, validation split) and :mod:`~qdcnn.models.specs` import
without it; the modules holding torch code (``pilotnet``, ``resnet``,
``preprocess``, ``augment``, ``weights``, ``trainer``, ``persistence``) load it
on import, raising :class:`qdcnn.errors.MissingExtraError` when it is absent.
"""

from qdcnn.models.training import ARCHS, CNNDirectionClassifier, inference_fps

__all__ = ["ARCHS", "CNNDirectionClassifier", "inference_fps"]
