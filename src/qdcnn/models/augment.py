"""Seeded training-time augmentation of direction-labelled frames, batched in torch.

Three label-aware transforms common in behavioural-cloning work on the Udacity
simulator (Bojarski et al. 2016 augment with shifts and rotations; flips,
brightness and shadows are the usual additions for this simulator):

- horizontal flip, which mirrors the road, so left and right labels swap;
- brightness scaling of the whole frame (scaling RGB scales HSV value, keeping hue);
- a synthetic shadow: a random quadrilateral spanning the frame top to bottom is
  darkened, mimicking tree and pole shadows across the road;
- optionally, a small horizontal shift (edge columns repeated), the lateral offset
  jitter of Bojarski et al.; labels are kept, so shifts should stay well below the
  offset that would change the direction class;
- optionally, colour randomisation (:func:`randomise_colour`): the colour channels
  permuted, the contrast scaled and some frames made grey, so a network cannot decide by
  the colours of one recording's road and markings (a yellow centre line, red kerbs) and
  has to use their shapes, which other roads share (the domain randomisation of Tobin et
  al. 2017).
"""

from __future__ import annotations

from itertools import permutations

from qdcnn._optional import require
from qdcnn.data.labels import LEFT, RIGHT

require("torch", "CNN training augmentation")
import torch  # noqa: E402

_FLIP_PROBABILITY = 0.5
_BRIGHTNESS_RANGE = (0.5, 1.3)
_SHADOW_PROBABILITY = 0.5
SHADOW_DARKNESS = (0.4, 0.8)  # factor multiplying pixels under the shadow
_PERMUTE_PROBABILITY = 0.5
_CONTRAST_RANGE = (0.6, 1.4)
_GREY_PROBABILITY = 0.2
_GREY_WEIGHTS = (0.299, 0.587, 0.114)  # ITU-R BT.601 luma, as OpenCV's RGB2GRAY


def _uniform(n: int, lo: float, hi: float, generator: torch.Generator) -> torch.Tensor:
    return lo + (hi - lo) * torch.rand(n, generator=generator)


def shadow_masks(n: int, height: int, width: int, generator: torch.Generator) -> torch.Tensor:
    """Random quadrilateral masks ``(n, height, width)`` bool, one per frame.

    Each quadrilateral joins a random span of the top row to a random span of
    the bottom row, so it crosses the road the way a roadside shadow does.
    """
    ends = torch.rand((n, 4), generator=generator) * width
    top = torch.sort(ends[:, :2], dim=1).values
    bottom = torch.sort(ends[:, 2:], dim=1).values
    t = torch.linspace(0.0, 1.0, height).view(1, height, 1)
    left = top[:, 0].view(n, 1, 1) + (bottom[:, 0] - top[:, 0]).view(n, 1, 1) * t
    right = top[:, 1].view(n, 1, 1) + (bottom[:, 1] - top[:, 1]).view(n, 1, 1) * t
    x = (torch.arange(width, dtype=torch.float32) + 0.5).view(1, 1, width)
    return (x >= left) & (x <= right)


def shift_columns(images: torch.Tensor, shifts: torch.Tensor) -> torch.Tensor:
    """Move each frame ``shifts[i]`` pixels right (negative: left), repeating the edge column.

    Parameters
    ----------
    images : (B, C, H, W) tensor
    shifts : (B,) int64 tensor

    Returns
    -------
    (B, C, H, W) tensor
        ``out[i, ..., x] = images[i, ..., clip(x - shifts[i], 0, W - 1)]``.
    """
    n, c, h, w = images.shape
    cols = torch.arange(w, device=images.device).view(1, w) - shifts.to(images.device).view(n, 1)
    index = cols.clamp_(0, w - 1).view(n, 1, 1, w).expand(n, c, h, w)
    return torch.gather(images, 3, index)


