"""The hybrid networks: shapes, parameter-matched classical twins, stacked frames, training."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")

from qdcnn.errors import ParameterError  # noqa: E402
from qdcnn.models.hybrid import (  # noqa: E402
    CLASSICAL_TRUNKS,
    HYBRIDS,
    build_hybrid,
    pilotnet_as_trunk,
    pilotnet_trunk,
    trainable_parameters,
)
from qdcnn.models.pilotnet import PilotNet  # noqa: E402
from qdcnn.models.quantum_layers import QuantumHead, RingMLPHead  # noqa: E402
from qdcnn.models.specs import HYBRID_NETWORKS  # noqa: E402
from qdcnn.models.transfer import load_trunk  # noqa: E402
from qdcnn.quantum.noise import NoiseSpec  # noqa: E402


@pytest.fixture(autouse=True)
def _one_torch_thread():  # type: ignore[no-untyped-def]
    """Small tensors: a second intra-op thread only adds contention on a shared machine."""
    old = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(old)


@pytest.mark.parametrize("name", list(HYBRIDS))
def test_hybrids_map_frames_to_logits_and_twins_match_in_size(name: str) -> None:
    torch.manual_seed(0)
    quantum = build_hybrid(name)
    classical = build_hybrid(name, head="classical")
    assert isinstance(quantum.head, QuantumHead) and isinstance(classical.head, RingMLPHead)
    assert trainable_parameters(quantum) == trainable_parameters(classical)
    assert trainable_parameters(quantum.head) == trainable_parameters(classical.head)
    x = torch.randn(2, 3, 66, 200)
    for net in (quantum, classical):
        out = net(x)
        assert out.shape == (2, 3) and bool(torch.isfinite(out).all())


@pytest.mark.parametrize("name", list(HYBRIDS))
def test_stacked_frames_widen_the_input(name: str) -> None:
    net = build_hybrid(name, in_channels=9, n_qubits=3, n_layers=1)
    assert net(torch.randn(1, 9, 66, 200)).shape == (1, 3)


def test_trunk_is_pilotnet_without_its_class_layer() -> None:
    torch.manual_seed(3)
    trunk, size = pilotnet_trunk()
    torch.manual_seed(3)
    net = PilotNet().eval()
    trunk.eval()
    x = torch.randn(2, 3, 66, 200)
    assert size == 10
    expected = net.classifier[:-1](net.features(x))
    torch.testing.assert_close(trunk(x), expected)
    with pytest.raises(ParameterError, match="input_size"):
        pilotnet_trunk(3, (20, 20))


@pytest.mark.parametrize("context", [1, 3])
def test_a_trained_pilotnet_is_qdcnn_head_with_a_linear_head(context: int) -> None:
    torch.manual_seed(4)
    net = PilotNet(in_channels=3 * context).eval()
    hybrid = build_hybrid("qdcnn-head", in_channels=3 * context, head="linear").eval()
    load_trunk(hybrid, pilotnet_as_trunk(net))
    hybrid.head.readout.load_state_dict(net.classifier[-1].state_dict())
    x = torch.randn(2, 3 * context, 66, 200)
    torch.testing.assert_close(hybrid(x), net(x), rtol=0, atol=0)
    assert {h.classical for h in HYBRID_NETWORKS} - {None} <= set(CLASSICAL_TRUNKS)
    with pytest.raises(ParameterError, match="network='HybridNet' is invalid.*a PilotNet"):
        pilotnet_as_trunk(hybrid)


def test_quantum_head_learns_three_classes() -> None:
    torch.manual_seed(0)
    y = torch.arange(150) % 3
    x = torch.eye(5)[y] * 2 + 0.5 * torch.randn(150, 5)
    head = QuantumHead(5, 4, 2)
    opt = torch.optim.Adam(head.parameters(), lr=0.05)
    for _ in range(120):
        opt.zero_grad()
        loss = torch.nn.functional.cross_entropy(head(x), y)
        loss.backward()
        opt.step()
    assert loss.item() < 0.1
    assert float((head(x).argmax(1) == y).float().mean()) > 0.97


def _toy_loss_after(head: torch.nn.Module, steps: int) -> float:
    torch.manual_seed(1)
    y = torch.arange(150) % 3
    x = torch.eye(5)[y] * 2 + 0.5 * torch.randn(150, 5)
    opt = torch.optim.AdamW(head.parameters(), lr=1e-2)
    for _ in range(steps):
        opt.zero_grad()
        loss = torch.nn.functional.cross_entropy(head(x), y)
        loss.backward()
        opt.step()
    return loss.item()


@pytest.mark.parametrize("head_cls", [QuantumHead, RingMLPHead])
def test_readout_gain_lets_bounded_features_reach_confident_logits(head_cls: type) -> None:
    """The undressed heads' fixed gain (the dressed heads train their output scale)."""
    torch.manual_seed(0)
    plain = head_cls(5, 4, 2, readout_gain=1.0, dressed=False)
    torch.manual_seed(0)
    gained = head_cls(5, 4, 2, readout_gain=10.0, dressed=False)
    assert _toy_loss_after(gained, 40) < 0.5 * _toy_loss_after(plain, 40)


def test_readout_gain_reaches_both_heads_and_is_checked() -> None:
    for head in ("quantum", "classical"):
        assert build_hybrid("qdcnn-head", head=head, readout_gain=3.0).head.readout_gain == 3.0
    with pytest.raises(ParameterError, match="readout_gain=0.0 is invalid"):
        build_hybrid("qdcnn-head", readout_gain=0.0)


@pytest.mark.parametrize("name", list(HYBRIDS))
def test_gradients_reach_every_layer(name: str) -> None:
    torch.manual_seed(2)
    net = build_hybrid(name, n_qubits=2, n_layers=1, input_size=(62, 64))
    x = torch.randn(2, 3, 62, 64) * 0.5
    torch.nn.functional.cross_entropy(net(x), torch.tensor([0, 2])).backward()
    for pname, p in net.named_parameters():
        assert p.grad is not None and float(p.grad.abs().sum()) > 0, pname


def test_noise_and_shots_are_for_the_quantum_head() -> None:
    net = build_hybrid("qdcnn-head", noise=NoiseSpec("depolarizing", 0.05), shots=256)
    net.eval()
    assert net(torch.randn(2, 3, 66, 200)).shape == (2, 3)
    with pytest.raises(ParameterError, match="noise=.* is invalid: None with the classical head"):
        build_hybrid("qdcnn-head", head="classical", noise=NoiseSpec("depolarizing", 0.05))
    with pytest.raises(ParameterError, match="architecture='qdcnn-x' is invalid"):
        build_hybrid("qdcnn-x")
    with pytest.raises(ParameterError, match="in_channels=4 is invalid: 3 K channels"):
        build_hybrid("qdcnn-uuconv", in_channels=4)
