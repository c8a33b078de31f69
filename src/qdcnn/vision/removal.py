"""Shadow removal inside the road region (paper Alg. 2: "replace shadow regions
within the ROI with road pixels").

Two methods:

- ``"road-fill"`` (the paper's reading, default): every shadow pixel of the
  region becomes the road colour, the per-channel median of the lit
  (non-shadow) pixels of the region. This flattens the shadow, and with it any
  lane marking the shadow covers.
- ``"relight"``: every shadow pixel of the region is scaled per channel by the
  ratio of the lit to the shadow colour of the region, the constant-ratio
  illumination model used to relight shadow regions from lit regions of the
  same material [1]_. The ratio is taken between per-channel medians, a robust
  form of the mean ratio of [1]_, so that lane markings (a minority of the
  pixels, not always equally shared between lit and shadow parts) do not bias
  it. Texture and lane markings under the shadow survive.

Only shadow pixels inside the region change; every other pixel is returned
exactly as given. When the region has no lit pixel (nothing to take the road
colour from) or no shadow pixel, the image is returned unchanged (a copy).

References
----------
.. [1] R. Guo, Q. Dai, D. Hoiem, "Paired regions for shadow detection and
   removal", IEEE Trans. Pattern Analysis and Machine Intelligence
   35(12):2956-2967, 2013 (first as "Single-image shadow detection and removal
   using paired regions", Proc. IEEE CVPR, 2011).
"""

from __future__ import annotations

from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn._validation import has_shape
from qdcnn.errors import InputError, ParameterError
from qdcnn.vision.compiled import compiled
from qdcnn.vision.metrics import as_shadow_mask

__all__ = ["REMOVAL_METHODS", "remove_shadows"]

REMOVAL_METHODS = ("road-fill", "relight")


def remove_shadows(
    image: NDArray[np.uint8],
    shadow_mask: NDArray[Any],
    region_mask: NDArray[Any] | None = None,
    *,
    method: Literal["road-fill", "relight"] = "road-fill",
) -> NDArray[np.uint8]:
    """Replace the shadow pixels of a region with road values taken from its lit pixels.

    Parameters
    ----------
    image : ndarray of uint8, shape (H, W, 3) or (H, W)
        RGB or greyscale image.
    shadow_mask : ndarray of bool or uint8, shape (H, W)
        Detected shadow (``uint8`` masks are binarised at 128).
    region_mask : ndarray of bool or uint8, shape (H, W), optional
        The road region of interest; the whole image when ``None``.
    method : {"road-fill", "relight"}
        ``"road-fill"``: set shadow pixels to the per-channel median of the lit
        region pixels. ``"relight"``: multiply shadow pixels per channel by
        ``median(lit) / median(shadow)`` (the shadow median floored at one grey
        level so a black shadow does not divide by zero), rounded and clipped
        to [0, 255].

    Returns
    -------
    ndarray of uint8, same shape as ``image``
        A new image; only pixels in both ``shadow_mask`` and ``region_mask`` differ.

    Raises
    ------
    InputError
        Image not ``uint8`` (H, W, 3) or (H, W), or a mask of another shape.
    ParameterError
        Unknown ``method``.
    """
    if method not in REMOVAL_METHODS:
        raise ParameterError("method", method, "'road-fill' or 'relight'")
    img = np.asarray(image)
    if img.dtype != np.uint8 or not has_shape(img, "H,W|H,W,3"):
        raise InputError(
            "image", f"expected uint8 of shape (H, W, 3) or (H, W), got {img.dtype} {img.shape}"
        )
    shadow = as_shadow_mask(shadow_mask, source="shadow_mask")
    region = (
        np.ones(img.shape[:2], dtype=bool)
        if region_mask is None
        else as_shadow_mask(region_mask, source="region_mask")
    )
    for name, mask in (("shadow_mask", shadow), ("region_mask", region)):
        if mask.shape != img.shape[:2]:
            raise InputError(
                name, f"mask shape {mask.shape} differs from image shape {img.shape[:2]}"
            )

    out = img.copy()
    # only the region's rows can change: the masks and counts work on that band alone
    # (a band of whole rows is contiguous, so OpenCV writes through to ``out``)
    _, y, _, h = cv2.boundingRect(region.view(np.uint8))
    if h == 0:  # an empty region: nothing to fill
        return out
    band = slice(y, y + h)
    pixels = img[band].reshape(h, img.shape[1], -1)
    target = np.empty((h, img.shape[1]), dtype=bool)
    lit_median = lit_medians(pixels, region[band], shadow[band], target)
    if lit_median is None:
        return out
    view = out[band].reshape(pixels.shape)  # writes through to ``out``
    if method == "road-fill":
        # A masked copy from a flat image is ~20x faster than boolean-index assignment
        value = np.rint(lit_median).astype(np.uint8)
        fill = np.tile(value, (h, img.shape[1])).reshape(view.shape)
        cv2.copyTo(fill, target.view(np.uint8), view)
    else:
        shadow_values = pixels[target]
        gain = lit_median / np.maximum(masked_channel_medians(pixels, target), 1.0)
        view[target] = np.clip(np.rint(shadow_values * gain), 0, 255).astype(np.uint8)
    return out


