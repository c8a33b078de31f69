"""NVIDIA PilotNet as a three-way direction classifier.

References
----------
.. [1] M. Bojarski et al., "End to End Learning for Self-Driving Cars",
       arXiv:1604.07316, 2016 (Fig. 4).
"""

from __future__ import annotations

from qdcnn._optional import require
from qdcnn.errors import ParameterError

require("torch", "the PilotNet model")
import torch  # noqa: E402
from torch import nn  # noqa: E402


class PilotNet(nn.Module):
    """PilotNet [1]_: five convolutions and three dense layers, with a class head.

    Input is a ``(B, 3, 66, 200)`` YUV tensor already scaled to about [-1, 1]
    (:data:`qdcnn.models.preprocess.PILOTNET_INPUT`; the paper's fixed
    normalisation layer). Convolutions: 24, 36, 48 filters 5x5 stride 2, then
    64, 64 filters 3x3 stride 1, leaving a 64x1x18 map. As in most
    reimplementations, the figure's "1164 neurons" is taken as this flattened
    map (1152 values), followed by dense layers of 100, 50 and 10 units and a
    ``num_classes`` head in place of the steering output. ELU activations;
    dropout on the flattened map because the recordings are small.

    Parameters
    ----------
    num_classes : int
        Output logits (3: left, straight, right).
    dropout : float
        Dropout probability on the flattened features.
    in_channels : int
        Input planes: 3, or 3K for K frames stacked along channels.
    standardise_frames : bool
        Put each frame through :class:`FrameStandardisation` first (not in [1]_).
    edge_frames : bool
        Put each frame through :class:`EdgeFrames` first (not in [1]_); with
        ``standardise_frames`` too, both (:class:`FramesAndEdges`: six planes a frame, so
        the first convolution takes twice ``in_channels``).
    """

    def __init__(
        self,
        num_classes: int = 3,
        dropout: float = 0.3,
        in_channels: int = 3,
        standardise_frames: bool = False,
        edge_frames: bool = False,
    ) -> None:
        super().__init__()
        self.standardise = frame_front(standardise_frames, edge_frames) or nn.Identity()
        planes = in_channels * front_planes(standardise_frames, edge_frames)
        self.features = nn.Sequential(
            nn.Conv2d(planes, 24, 5, stride=2), nn.ELU(),
            nn.Conv2d(24, 36, 5, stride=2), nn.ELU(),
            nn.Conv2d(36, 48, 5, stride=2), nn.ELU(),
            nn.Conv2d(48, 64, 3), nn.ELU(),
            nn.Conv2d(64, 64, 3), nn.ELU(),
        )  # fmt: skip
        self.classifier = nn.Sequential(
            nn.Flatten(),
            nn.Dropout(dropout),
            nn.Linear(64 * 1 * 18, 100), nn.ELU(),
            nn.Linear(100, 50), nn.ELU(),
            nn.Linear(50, 10), nn.ELU(),
            nn.Linear(10, num_classes),
        )  # fmt: skip

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Logits ``(B, num_classes)`` for a ``(B, in_channels, 66, 200)`` batch."""
        out: torch.Tensor = self.classifier(self.features(self.standardise(x)))
        return out


class FrameStandardisation(nn.Module):
    """Each frame on its own scale: its planes minus their means, over its Y spread.

    ``(B, 3K, H, W)`` scaled YUV (K frames stacked) -> the same shape. Every plane of a
    frame loses its own mean, and all three are divided by twice the standard deviation
    of the frame's Y plane (plus ``eps``), so a frame's overall brightness, contrast and
    colour cast no longer reach the network while the relative colours within it do.
    A road in deep shade or at dusk then looks like the sunlit roads a network trained
    on (``docs/builtin-model.md``). No parameters: a state dict is unchanged by it.
    """

    def __init__(self, eps: float = 0.02) -> None:
        super().__init__()
        self.eps = eps

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, c, h, w = x.shape
        frames = x.reshape(b, c // 3, 3, h * w)
        centred = frames - frames.mean(dim=-1, keepdim=True)
        spread = frames[:, :, :1].std(dim=-1, keepdim=True) + self.eps
        return (0.5 * centred / spread).reshape(b, c, h, w)


class EdgeFrames(nn.Module):
    """Each frame as its edges only: the Sobel gradients of its Y plane and their size.

    ``(B, 3K, H, W)`` scaled YUV (K frames stacked) -> the same shape: for each frame the
    horizontal and vertical Sobel derivatives of Y (replicated borders) and the gradient
    magnitude, all three divided by twice the frame's mean magnitude (plus ``eps``). The
    colour planes are dropped and a frame's brightness and contrast cancel, so what
    reaches the network is where the edges are and which way they run: what HOG sees
    (``docs/builtin-model.md``). No parameters: a state dict is unchanged by it.
    """

    def __init__(self, eps: float = 0.01) -> None:
        super().__init__()
        self.eps = eps
        sobel_x = torch.tensor([[-1.0, 0.0, 1.0], [-2.0, 0.0, 2.0], [-1.0, 0.0, 1.0]]) / 8
        kernels = torch.stack([sobel_x, sobel_x.T]).unsqueeze(1)  # (2, 1, 3, 3)
        self.kernels: torch.Tensor
        self.register_buffer("kernels", kernels, persistent=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, c, h, w = x.shape
        luma = x.reshape(b * (c // 3), 3, h, w)[:, :1]
        padded = nn.functional.pad(luma, (1, 1, 1, 1), mode="replicate")
        grad = nn.functional.conv2d(padded, self.kernels)
        size = grad.square().sum(dim=1, keepdim=True).add(1e-12).sqrt()
        scale = 2 * size.mean(dim=(1, 2, 3), keepdim=True) + self.eps
        return (torch.cat([grad, size], dim=1) / scale).reshape(b, c, h, w)


class FramesAndEdges(nn.Module):
    """Both fronts: each frame as its three standardised planes
    (:class:`FrameStandardisation`) followed by its three edge planes (:class:`EdgeFrames`).

    ``(B, 3K, H, W)`` -> ``(B, 6K, H, W)``, frame by frame. The edges carry between roads of
    other colours, the standardised colours carry what the edges miss
    (``docs/builtin-model.md``). No parameters.
    """

    def __init__(self) -> None:
        super().__init__()
        self.frames, self.edges = FrameStandardisation(), EdgeFrames()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        b, c, h, w = x.shape
        parts = [f(x).reshape(b, c // 3, 3, h, w) for f in (self.frames, self.edges)]
        return torch.cat(parts, dim=2).reshape(b, 2 * c, h, w)


def frame_front(standardise: bool, edges: bool = False) -> nn.Module | None:
    """:class:`FrameStandardisation` when ``standardise``, :class:`EdgeFrames` when
    ``edges``, :class:`FramesAndEdges` when both, else ``None``."""
    for name, on in (("standardise_frames", standardise), ("edge_frames", edges)):
        if not isinstance(on, bool):
            raise ParameterError(name, on, "True or False")
    if standardise and edges:
        return FramesAndEdges()
    if edges:
        return EdgeFrames()
    return FrameStandardisation() if standardise else None


def front_planes(standardise: bool, edges: bool) -> int:
    """Planes the front gives per input plane: 2 with both fronts, else 1."""
    return 2 if standardise and edges else 1
