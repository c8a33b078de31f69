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
    """

    def __init__(
        self,
        num_classes: int = 3,
        dropout: float = 0.3,
        in_channels: int = 3,
        standardise_frames: bool = False,
    ) -> None:
        super().__init__()
        self.standardise = frame_standardisation(standardise_frames) or nn.Identity()
        self.features = nn.Sequential(
            nn.Conv2d(in_channels, 24, 5, stride=2), nn.ELU(),
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


def frame_standardisation(on: bool) -> FrameStandardisation | None:
    """:class:`FrameStandardisation` when ``on``, else ``None``."""
    if not isinstance(on, bool):
        raise ParameterError("standardise_frames", on, "True or False")
    return FrameStandardisation() if on else None
