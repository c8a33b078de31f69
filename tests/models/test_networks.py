"""The network registry: building, seeding, registering a new network, initial weights files."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

torch = pytest.importorskip("torch")
safetensors_torch = pytest.importorskip("safetensors.torch")

from torch import nn  # noqa: E402

from qdcnn.errors import InputError, ParameterError  # noqa: E402
from qdcnn.models import ARCHS, CNNDirectionClassifier  # noqa: E402
from qdcnn.models.hybrid import HYBRIDS  # noqa: E402
from qdcnn.models.networks import (  # noqa: E402
    NETWORKS,
    NetworkEntry,
    build_network,
    input_spec,
    network_entry,
    register_network,
)
from qdcnn.models.pilotnet import PilotNet  # noqa: E402
from qdcnn.models.preprocess import PILOTNET_INPUT, normalise  # noqa: E402
from qdcnn.models.specs import (  # noqa: E402
    HYBRID_NETWORKS,
    InputSpec,
    hybrid_of,
    network_label,
)


def test_registry_holds_the_baselines_and_the_hybrids() -> None:
    hybrids = ("qdcnn-head", "qdcnn-uuconv", "qdcnn-quanv")
    assert ARCHS == ("pilotnet", "resnet50", *hybrids) == tuple(NETWORKS)
    assert network_entry("pilotnet").input_spec == PILOTNET_INPUT
    assert network_entry("resnet50").weights_skip == ("fc.",)
    assert input_spec("pilotnet", (0.5, 1)).crop == (0.5, 1.0)
    with pytest.raises(ParameterError) as err:
        network_entry("vgg")
    assert str(err.value) == (
        "arch='vgg' is invalid: one of 'pilotnet', 'resnet50', 'qdcnn-head', 'qdcnn-uuconv', "
        "'qdcnn-quanv'"
    )
    with pytest.raises(ParameterError) as err:
        build_network("pilotnet", in_channels=0)
    assert str(err.value) == "in_channels=0 is invalid: an integer in [1, 3072]"


def test_each_hybrid_is_a_network_with_a_named_classical_twin() -> None:
    assert [h.name for h in HYBRID_NETWORKS] == list(HYBRIDS)
    assert all(network_entry(h.name).min_batch_size == h.min_batch_size for h in HYBRID_NETWORKS)
    head = hybrid_of("qdcnn-head-classical")
    assert head is hybrid_of("qdcnn-head") and head is not None
    assert head.twin == "qdcnn-head-classical"
    assert hybrid_of("pilotnet") is None and hybrid_of("pilotnet-classical") is None
    assert network_label("qdcnn-head", "classical") == "qdcnn-head-classical"
    assert network_label("qdcnn-head", "quantum") == network_label("qdcnn-head") == "qdcnn-head"


def test_channels_classes_and_seeded_initialisation() -> None:
    net = build_network("pilotnet", in_channels=6, num_classes=4, seed=5).eval()
    with torch.inference_mode():
        assert tuple(net(torch.zeros(2, 6, 66, 200)).shape) == (2, 4)
    torch.manual_seed(0)
    expected = torch.rand(2)
    torch.manual_seed(0)
    twin = build_network("pilotnet", in_channels=6, num_classes=4, seed=5)
    assert torch.equal(torch.rand(2), expected)  # the global generator was not used
    assert all(torch.equal(a, b) for a, b in zip(net.parameters(), twin.parameters(), strict=True))
    other = build_network("pilotnet", in_channels=6, num_classes=4, seed=6)
    assert not torch.equal(other.features[0].weight, net.features[0].weight)
    resnet = build_network("resnet50", in_channels=9, seed=0)
    assert tuple(resnet.conv1.weight.shape) == (64, 9, 7, 7)


class TinyBN(nn.Module):
    """A small network with BatchNorm (0-d num_batches_tracked buffers) on 16x32 frames."""

    def __init__(self, in_channels: int, num_classes: int, width: int = 4) -> None:
        super().__init__()
        self.body = nn.Sequential(
            nn.Conv2d(in_channels, width, 3, stride=2, padding=1),
            nn.BatchNorm2d(width),
            nn.ReLU(),
            nn.Flatten(),
            nn.Linear(width * 8 * 16, num_classes),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out: torch.Tensor = self.body(x)
        return out


@pytest.fixture
def tiny_registered() -> Iterator[str]:
    spec = InputSpec(crop=(0.0, 1.0), height=16, width=32, colour="imagenet")
    register_network("tiny-bn", NetworkEntry(TinyBN, spec, "tiny-bn", min_batch_size=2))
    yield "tiny-bn"
    NETWORKS.pop("tiny-bn")


def test_a_registered_network_trains_saves_and_loads(tiny_registered: str, tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    frames = rng.integers(0, 256, (24, 32, 64, 3), dtype=np.uint8)
    labels = np.arange(24) % 3
    clf = CNNDirectionClassifier(
        tiny_registered, epochs=1, progress=False, num_threads=1, device="cpu", context=2
    ).fit(frames, labels)
    assert isinstance(clf.model_, TinyBN) and clf.model_.body[0].in_channels == 6
    loaded = CNNDirectionClassifier.load(clf.save(tmp_path / "tiny.safetensors"))
    np.testing.assert_array_equal(loaded.predict_proba(frames), clf.predict_proba(frames))
    counter = loaded.model_.state_dict()["body.1.num_batches_tracked"]
    assert counter.shape == () and int(counter) == int(clf.model_.body[1].num_batches_tracked)
    with pytest.raises(ParameterError) as err:
        CNNDirectionClassifier(tiny_registered, batch_size=1, progress=False).fit(frames, labels)
    assert str(err.value) == "batch_size=1 is invalid: an integer in [2, 65536]"
    with pytest.raises(ParameterError) as err:
        register_network(tiny_registered, NETWORKS["pilotnet"])
    assert str(err.value) == (
        "name='tiny-bn' is invalid: a name not registered yet (pass replace=True)"
    )
    register_network(tiny_registered, NETWORKS["pilotnet"], replace=True)
    assert network_entry(tiny_registered) is NETWORKS["pilotnet"]


def stacked(frame: torch.Tensor, k: int) -> torch.Tensor:
    return frame.repeat(1, k, 1, 1)


def test_rgb_weights_inflate_to_stacked_frames(tmp_path: Path) -> None:
    torch.manual_seed(7)
    rgb = PilotNet().eval()
    path = tmp_path / "pilotnet.pth"
    torch.save(rgb.state_dict(), path)
    three = build_network("pilotnet", in_channels=9, weights=path).eval()
    frame = normalise(torch.randint(0, 256, (2, 3, 66, 200)), PILOTNET_INPUT)
    with torch.inference_mode():
        torch.testing.assert_close(three(stacked(frame, 3)), rgb(frame), rtol=1e-5, atol=1e-5)
    state = three.state_dict()
    assert torch.equal(state["features.0.weight"][:, 3:6], rgb.features[0].weight / 3)
    assert torch.equal(state["classifier.8.bias"], rgb.classifier[8].bias)


def test_safetensors_weights_and_saved_classifiers_start_a_network(tmp_path: Path) -> None:
    torch.manual_seed(8)
    start = PilotNet().state_dict()
    path = tmp_path / "pilotnet.safetensors"
    safetensors_torch.save_file(start, str(path))
    state = build_network("pilotnet", weights=path).state_dict()
    assert all(torch.equal(state[k], v) for k, v in start.items())
    clf = CNNDirectionClassifier.from_network(build_network("pilotnet", seed=2), device="cpu")
    saved = clf.save(tmp_path / "clf.safetensors")
    state = build_network("pilotnet", weights=saved).state_dict()
    assert all(torch.equal(state[k], v) for k, v in clf.model_.state_dict().items())
    cut = tmp_path / "cut.safetensors"
    cut.write_bytes(path.read_bytes()[:5000])
    with pytest.raises(InputError) as err:
        build_network("pilotnet", weights=cut)
    message = str(err.value)
    assert message.startswith(f"{cut}: not a readable safetensors file (") and "\n" not in message


def test_factory_keywords_reach_the_network() -> None:
    net: Any = build_network("pilotnet", dropout=0.5)
    assert net.classifier[1].p == 0.5


def test_network_params_reach_the_factory_and_the_file(tmp_path: Path) -> None:
    frames = np.random.default_rng(3).integers(0, 256, (20, 40, 80, 3), dtype=np.uint8)
    labels = np.arange(20) % 3
    clf = CNNDirectionClassifier(
        epochs=1, progress=False, num_threads=1, device="cpu", network_params={"dropout": 0.0}
    ).fit(frames, labels)
    assert clf.model_.classifier[1].p == 0.0
    loaded = CNNDirectionClassifier.load(clf.save(tmp_path / "p.safetensors"))
    assert loaded.model_.classifier[1].p == 0.0
    assert loaded.get_params()["network_params"] == {"dropout": 0.0}
    with pytest.raises(ParameterError) as err:
        CNNDirectionClassifier(network_params={"depth": 3}, progress=False).fit(frames, labels)
    assert str(err.value).startswith(
        "network_params={'depth': 3} is invalid: keyword arguments the pilotnet network takes ("
    )
    with pytest.raises(ParameterError) as err:
        CNNDirectionClassifier(network_params={"p": float("nan")}).fit(frames, labels)
    assert str(err.value) == (
        "network_params={'p': nan} is invalid: None or a dict of str to plain values "
        "(numbers, strings)"
    )
