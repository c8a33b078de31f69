"""Lane-mark evidence: white and yellow road markings selected by colour (not the paper's).

The paper finds lane lines with Canny on the grey frame (Sec. III-A), which on a real road
also outlines trees, kerbs, cars and shadow edges. Markings differ from all of these in two
ways that survive changes of light: they are *narrow* bright stripes on the road (brighter
than the asphalt beside them), and they are white or yellow. :func:`marking_mask` keeps the
pixels that are both:

- narrow and bright: a horizontal morphological top-hat (the image minus its opening with a
  ``1 x k`` window, ``k = marks_width`` of the width) of the lightness exceeds
  ``marks_contrast`` times the opening (the road beside the stripe), and 4 grey levels.
  Structures wider than ``k`` (sky, walls, bright road) are removed by the opening, and the
  test is a ratio to the road beside the stripe, not a fixed brightness, so a marking at
  dusk or in a tree's shadow passes as one in the sun does.
- white or yellow: white is such a lightness stripe of low chroma (Lab: ``a`` and ``b``
  within 24 of neutral; HLS: saturation below 40 %). Yellow paint is not much lighter than
  asphalt, so a yellow marking is a stripe in the colour channel instead: ``"lab"``: ``b``
  (blue to yellow) above its opening by 10 levels, above neutral by at least 8 and by at
  least four times ``|a - 128|`` (hue between about 76 and 104 degrees: orange and red
  fences, brake lights and brown soil are out); ``"hls"``: saturation above its opening by
  40 levels, with a hue in [18, 38] on OpenCV's 0-180 scale (36 to 76 degrees).

References
----------
.. [1] P. Soille, "Morphological Image Analysis", 2nd ed., Springer 2003, Sec. 4.4 (top-hat).
.. [2] M. Aly, "Real time detection of lane markers in urban streets", IEEE IV 2008.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn._validation import check_input_shape
from qdcnn.config import LaneConfig
from qdcnn.errors import InputError, ParameterError

#: OpenCV hue range (0-180 scale) counted as yellow by the "hls" selection
_YELLOW_HUE = (18, 38)
#: least brightness step (grey levels) of a marking, whatever the ratio
_MIN_STEP = 4
#: least step of a yellow marking above the road beside it: Lab b, HLS saturation
_YELLOW_STEP_B, _YELLOW_STEP_S = 10, 40
#: Lab: a white marking's a and b stay within this of neutral (128)
_WHITE_CHROMA = 24


@lru_cache(maxsize=16)
def _window(width: int, fraction: float) -> NDArray[np.uint8]:
    k = max(3, round(fraction * width) | 1)
    return np.ones((1, k), np.uint8)


def _stripes(
    channel: NDArray[np.uint8], window: NDArray[np.uint8], ratio: float, step: int = _MIN_STEP
) -> NDArray[np.uint8]:
    """255 where above the opening (the background beside a narrow stripe) by ``ratio``.

    ``channel > (1 + ratio) * background`` and ``channel >= background + step``, with
    OpenCV's saturating uint8 arithmetic (a background above ``255 / (1 + ratio)`` leaves
    no room for a brighter stripe and gives none).
    """
    background = cv2.morphologyEx(channel, cv2.MORPH_OPEN, window)
    limit = cv2.add(background, step - 1)
    if ratio > 0:
        limit = cv2.max(cv2.convertScaleAbs(background, alpha=1.0 + ratio), limit)
    return np.asarray(cv2.compare(channel, limit, cv2.CMP_GT), dtype=np.uint8)


def marking_mask(
    image: NDArray[np.uint8], config: LaneConfig, width: int | None = None
) -> NDArray[np.bool_]:
    """White and yellow marking pixels of an RGB frame (module docstring).

    Parameters
    ----------
    image : (H, W, 3) or (H, W) uint8 array
        RGB frame (or a window of one); a grey frame gets the white test only.
    config : LaneConfig
        ``marks`` ("hls" or "lab"), ``marks_contrast`` and ``marks_width``.
    width : int, optional
        Width the top-hat window is relative to (the whole frame's when ``image`` is a
        window of it); the image's own width by default.

    Returns
    -------
    (H, W) bool array

    Examples
    --------
    >>> import numpy as np
    >>> img = np.full((20, 60, 3), 90, np.uint8)
    >>> img[:, 30:32] = 220  # a white stripe 2 px wide
    >>> m = marking_mask(img, LaneConfig(marks="lab"))
    >>> sorted(set(np.nonzero(m)[1].tolist()))
    [30, 31]
    """
    if config.marks not in ("hls", "lab"):
        raise ParameterError("lanes.marks", config.marks, "'hls' or 'lab' to select markings")
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8:
        kind = getattr(image, "dtype", type(image).__name__)
        raise InputError("image", f"expected a uint8 array, got {kind}")
    check_input_shape("image", image, "H,W,3|H,W")
    return marking_mask_u8(image, config, width) > 0


def marking_mask_u8(
    image: NDArray[np.uint8], config: LaneConfig, width: int | None = None
) -> NDArray[np.uint8]:
    """:func:`marking_mask` as uint8 (255 on a marking, 0 elsewhere), without checks."""
    window = _window(int(width or image.shape[1]), config.marks_width)
    ratio = config.marks_contrast
    if image.ndim == 2:
        return _stripes(image, window, ratio)
    if config.marks == "hls":
        hue, light, sat = cv2.split(cv2.cvtColor(image, cv2.COLOR_RGB2HLS))
        white = _stripes(light, window, ratio) & cv2.compare(sat, 102, cv2.CMP_LT)
        yellow = cv2.inRange(hue, _YELLOW_HUE[0], _YELLOW_HUE[1]) & _stripes(
            sat, window, 0.0, _YELLOW_STEP_S
        )
    else:
        light, a, b = cv2.split(cv2.cvtColor(image, cv2.COLOR_RGB2LAB))
        lo, hi = 128 - _WHITE_CHROMA, 128 + _WHITE_CHROMA
        white = _stripes(light, window, ratio) & cv2.inRange(a, lo, hi) & cv2.inRange(b, lo, hi)
        # yellow hue: b - 128 >= 8 and b - 128 >= 4 |a - 128|
        off_a = cv2.absdiff(a, np.full_like(a, 128))
        above = cv2.subtract(b, np.full_like(b, 128))
        hue = cv2.compare(above, 8, cv2.CMP_GE) & cv2.compare(
            above, cv2.convertScaleAbs(off_a, alpha=4.0), cv2.CMP_GE
        )
        yellow = hue & _stripes(b, window, 0.0, _YELLOW_STEP_B)
    return np.asarray(white | yellow, dtype=np.uint8)
