"""The networks a direction classifier can train: a registry of name -> factory + input spec.

Every entry builds a plain ``torch.nn.Module`` mapping preprocessed frames
``(B, in_channels, H, W)`` to logits ``(B, num_classes)``; its
:class:`~qdcnn.models.specs.InputSpec` says how frames are cropped, resized and
scaled for it. Registering a network is one entry in :data:`NETWORKS` (or a call
to :func:`register_network`)::

    def _my_net(in_channels: int, num_classes: int, **kw: Any) -> nn.Module:
        from qdcnn.models.mine import MyNet  # imported when built: torch stays optional

        return MyNet(in_channels=in_channels, num_classes=num_classes, **kw)

    NETWORKS["my-net"] = NetworkEntry(_my_net, PILOTNET_INPUT, "qdcnn my-net")

This module imports without torch; torch is loaded when a network is built.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from qdcnn._optional import require
from qdcnn._validation import check_int, check_seed
from qdcnn.errors import ParameterError
from qdcnn.models.specs import (
    HYBRID_NETWORKS,
    PILOTNET_INPUT,
    RESNET50_INPUT,
    InputSpec,
)

if TYPE_CHECKING:
    from torch import nn

#: ``factory(in_channels, num_classes, **kw)`` returning a freshly initialised network.
_NetworkFactory = Callable[..., "nn.Module"]


@dataclass(frozen=True)
class NetworkEntry:
    """How to build one registered network and feed it.

    Attributes
    ----------
    factory : callable
        ``factory(in_channels, num_classes, **kw) -> nn.Module``; imports torch
        code lazily, so the registry itself needs no torch.
    input_spec : InputSpec
        Crop, input size and colour scaling of its frames.
    weights_name : str
        What a weights file for it holds, in error messages (``"torchvision ResNet-50"``).
    weights_skip : tuple of str
        State-dict prefixes left at their fresh values when initial weights are
        loaded (a new 3-class head on an ImageNet backbone: ``("fc.",)``).
    min_batch_size : int
        Smallest training batch (2 for networks with BatchNorm).
    """

    factory: _NetworkFactory
    input_spec: InputSpec
    weights_name: str
    weights_skip: tuple[str, ...] = ()
    min_batch_size: int = 1


def _pilotnet(in_channels: int, num_classes: int, **kw: Any) -> nn.Module:
    from qdcnn.models.pilotnet import PilotNet

    return PilotNet(num_classes=num_classes, in_channels=in_channels, **kw)


def _resnet50(in_channels: int, num_classes: int, **kw: Any) -> nn.Module:
    from qdcnn.models.resnet import resnet50

    return resnet50(num_classes=num_classes, in_channels=in_channels, **kw)


def _hybrid(name: str) -> _NetworkFactory:
    def build(in_channels: int, num_classes: int, **kw: Any) -> nn.Module:
        from qdcnn.models.hybrid import build_hybrid

        return build_hybrid(name, in_channels, num_classes=num_classes, **kw)

    return build


NETWORKS: dict[str, NetworkEntry] = {
    "pilotnet": NetworkEntry(_pilotnet, PILOTNET_INPUT, "qdcnn PilotNet"),
    "resnet50": NetworkEntry(
        _resnet50,
        RESNET50_INPUT,
        "torchvision ResNet-50",
        weights_skip=("fc.",),
        min_batch_size=2,
    ),
    # the hybrids (PilotNet trunk; ``network_params={"head": "classical"}`` gives the twin)
    **{
        h.name: NetworkEntry(
            _hybrid(h.name), PILOTNET_INPUT, f"qdcnn {h.name}", min_batch_size=h.min_batch_size
        )
        for h in HYBRID_NETWORKS
    },
}


def register_network(name: str, entry: NetworkEntry, *, replace: bool = False) -> None:
    """Add ``entry`` to :data:`NETWORKS` under ``name``.

    Raises
    ------
    ParameterError
        ``name`` is empty, not a string, or already registered (unless ``replace``).
    """
    if not isinstance(name, str) or not name.strip():
        raise ParameterError("name", name, "a non-empty network name")
    if name in NETWORKS and not replace:
        raise ParameterError("name", name, "a name not registered yet (pass replace=True)")
    NETWORKS[name] = entry


def network_entry(arch: object) -> NetworkEntry:
    """The registry entry of ``arch``.

    Raises
    ------
    ParameterError
        ``arch`` is not a registered network (the message lists them).

    Examples
    --------
    >>> network_entry("resnet50").min_batch_size
    2
    >>> network_entry("vgg")
    Traceback (most recent call last):
    ...
    qdcnn.errors.ParameterError: arch='vgg' is invalid: one of 'pilotnet', 'resnet50', ...
    """
    if not isinstance(arch, str) or arch not in NETWORKS:
        raise ParameterError("arch", arch, "one of " + ", ".join(map(repr, NETWORKS)))
    return NETWORKS[arch]


def input_spec(arch: str, crop: tuple[float, float] | None = None) -> InputSpec:
    """Preprocessing of ``arch``, optionally with another crop (rows as fractions of the height)."""
    spec = network_entry(arch).input_spec
    if crop is None:
        return spec
    return dataclasses.replace(spec, crop=(float(crop[0]), float(crop[1])))


def build_network(
    arch: str,
    in_channels: int = 3,
    num_classes: int = 3,
    *,
    weights: str | os.PathLike[str] | None = None,
    seed: int | None = None,
    **kw: Any,
) -> nn.Module:
    """A freshly built network of the registry, optionally starting from a weights file.

    Parameters
    ----------
    arch : str
        A name in :data:`NETWORKS` (``"pilotnet"``, ``"resnet50"``).
    in_channels : int
        Input planes: 3 for one RGB frame, 3K for K stacked frames.
    num_classes : int
        Output logits.
    weights : path or None
        A local ``state_dict`` (PyTorch file read with ``weights_only=True``, or
        safetensors). Keys under the entry's ``weights_skip`` keep their fresh
        values; RGB first-layer kernels are inflated to ``in_channels = 3K``
        (:func:`qdcnn.models.weights.inflate_input_channels`). Never downloaded.
    seed : int or None
        Seeds the initialisation without touching torch's global random state
        (``None``: draw from it).
    **kw
        Further arguments of the network's factory (``dropout=0.5`` for PilotNet).

    Raises
    ------
    ParameterError
        Unknown ``arch``, a bad channel/class count, or keywords its factory rejects.
    InputError
        The weights file is missing, unreadable or does not fit the network.

    Examples
    --------
    >>> net = build_network("pilotnet", in_channels=6, seed=0)  # doctest: +SKIP
    >>> tuple(net.features[0].weight.shape)  # doctest: +SKIP
    (24, 6, 5, 5)
    """
    entry = network_entry(arch)
    check_int("in_channels", in_channels, 1, 3 * 1024)
    check_int("num_classes", num_classes, 2, 100_000)
    if weights is not None and kw.get("edge_frames") is True:
        raise ParameterError(
            "weights",
            str(weights),
            "no weights file with edge_frames: its first layer was trained on colour planes, "
            "and the edge front gives the network other planes",
        )
    torch = require("torch", f"building the {arch} network")
    if seed is None:
        network = _call(entry, arch, in_channels, num_classes, kw)
    else:
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(check_seed("seed", seed))
            network = _call(entry, arch, in_channels, num_classes, kw)
    if weights is not None:
        from qdcnn.models.weights import load_weights

        load_weights(network, weights, name=entry.weights_name, skip_prefixes=entry.weights_skip)
    return network


def _call(
    entry: NetworkEntry, arch: str, in_channels: int, num_classes: int, kw: dict[str, Any]
) -> nn.Module:
    try:
        return entry.factory(in_channels, num_classes, **kw)
    except TypeError as exc:  # an unknown or mistyped keyword of the factory
        raise ParameterError(
            "network_params", kw, f"keyword arguments the {arch} network takes ({exc})"
        ) from None
