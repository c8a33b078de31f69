"""Batch preprocessing of RGB frames for the CNN baselines: crop, resize, colour, scale.

Geometry (crop and resize, :func:`crop_resize`) runs once per ``fit`` (per chunk
of frames in ``predict``) and keeps ``uint8``; colour conversion and scaling
(:func:`normalise`) run per batch on the training device, after augmentation,
so augmented pixels stay in 0..255.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn._optional import require
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
    "crop_resize",
    "crop_rows",
    "normalise",
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


def crop_resize(images: NDArray[np.uint8], spec: InputSpec) -> torch.Tensor:
    """Crop the road rows of RGB frames and resize them to the network input.

    Shrinking uses OpenCV's area interpolation (no aliasing of lane edges),
    enlarging bilinear. OpenCV resizes frame by frame: on two cores that is about
    five times faster than torch's batched antialiased ``interpolate``.

    Parameters
    ----------
    images : (N, H, W, 3) uint8 ndarray
        RGB frames, all the same size.
    spec : InputSpec
        Crop and output size.

    Returns
    -------
    (N, 3, height, width) uint8 tensor
        On the CPU, channels first (a channels-last view of an NHWC array), still RGB.
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