def lit_medians(
    pixels: NDArray[np.uint8],
    region: NDArray[np.bool_],
    shadow: NDArray[np.bool_],
    target: NDArray[np.bool_],
) -> NDArray[np.float64] | None:
    """Per-channel median of the lit pixels (in ``region``, not in ``shadow``) of
    ``pixels`` ``(H, W, C)``; ``target`` (bool, ``(H, W)``) receives the region's shadow
    pixels. None when the region has no shadow pixel or no lit one (nothing to fill, or
    nothing to fill it with). Compiled
    (:func:`~qdcnn.vision.removal_kernels.lit_levels`) unless ``QDCNN_KERNELS=numpy``."""
    kernels = compiled("removal_kernels")
    if kernels is not None:
        counts, shaded = kernels.lit_levels(pixels, region, shadow, target)
        return _medians_from_counts(counts) if shaded and counts[0].any() else None
    np.logical_and(shadow, region, out=target)
    lit = np.greater(region, shadow)  # in the region and not shadow
    if not target.any() or not lit.any():
        return None
    return masked_channel_medians(pixels, lit)


def fill_where(values: NDArray[np.uint8], where: NDArray[np.bool_], value: np.uint8) -> None:
    """``values[where] = value`` in place, for a 2-D ``uint8`` array and a bool mask of its
    shape: compiled (:func:`~qdcnn.vision.removal_kernels.fill_where`, which reads the
    mask unchecked) unless ``QDCNN_KERNELS=numpy``."""
    if values.dtype != np.uint8 or values.ndim != 2:
        raise InputError("values", f"expected 2-D uint8, got {values.dtype} {values.shape}")
    if where.dtype != np.bool_ or where.shape != values.shape:
        raise InputError("where", f"expected bool {values.shape}, got {where.dtype} {where.shape}")
    if not 0 <= int(value) <= 255:
        raise ParameterError("value", value, "a grey level in [0, 255]")
    kernels = compiled("removal_kernels")
    if kernels is not None:
        kernels.fill_where(values, where, value)
    else:
        np.copyto(values, value, where=where)


def _medians_from_counts(counts: NDArray[np.intp]) -> NDArray[np.float64]:
    """Medians of ``C`` histograms of 256 levels, shape ``(C, 256)``, as :func:`numpy.median`."""
    n = int(counts[0].sum())
    cum = counts.cumsum(axis=1)
    lo = (cum <= (n - 1) // 2).sum(axis=1)  # level of order statistic (n - 1) // 2
    hi = (cum <= n // 2).sum(axis=1)  # level of order statistic n // 2
    return (lo + hi) / 2.0


def channel_medians(values: NDArray[np.uint8]) -> NDArray[np.float64]:
    """Per-column median of ``uint8`` values ``(N, C)``, equal to :func:`numpy.median`.

    Counting the 256 levels of each channel and reading the middle order
    statistics off the cumulative counts is exact and much faster than sorting.
    """
    c = values.shape[1]
    counts = np.bincount((values + np.arange(c, dtype=np.intp) * 256).ravel(), minlength=256 * c)
    return _medians_from_counts(counts.reshape(c, 256))


def masked_channel_medians(
    pixels: NDArray[np.uint8], mask: NDArray[np.bool_]
) -> NDArray[np.float64]:
    """Per-channel median of ``pixels`` ``(H, W, C)`` where ``mask``, without gathering them.

    OpenCV's masked histogram counts the levels in place; the result equals
    :func:`channel_medians` of ``pixels[mask]``.
    """
    m = mask.view(np.uint8)
    counts = np.stack(
        [cv2.calcHist([pixels], [c], m, [256], [0, 256]).ravel() for c in range(pixels.shape[2])]
    ).astype(np.intp)
    return _medians_from_counts(counts)
