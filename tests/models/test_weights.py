"""Local weights files: torchvision-format ResNet-50 loads; wrong files give one-line errors."""

from __future__ import annotations

import functools
import os
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from qdcnn.errors import InputError  # noqa: E402
from qdcnn.models import CNNDirectionClassifier  # noqa: E402
from qdcnn.models.networks import build_network  # noqa: E402
from qdcnn.models.pilotnet import PilotNet  # noqa: E402
from qdcnn.models.resnet import resnet50  # noqa: E402
from qdcnn.models.weights import load_weights  # noqa: E402

NAME = "torchvision ResNet-50"


@pytest.fixture(scope="module")
def imagenet_state() -> dict[str, torch.Tensor]:
    """Stands in for torchvision's ImageNet file: same keys and shapes, 1000-class fc."""
    torch.manual_seed(0)
    return resnet50(num_classes=1000).state_dict()


@pytest.fixture(scope="module")
def imagenet_file(
    imagenet_state: dict[str, torch.Tensor], tmp_path_factory: pytest.TempPathFactory
) -> Path:
    path = tmp_path_factory.mktemp("weights") / "resnet50-imagenet.pth"
    torch.save(imagenet_state, path)
    return path


@functools.cache
def _target() -> torch.nn.Module:
    return resnet50(num_classes=3)  # built once: 25 M parameters take a while to initialise


def load_into_resnet(path: Path) -> torch.nn.Module:
    model = _target()
    load_weights(model, path, name=NAME, skip_prefixes=("fc.",))
    return model


def error_of(path: Path) -> str:
    with pytest.raises(InputError) as err:
        load_into_resnet(path)
    return str(err.value)


def test_torchvision_file_loads_backbone_and_keeps_new_head(
    imagenet_state: dict[str, torch.Tensor], imagenet_file: Path
) -> None:
    model = resnet50(num_classes=3)
    head = model.fc.weight.detach().clone()
    load_weights(model, imagenet_file, name=NAME, skip_prefixes=("fc.",))
    state = model.state_dict()
    for key in ("conv1.weight", "layer3.2.conv2.weight", "layer4.2.bn3.running_var"):
        assert torch.equal(state[key], imagenet_state[key])
    assert torch.equal(state["fc.weight"], head)  # the new 3-class head is kept


def test_older_and_wrapped_formats_load(
    imagenet_state: dict[str, torch.Tensor], tmp_path: Path
) -> None:
    old = {k: v for k, v in imagenet_state.items() if not k.endswith("num_batches_tracked")}
    torch.save(old, tmp_path / "old.pth")  # torchvision's first ImageNet files lack counters
    model = load_into_resnet(tmp_path / "old.pth")
    assert torch.equal(model.state_dict()["bn1.weight"], imagenet_state["bn1.weight"])
    wrapped = {"epoch": 3, "state_dict": {"module." + k: v for k, v in imagenet_state.items()}}
    torch.save(wrapped, tmp_path / "ckpt.pth")  # a DataParallel training checkpoint
    model = load_into_resnet(tmp_path / "ckpt.pth")
    assert torch.equal(model.state_dict()["conv1.weight"], imagenet_state["conv1.weight"])


def test_missing_and_unreadable_files(tmp_path: Path) -> None:
    missing = tmp_path / "nope.pth"
    assert error_of(missing) == f"{missing}: file not found"
    noise = tmp_path / "noise.pth"
    noise.write_bytes(np.random.default_rng(0).bytes(4096))
    assert error_of(noise) == (
        f"{noise}: not a readable PyTorch weights file (corrupt, truncated or another format)"
    )
    empty = tmp_path / "empty.pth"
    empty.touch()
    assert error_of(empty) == f"{empty}: empty file (0 bytes)"
    assert error_of(tmp_path) == f"{tmp_path}: is a directory, not a weights file"


