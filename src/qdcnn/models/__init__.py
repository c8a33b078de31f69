"""Direction classifiers on road frames: CNNs and hybrid quantum CNNs, in PyTorch.

torch is the optional ``dnn`` extra; this package imports without it, and so do
:mod:`~qdcnn.models.training` (the estimator), :mod:`~qdcnn.models.networks` (the network
registry), :mod:`~qdcnn.models.samples` and :mod:`~qdcnn.models.specs`. The modules holding
torch code load it when used, raising :class:`qdcnn.errors.MissingExtraError` without it.

=====================  ============================================================
``training``           :class:`CNNDirectionClassifier`, the scikit-learn estimator
``networks``           the registry of networks (PilotNet, ResNet-50, the hybrids)
``trainer``            the training loop
``persistence``        safetensors model files and checkpoints
``quantum_layers``     :class:`QuantumHead`, :class:`UUConv2d`, :class:`Quanvolution2d`
``hybrid``             the hybrid QDCNN networks and their classical twins
=====================  ============================================================
"""

from qdcnn._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "training": ["ARCHS", "CNNDirectionClassifier", "inference_fps"],
        "networks": ["NETWORKS", "build_network", "register_network"],
        "trainer": ["Trainer"],
        "quantum_layers": ["QuantumHead", "UUConv2d", "Quanvolution2d"],
        "hybrid": ["HYBRIDS", "build_hybrid"],
    },
)
