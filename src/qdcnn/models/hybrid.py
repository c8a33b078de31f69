"""Hybrid quantum-classical direction networks ("QDCNN proper"): a PilotNet trunk with
quantum layers, and classical twins with the same trunk and a head of equal size.

Every network is a plain ``nn.Module`` mapping the preprocessed frames PilotNet gets
(:data:`qdcnn.models.preprocess.PILOTNET_INPUT`: ``(B, 3 K, 66, 200)`` YUV scaled to
about ``[-1, 1]``, ``K`` stacked frames) to ``(B, 3)`` logits, so any training loop
that trains PilotNet trains them.

* ``qdcnn-head``: PilotNet's convolutions and dense layers down to its 10-unit
  embedding, then :class:`~qdcnn.models.quantum_layers.QuantumHead`.
* ``qdcnn-uuconv``: a :class:`~qdcnn.models.quantum_layers.UUConv2d` front end on the
  intensity (Y) of every frame (``v = (Y + 1) / 2``, stride 1, same size), then the
  trunk, then the quantum head.
* ``qdcnn-quanv``: a :class:`~qdcnn.models.quantum_layers.Quanvolution2d` front end on
  every input channel in place of PilotNet's first strided convolution (both halve the
  frame), then the rest of the trunk and the quantum head.

``head="classical"`` swaps the quantum head for
:class:`~qdcnn.models.quantum_layers.RingMLPHead`, which has exactly as many
trainable parameters; ``head="product"``, ``"fixed"`` and ``"linear"`` build the
ablations of :data:`~qdcnn.models.specs.HEAD_ABLATIONS`. ``dressed=False`` builds the
original (undressed) heads, as files saved before the dressing hold them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from qdcnn._optional import require
from qdcnn._validation import check_choice, check_int
from qdcnn.errors import ParameterError
from qdcnn.models.pilotnet import PilotNet, frame_front, front_planes
from qdcnn.models.quantum_layers import (
    LinearHead,
    QuantumHead,
    Quanvolution2d,
    RingMLPHead,
    UUConv2d,
)
from qdcnn.models.specs import ALL_HEADS, HYBRID_NETWORKS
from qdcnn.quantum.noise import NoiseSpec

require("torch", "the hybrid quantum networks")
import torch  # noqa: E402
from torch import nn  # noqa: E402

#: PilotNet's input size (rows, columns)
_INPUT_SIZE = (66, 200)


def pilotnet_trunk(
    in_channels: int = 3,
    input_size: tuple[int, int] = _INPUT_SIZE,
    *,
    drop_first_conv: bool = False,
    dropout: float = 0.3,
) -> tuple[nn.Sequential, int]:
    """PilotNet without its class layer: ``(B, C, H, W)`` -> ``(B, 10)`` embeddings.

    The layers are those of :class:`qdcnn.models.pilotnet.PilotNet`; the first
    convolution is rebuilt for ``in_channels`` (or dropped), and the first dense layer
    for the flattened size of ``input_size``. Returns the trunk and its embedding size.
    """
    net = PilotNet(dropout=dropout)
    convs = list(net.features)[2:] if drop_first_conv else list(net.features)
    first = convs[0]
    assert isinstance(first, nn.Conv2d)
    if first.in_channels != in_channels:  # PilotNet's kernels and strides are square
        k, stride = first.kernel_size[0], first.stride[0]
        convs[0] = nn.Conv2d(in_channels, first.out_channels, k, stride)
    features = nn.Sequential(*convs)
    try:
        with torch.no_grad():
            flat = features(torch.zeros(1, in_channels, *input_size)).numel()
    except RuntimeError:
        flat = 0
    if flat == 0:
        raise ParameterError("input_size", input_size, "large enough for PilotNet's convolutions")
    dense = list(net.classifier)[:-1]  # Flatten, Dropout, 100, ELU, 50, ELU, 10, ELU
    first_dense = dense[2]
    assert isinstance(first_dense, nn.Linear)
    if first_dense.in_features != flat:
        dense[2] = nn.Linear(flat, first_dense.out_features)
    last = dense[-2]
    assert isinstance(last, nn.Linear)
    return nn.Sequential(features, *dense), last.out_features


def pilotnet_as_trunk(network: nn.Module) -> dict[str, torch.Tensor]:
    """A :class:`PilotNet`'s layers without its class layer, under the names they have in
    a hybrid's :func:`pilotnet_trunk` (``trunk.0`` the convolutions, then the dense
    layers): the trunk ``qdcnn-head`` takes from a trained PilotNet (copies, on the CPU).
    """
    if not isinstance(network, PilotNet):
        raise ParameterError("network", type(network).__name__, "a PilotNet")
    parts = [network.features, *list(network.classifier)[:-1]]
    return {
        f"trunk.{i}.{key}": value.detach().cpu().clone()
        for i, module in enumerate(parts)
        for key, value in module.state_dict().items()
    }


#: Classical network -> its trunk under a hybrid's names (:attr:`HybridNetwork.classical
#: <qdcnn.models.specs.HybridNetwork.classical>`).
CLASSICAL_TRUNKS: dict[str, Callable[[nn.Module], dict[str, torch.Tensor]]] = {
    "pilotnet": pilotnet_as_trunk,
}


def _make_head(
    head: str,
    in_features: int,
    *,
    n_qubits: int = 4,
    n_layers: int = 2,
    reupload: bool = False,
    shots: int | None = None,
    noise: NoiseSpec | None = None,
    num_classes: int = 3,
    readout_gain: float | None = None,
    dressed: bool = True,
    entangler: str | None = None,
) -> nn.Module:
    """The head ``head`` names (:data:`~qdcnn.models.specs.ALL_HEADS`): the quantum head,
    its classical twin, or an ablation (``product``: no entangling gates; ``fixed``: a
    fixed random circuit; ``linear``: one linear layer). Only circuits take shots and noise;
    ``entangler`` (the circuit's two-qubit gate) is ignored by the heads without a circuit,
    so a hybrid and its twin share their network parameters.
    """
    head = check_choice("head", head, ALL_HEADS)
    if head in ("quantum", "product", "fixed"):
        return QuantumHead(
            in_features,
            n_qubits,
            n_layers,
            reupload,
            shots,
            noise,
            num_classes=num_classes,
            readout_gain=readout_gain,
            dressed=dressed,
            entangle=head != "product",
            entangler=entangler,
            trainable_circuit=head != "fixed",
        )
    for name, value in (("shots", shots), ("noise", noise), ("reupload", reupload or None)):
        if value is not None:
            raise ParameterError(name, value, f"None with the {head} head (circuits only)")
    if head == "linear":
        return LinearHead(in_features, num_classes)
    return RingMLPHead(in_features, n_qubits, n_layers, num_classes, readout_gain, dressed=dressed)


class HybridNet(nn.Module):
    """``front`` (optional) -> ``trunk`` -> ``head``: ``(B, C, H, W)`` -> ``(B, 3)`` logits."""

    def __init__(self, front: nn.Module | None, trunk: nn.Module, head: nn.Module) -> None:
        super().__init__()
        self.front = front
        self.trunk = trunk
        self.head = head

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.front is not None:
            x = self.front(x)
        out: torch.Tensor = self.head(self.trunk(x))
        return out


class _IntensityUUConv(nn.Module):
    """:class:`UUConv2d` on the Y plane of each of ``K`` stacked YUV frames, same size.

    ``(B, 3 K, H, W)`` scaled YUV -> ``(B, K n_centroids, H, W)`` fidelities; the frames
    share the centroids. ``Y`` in ``[-1, 1]`` maps to ``v = (Y + 1) / 2 = Y_8bit / 255``.
    """

    def __init__(self, in_channels: int, n_centroids: int = 4, kernel_size: int = 3) -> None:
        super().__init__()
        if check_int("in_channels", in_channels, 3) % 3:
            raise ParameterError("in_channels", in_channels, "3 K channels (K YUV frames)")
        self.frames = in_channels // 3
        k = check_int("kernel_size", kernel_size, 1)
        if k % 2 == 0:
            raise ParameterError("kernel_size", k, "an odd size (the output keeps the frame size)")
        self.uu = UUConv2d(1, n_centroids, k, stride=1, padding=k // 2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, _, h, w = x.shape
        y = ((x[:, 0::3] + 1.0) * 0.5).clamp(0.0, 1.0).reshape(b * self.frames, 1, h, w)
        out: torch.Tensor = self.uu(y)
        return out.reshape(b, self.frames * self.uu.n_centroids, *out.shape[-2:])


def qdcnn_head(
    in_channels: int = 3,
    head: str = "quantum",
    *,
    input_size: tuple[int, int] = _INPUT_SIZE,
    dropout: float = 0.3,
    standardise_frames: bool = False,
    edge_frames: bool = False,
    **head_options: Any,
) -> HybridNet:
    """``qdcnn-head``: PilotNet trunk -> quantum head (or its twin); optionally
    :class:`~qdcnn.models.pilotnet.FrameStandardisation`,
    :class:`~qdcnn.models.pilotnet.EdgeFrames` or both first, as in its PilotNet."""
    front = frame_front(standardise_frames, edge_frames)
    planes = in_channels * front_planes(standardise_frames, edge_frames)
    trunk, features = pilotnet_trunk(planes, input_size, dropout=dropout)
    return HybridNet(front, trunk, _make_head(head, features, **head_options))


def qdcnn_uuconv(
    in_channels: int = 3,
    head: str = "quantum",
    *,
    n_centroids: int = 4,
    kernel_size: int = 3,
    input_size: tuple[int, int] = _INPUT_SIZE,
    dropout: float = 0.3,
    **head_options: Any,
) -> HybridNet:
    """``qdcnn-uuconv``: UU-dagger convolution on Y -> batch norm -> PilotNet trunk -> head.

    The fidelities lie in ``[0, 1]`` with a mean near 0.75; without the batch norm the
    trunk's activations grow until the head's ``tanh`` saturates and nothing trains
    (measured on the lean-line toy of the tests: 0.33 accuracy without, 0.66 with).
    """
    front = _IntensityUUConv(in_channels, n_centroids, kernel_size)
    channels = front.frames * n_centroids
    trunk, features = pilotnet_trunk(channels, input_size, dropout=dropout)
    normalised = nn.Sequential(front, nn.BatchNorm2d(channels))
    return HybridNet(normalised, trunk, _make_head(head, features, **head_options))


def qdcnn_quanv(
    in_channels: int = 3,
    head: str = "quantum",
    *,
    quanv_layers: int = 1,
    quanv_seed: int = 42,
    input_size: tuple[int, int] = _INPUT_SIZE,
    dropout: float = 0.3,
    **head_options: Any,
) -> HybridNet:
    """``qdcnn-quanv``: quanvolution (in place of the first strided conv) -> batch norm ->
    trunk -> head.

    The batch norm puts the ``<Z>`` maps on the scale the trunk expects; without it the
    lean-line toy of the tests stays at the majority class after 15 epochs (0.33), with
    it 0.67.
    """
    front = Quanvolution2d(in_channels, quanv_layers, seed=quanv_seed)
    half = (input_size[0] // 2, input_size[1] // 2)
    trunk, features = pilotnet_trunk(4 * in_channels, half, drop_first_conv=True, dropout=dropout)
    normalised = nn.Sequential(front, nn.BatchNorm2d(4 * in_channels))
    return HybridNet(normalised, trunk, _make_head(head, features, **head_options))


#: The builder of each hybrid network, by name (the table is
#: :data:`qdcnn.models.specs.HYBRID_NETWORKS`).
HYBRIDS: dict[str, Callable[..., HybridNet]] = {
    h.name: globals()[h.builder] for h in HYBRID_NETWORKS
}


def build_hybrid(name: str, in_channels: int = 3, **kwargs: Any) -> HybridNet:
    """Build the hybrid network ``name`` (a key of :data:`HYBRIDS`)."""
    name = check_choice("architecture", name, tuple(HYBRIDS))
    return HYBRIDS[name](in_channels, **kwargs)


def trainable_parameters(module: nn.Module) -> int:
    """Number of trainable parameters."""
    return sum(p.numel() for p in module.parameters() if p.requires_grad)