def test_truncated_file(imagenet_file: Path, tmp_path: Path) -> None:
    cut = tmp_path / "cut.pth"
    with open(imagenet_file, "rb") as src:
        cut.write_bytes(src.read(os.path.getsize(imagenet_file) // 2))
    assert error_of(cut) == (
        f"{cut}: not a readable PyTorch weights file (corrupt, truncated or another format)"
    )


def test_not_a_state_dict(tmp_path: Path) -> None:
    listed = tmp_path / "list.pth"
    torch.save([torch.zeros(1)], listed)
    assert error_of(listed) == f"{listed}: holds a list, not a state_dict"
    module = tmp_path / "module.pth"
    torch.save(torch.nn.Linear(2, 2), module)
    assert error_of(module) == (
        f"{module}: holds pickled Python objects, not a plain state_dict "
        "(save model.state_dict() instead)"
    )
    mixed = tmp_path / "mixed.pth"
    torch.save({"conv1.weight": "abc"}, mixed)
    assert error_of(mixed) == (
        f"{mixed}: not a state_dict: entry 'conv1.weight' is a str, not a tensor"
    )


def test_wrong_keys(imagenet_state: dict[str, torch.Tensor], tmp_path: Path) -> None:
    other = tmp_path / "other.pth"
    torch.save({"foo.weight": torch.zeros(3)}, other)
    # 320 keys less fc.weight, fc.bias and 53 optional BatchNorm counters
    assert error_of(other) == (
        f"{other}: not a {NAME} state_dict: missing 265 keys such as conv1.weight; "
        "unexpected 1 key such as foo.weight"
    )
    partial = tmp_path / "partial.pth"
    torch.save({k: v for k, v in imagenet_state.items() if not k.startswith("layer1.0.")}, partial)
    assert error_of(partial) == (
        f"{partial}: not a {NAME} state_dict: missing 20 keys such as layer1.0.conv1.weight"
    )


def test_wrong_shapes_and_values(imagenet_state: dict[str, torch.Tensor], tmp_path: Path) -> None:
    shapes = tmp_path / "shapes.pth"
    torch.save({**imagenet_state, "conv1.weight": torch.zeros(64, 3, 3, 3)}, shapes)
    assert error_of(shapes) == (
        f"{shapes}: not a {NAME} state_dict: 1 tensor with the wrong shape, "
        "such as conv1.weight (64, 3, 3, 3) instead of (64, 3, 7, 7)"
    )
    nan = tmp_path / "nan.pth"
    bad = imagenet_state["bn1.bias"].clone()
    bad[0] = float("nan")
    torch.save({**imagenet_state, "bn1.bias": bad}, nan)
    assert error_of(nan) == f"{nan}: weights contain NaN or infinite values (in bn1.bias)"


def test_classifier_reports_bad_weights(tmp_path: Path) -> None:
    frames = np.zeros((6, 40, 80, 3), np.uint8)
    labels = np.array([0, 1, 2, 0, 1, 2])
    missing = tmp_path / "resnet50.pth"
    clf = CNNDirectionClassifier("resnet50", weights=missing, epochs=1, progress=False)
    with pytest.raises(InputError, match=f"^{missing}: file not found$"):
        clf.fit(frames, labels)
    resnet_like = tmp_path / "resnet_like.pth"
    torch.save({"conv1.weight": torch.zeros(64, 3, 7, 7)}, resnet_like)
    clf = CNNDirectionClassifier("pilotnet", weights=resnet_like, epochs=1, progress=False)
    with pytest.raises(InputError) as err:
        clf.fit(frames, labels)
    assert str(err.value) == (
        f"{resnet_like}: not a qdcnn PilotNet state_dict: missing 18 keys such as "
        "features.0.weight; unexpected 1 key such as conv1.weight"
    )


def test_pilotnet_starts_from_given_weights(tmp_path: Path) -> None:
    torch.manual_seed(7)
    start = PilotNet().state_dict()
    torch.save(start, tmp_path / "pilotnet.pth")
    state = build_network("pilotnet", weights=tmp_path / "pilotnet.pth").state_dict()
    assert all(torch.equal(state[k], v) for k, v in start.items())
