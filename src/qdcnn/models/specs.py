"""What each network expects of its input frames, without importing torch.

:class:`InputSpec` names the rows kept, the network input size and the colour
scaling; :mod:`qdcnn.models.preprocess` applies it (and re-exports these names),
:mod:`qdcnn.models.networks` pairs one with every registered network.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

# Rows 60..135 of a 160-row Udacity frame: drop the sky above and the car hood below.
ROAD_CROP: tuple[float, float] = (60 / 160, 135 / 160)
IMAGENET_MEAN: tuple[float, float, float] = (0.485, 0.456, 0.406)
IMAGENET_STD: tuple[float, float, float] = (0.229, 0.224, 0.225)
COLOURS: tuple[str, str] = ("yuv", "imagenet")


@dataclass(frozen=True)
class InputSpec:
    """What a network expects: the rows kept, the input size and the colour scaling.

    Attributes
    ----------
    crop : (float, float)
        First and end row kept, as fractions of the frame height (full width is kept).
    height, width : int
        Network input size after resizing the crop.
    colour : {"yuv", "imagenet"}
        ``"yuv"``: BT.601 YUV scaled to about [-1, 1] (PilotNet's fixed normalisation
        layer). ``"imagenet"``: RGB in [0, 1] standardised with ImageNet mean and std.
    """

    crop: tuple[float, float]
    height: int
    width: int
    colour: Literal["yuv", "imagenet"]


# Bojarski et al. 2016 (arXiv:1604.07316), Fig. 4: 66x200 YUV planes.
PILOTNET_INPUT = InputSpec(crop=ROAD_CROP, height=66, width=200, colour="yuv")
# He et al. 2016 / torchvision: 224x224 ImageNet-normalised RGB. The road crop of a 320x160
# frame (320x75) is stretched vertically to a square, as in the usual transfer-learning
# recipes, so the pretrained receptive fields see a 224-pixel-high road.
RESNET50_INPUT = InputSpec(crop=ROAD_CROP, height=224, width=224, colour="imagenet")


#: The heads a hybrid network takes: its quantum head, or the classical twin of equal size.
HEADS: tuple[str, str] = ("quantum", "classical")
#: A hybrid's classical twin is named after it with this suffix (method, progress label).
_TWIN_SUFFIX = "-classical"


@dataclass(frozen=True)
class HeadAblation:
    """A head that removes part of the quantum head, trained like it on the same trunk.

    Attributes
    ----------
    suffix : str
        The method is the hybrid's name, ``-`` and this (``qdcnn-head-noent``).
    head : str
        The value of the network's ``head`` parameter that builds it.
    summary : str
        What it removes, for listings and reports.
    """

    suffix: str
    head: str
    summary: str


#: The ablations of a quantum head (the field's check that a quantum layer adds anything:
#: Bowles, Ahmed and Schuld 2024).
HEAD_ABLATIONS: tuple[HeadAblation, ...] = (
    HeadAblation("noent", "product", "its quantum head without entangling gates (a product state)"),
    HeadAblation(
        "fixed",
        "fixed",
        "its quantum head as a fixed random circuit (only the encoding and read-out train)",
    ),
    HeadAblation("linear", "linear", "a linear head on the trunk's embedding (no circuit)"),
)
#: Every head a hybrid network can be built with.
ALL_HEADS: tuple[str, ...] = HEADS + tuple(a.head for a in HEAD_ABLATIONS)


@dataclass(frozen=True)
class HybridNetwork:
    """One hybrid QDCNN network: its name, its builder and what it is.

    Each hybrid is a registered network (:data:`qdcnn.models.networks.NETWORKS`) and two
    direction methods: the hybrid itself (``head="quantum"``) and its classical twin
    (``head="classical"``, named :attr:`twin`), which swaps the quantum head for an MLP of
    the same parameter count.

    Attributes
    ----------
    name : str
        The network's name, which is also its quantum method's.
    builder : str
        The function of :mod:`qdcnn.models.hybrid` that builds it.
    summary : str
        One line for listings and reports.
    min_batch_size : int
        Smallest training batch (2 for networks with BatchNorm).
    ablated : bool
        Also registered with each head of :data:`HEAD_ABLATIONS` (:attr:`ablations`).
    classical : str or None
        The registered classical network that is this hybrid with a linear head, if any
        (``pilotnet`` for ``qdcnn-head``): the transfer recipe's stage 1 is that network's
        own training, shared with its method (``dnn-pilotnet``).
    """

    name: str
    builder: str
    summary: str
    min_batch_size: int = 1
    ablated: bool = False
    classical: str | None = None

    @property
    def twin(self) -> str:
        """The name of its classical twin."""
        return self.name + _TWIN_SUFFIX

    @property
    def ablations(self) -> tuple[tuple[str, HeadAblation], ...]:
        """``(method name, ablation)`` of each of its ablations (none unless :attr:`ablated`)."""
        if not self.ablated:
            return ()
        return tuple((f"{self.name}-{a.suffix}", a) for a in HEAD_ABLATIONS)


#: The hybrid QDCNN networks (quantum layers inside a PilotNet-style CNN, issue 11).
HYBRID_NETWORKS: tuple[HybridNetwork, ...] = (
    HybridNetwork(
        "qdcnn-head",
        "qdcnn_head",
        "PilotNet trunk, then a 4-qubit variational quantum head",
        ablated=True,
        classical="pilotnet",
    ),
    HybridNetwork(
        "qdcnn-uuconv",
        "qdcnn_uuconv",
        "UU-dagger fidelity convolution, PilotNet trunk, quantum head",
        min_batch_size=2,
    ),
    HybridNetwork(
        "qdcnn-quanv",
        "qdcnn_quanv",
        "quanvolution (fixed random 4-qubit circuits), PilotNet trunk, quantum head",
        min_batch_size=2,
    ),
)


def hybrid_of(name: str) -> HybridNetwork | None:
    """The hybrid that ``name`` (a hybrid's name or its twin's) belongs to, else ``None``."""
    base = name.removesuffix(_TWIN_SUFFIX)
    return next((h for h in HYBRID_NETWORKS if h.name == base), None)


def classical_network(arch: str) -> str | None:
    """The classical network whose training is hybrid ``arch``'s transfer stage 1, if any."""
    hybrid = hybrid_of(arch)
    return None if hybrid is None else hybrid.classical


def network_label(arch: str, head: object = None) -> str:
    """The name a network trained with ``head`` goes by: a classical twin or an ablation
    says so."""
    if head == "classical":
        return arch + _TWIN_SUFFIX
    ablation = next((a for a in HEAD_ABLATIONS if a.head == head), None)
    return arch if ablation is None else f"{arch}-{ablation.suffix}"
