"""ResNet-50 in plain torch: torchvision's names, shapes and parameter count."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from qdcnn.models import CNNDirectionClassifier  # noqa: E402
from qdcnn.models.networks import build_network  # noqa: E402
from qdcnn.models.resnet import resnet50  # noqa: E402

# (key, shape) pairs as in torchvision.models.resnet50().state_dict()
TORCHVISION_KEYS = {
    "conv1.weight": (64, 3, 7, 7),
    "bn1.running_mean": (64,),
    "layer1.0.conv1.weight": (64, 64, 1, 1),
    "layer1.0.downsample.0.weight": (256, 64, 1, 1),
    "layer1.0.downsample.1.num_batches_tracked": (),
    "layer2.0.conv2.weight": (128, 128, 3, 3),
    "layer3.5.bn2.weight": (256,),
    "layer4.0.downsample.0.weight": (2048, 1024, 1, 1),
    "layer4.2.conv3.weight": (2048, 512, 1, 1),
    "layer4.2.bn3.running_var": (2048,),
    "fc.weight": (1000, 2048),
    "fc.bias": (1000,),
}


def test_state_dict_uses_torchvision_names() -> None:
    model = resnet50()
    state = model.state_dict()
    assert len(state) == 320
    assert {k: tuple(state[k].shape) for k in TORCHVISION_KEYS} == TORCHVISION_KEYS
    assert sum(p.numel() for p in model.parameters()) == 25_557_032
    assert list(state)[:3] == ["conv1.weight", "bn1.weight", "bn1.bias"]


def test_three_class_head_forward() -> None:
    model = resnet50(num_classes=3).eval()
    with torch.inference_mode():
        assert tuple(model(torch.zeros((2, 3, 64, 64))).shape) == (2, 3)


def test_classifier_predicts_on_frames() -> None:
    network = build_network("resnet50", seed=0)
    clf = CNNDirectionClassifier.from_network(network, "resnet50", device="cpu", num_threads=1)
    frames = np.random.default_rng(0).integers(0, 256, (2, 40, 80, 3), dtype=np.uint8)
    proba = clf.predict_proba(frames)
    assert proba.shape == (2, 3)
    np.testing.assert_allclose(proba.sum(axis=1), 1.0, atol=1e-6)