def randomise_colour(images: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
    """Random colour changes that keep every frame's shapes.

    Per frame: with probability 1/2 its RGB channels are put in a random order (one of
    the six, the identity included), its contrast is scaled about its mean by a factor
    in [0.6, 1.4], and with probability 0.2 it becomes grey (BT.601 luma in all three
    channels). The ``K`` stacked frames of a sample (``3K`` channels) get the same draws,
    each as if alone.

    Parameters
    ----------
    images : (B, 3K, H, W) float tensor
        RGB pixel values in 0..255.
    generator : torch.Generator
        CPU generator all random choices are drawn from.

    Returns
    -------
    (B, 3K, H, W) float32 tensor
        Not clipped (the caller clips).
    """
    n, c, h, w = images.shape
    x = images.float().reshape(n, c // 3, 3, h, w)
    orders = torch.tensor(list(permutations(range(3))))
    pick = torch.randint(0, len(orders), (n,), generator=generator)
    permuted = torch.rand(n, generator=generator) < _PERMUTE_PROBABILITY
    contrast = _uniform(n, *_CONTRAST_RANGE, generator).to(x.device).view(n, 1, 1, 1, 1)
    grey = (torch.rand(n, generator=generator) < _GREY_PROBABILITY).to(x.device)
    # grey first, from the frame's own RGB: a grey frame is the same in any channel order
    weights = torch.tensor(_GREY_WEIGHTS, device=x.device).view(1, 1, 3, 1, 1)
    luma = (x * weights).sum(2, keepdim=True)
    x = torch.where(grey.view(n, 1, 1, 1, 1), luma.expand_as(x), x)
    order = torch.where(permuted.view(n, 1), orders[pick], orders[0]).to(x.device)
    x = torch.gather(x, 2, order.view(n, 1, 3, 1, 1).expand_as(x))
    mean = x.mean(dim=(2, 3, 4), keepdim=True)
    return (mean + (x - mean) * contrast).reshape(n, c, h, w)


def augment_batch(
    images: torch.Tensor,
    labels: torch.Tensor,
    generator: torch.Generator,
    *,
    max_shift: float = 0.0,
    colour: bool = False,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Augment a batch of frames and their direction labels.

    Parameters
    ----------
    images : (B, 3K, H, W) tensor
        RGB pixel values in 0..255 (any dtype; any device), ``K`` stacked frames.
    labels : (B,) int64 tensor
        0 = left, 1 = straight, 2 = right.
    generator : torch.Generator
        CPU generator all random choices are drawn from (seeded by the caller).
    max_shift : float
        Largest horizontal shift as a fraction of the width (0: no shift, and no
        random numbers drawn for it).
    colour : bool
        Also :func:`randomise_colour` (no random numbers drawn for it when off, so the
        other transforms are as before).

    Returns
    -------
    images : (B, 3K, H, W) float32 tensor
        Augmented pixels, clipped to [0, 255], on the input's device.
    labels : (B,) int64 tensor
        Labels with left and right swapped where the frame was flipped.
    """
    n, _, h, w = images.shape
    device = images.device
    x = images.float()
    flip = (torch.rand(n, generator=generator) < _FLIP_PROBABILITY).to(device)
    x = torch.where(flip.view(n, 1, 1, 1), x.flip(-1), x)
    swapped = torch.where(labels == LEFT, RIGHT, torch.where(labels == RIGHT, LEFT, labels))
    labels = torch.where(flip, swapped, labels)

    brightness = _uniform(n, *_BRIGHTNESS_RANGE, generator).to(device)
    x = x * brightness.view(n, 1, 1, 1)

    shaded = torch.rand(n, generator=generator) < _SHADOW_PROBABILITY
    darkness = _uniform(n, *SHADOW_DARKNESS, generator)
    masks = shadow_masks(n, h, w, generator) & shaded.view(n, 1, 1)
    factor = torch.where(masks, darkness.view(n, 1, 1), torch.ones(()))
    x = x * factor.to(device).unsqueeze(1)
    if max_shift > 0:
        shifts = torch.round(_uniform(n, -max_shift, max_shift, generator) * w).long()
        x = shift_columns(x, shifts)
    if colour:
        x = randomise_colour(x, generator)
    return x.clamp_(0.0, 255.0), labels
