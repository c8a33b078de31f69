"""Batch preprocessing of RGB frames for the CNN baselines: crop, resize, colour, scale.

Geometry (crop and resize, :func:`crop_resize`) runs once per ``fit`` (per chunk
of frames in ``predict``) and keeps ``uint8``; colour conversion and scaling
(:func:`normalise`) run per batch on the training device, after augmentation,
so augmented pixels stay in 0..255.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn._optional import require
from qdcnn.errors import InputError
from qdcnn.models.specs import (
    IMAGENET_MEAN,
    IMAGENET_STD,
    PILOTNET_INPUT,
    RESNET50_INPUT,
    ROAD_CROP,
    InputSpec,
)

require("torch", "the CNN baselines")
import torch  # noqa: E402

__all__ = [
    "IMAGENET_MEAN",
    "IMAGENET_STD",
    "PILOTNET_INPUT",
    "RESNET50_INPUT",
    "ROAD_CROP",
    "InputSpec",
    "PreparedFrames",
    "crop_resize",
    "crop_rows",
    "normalise",
    "prepare_frames",
]

# ITU-R BT.601 as OpenCV's COLOR_RGB2YUV: Y = .299R + .587G + .114B, U = .492(B-Y), V = .877(R-Y).
_RGB_TO_YUV = torch.tensor(
    [
        [0.299, 0.587, 0.114],
        [-0.492 * 0.299, -0.492 * 0.587, 0.492 * (1 - 0.114)],
        [0.877 * (1 - 0.299), -0.877 * 0.587, -0.877 * 0.114],
    ]
)


def crop_rows(height: int, crop: tuple[float, float]) -> tuple[int, int]:
    """Pixel rows ``[top, bottom)`` kept from a frame ``height`` rows high (at least one)."""
    top = min(round(crop[0] * height), height - 1)
    bottom = max(round(crop[1] * height), top + 1)
    return top, bottom


class PreparedFrames(np.ndarray):
    """RGB frames already cropped and resized to a network input: ``(N, height, width, 3)``
    uint8 with the :class:`InputSpec` they were prepared for (``spec``, kept by slices and
    indexing). :func:`crop_resize` passes them through unchanged for that spec, so a
    recording decoded and resized once (:mod:`qdcnn.direction.frame_cache`) serves every
    fold, seed and method that reads frames at that input, with the same pixels as the
    frames themselves would give.
    """

    spec: InputSpec | None

    def __new__(cls, images: NDArray[np.uint8], spec: InputSpec) -> PreparedFrames:
        obj = np.asarray(images).view(cls)
        obj.spec = spec
        return obj

    def __array_finalize__(self, obj: object) -> None:
        self.spec = getattr(obj, "spec", None)

    def __reduce__(self) -> tuple[Any, ...]:  # the spec travels to Dask workers too
        reduced: tuple[Any, ...] = super().__reduce__()  # type: ignore[assignment]
        rebuild, args, state = reduced[:3]
        return rebuild, args, (state, self.spec)

    def __setstate__(self, state: Any) -> None:
        base, self.spec = state
        super().__setstate__(base)


def prepare_frames(images: NDArray[np.uint8], spec: InputSpec) -> NDArray[np.uint8]:
    """The road rows of RGB frames ``(N, H, W, 3)`` resized to the network input, as
    ``(N, height, width, 3)`` uint8 (channels last): what :func:`crop_resize` feeds a network.

    Shrinking uses OpenCV's area interpolation (no aliasing of lane edges),
    enlarging bilinear. OpenCV resizes frame by frame: on two cores that is about
    five times faster than torch's batched antialiased ``interpolate``; each frame's
    result is the same whatever the frames beside it.
    """
    n, h, w = images.shape[:3]
    top, bottom = crop_rows(h, spec.crop)
    out = np.empty((n, spec.height, spec.width, 3), dtype=np.uint8)
    size = (spec.width, spec.height)
    if (bottom - top, w) == (spec.height, spec.width):
        out[:] = images[:, top:bottom]
    else:
        shrink = bottom - top >= spec.height and w >= spec.width
        interpolation = cv2.INTER_AREA if shrink else cv2.INTER_LINEAR
        for i, frame in enumerate(images[:, top:bottom]):
            cv2.resize(frame, size, dst=out[i], interpolation=interpolation)
    return out


def crop_resize(images: NDArray[np.uint8], spec: InputSpec) -> torch.Tensor:
    """Crop the road rows of RGB frames and resize them to the network input
    (:func:`prepare_frames`); :class:`PreparedFrames` of ``spec`` are taken as they are.

    Parameters
    ----------
    images : (N, H, W, 3) uint8 ndarray
        RGB frames, all the same size, or frames prepared for ``spec``.
    spec : InputSpec
        Crop and output size.

    Returns
    -------
    (N, 3, height, width) uint8 tensor
        On the CPU, channels first (a channels-last view of an NHWC array), still RGB.

    Raises
    ------
    InputError
        Frames prepared for another input than ``spec``.
    """
    if isinstance(images, PreparedFrames):
        if images.spec != spec:
            raise InputError(
                "images", f"frames prepared for {images.spec}, not for this network's {spec}"
            )
        out = np.array(images, dtype=np.uint8, order="C")  # a plain copy (of a memory map too)
    else:
        out = prepare_frames(images, spec)
    return torch.from_numpy(out).permute(0, 3, 1, 2)


def normalise(batch: torch.Tensor, spec: InputSpec) -> torch.Tensor:
    """Turn RGB pixel values in 0..255 into the network's float input.

    Parameters
    ----------
    batch : (B, 3K, H, W) tensor
        One RGB frame (K = 1) or K frames stacked along channels, each scaled alike.
    spec : InputSpec
        The colour scaling.

    Returns
    -------
    (B, 3K, H, W) float32 tensor
    """
    b, c, h, w = batch.shape
    x = batch.float().reshape(b * (c // 3), 3, h, w)
    if spec.colour == "yuv":
        yuv = torch.einsum("ij,bjhw->bihw", _RGB_TO_YUV.to(x.device), x)
        offset = torch.tensor([127.5, 0.0, 0.0], device=x.device).view(1, 3, 1, 1)
        out = (yuv - offset) / 127.5
    else:
        mean = torch.tensor(IMAGENET_MEAN, device=x.device).view(1, 3, 1, 1) * 255.0
        std = torch.tensor(IMAGENET_STD, device=x.device).view(1, 3, 1, 1) * 255.0
        out = (x - mean) / std
    return out.reshape(b, c, h, w)
