"""Classical single-image shadow detectors the paper compares QDCNN against.

The paper's shadow-detection timing table names intensity-based thresholding (IBT),
chromaticity-based shadow detection (CBS) and local binary patterns (LBP)
without saying which variants it ran (NOTES 4). Each detector here follows a
standard published single-image form, cited in its docstring:

- :func:`detect_ibt`: a global threshold on greyscale intensity, chosen by
  Otsu's method unless fixed.
- :func:`detect_cbs`: Tsai's hue/intensity ratio map in the HSI colour model,
  thresholded by Otsu's method.
- :func:`detect_lbp`: dense local LBP-histogram texture plus local intensity,
  clustered into two classes by k-means; the darker class is shadow.

All take an RGB ``uint8`` image ``(H, W, 3)`` or a greyscale one ``(H, W)``
and return a ``bool`` shadow mask of shape ``(H, W)``. An image with no
contrast in the quantity a detector thresholds (for example a constant image)
has no second class to find: the detectors return an all-``False`` mask for it.
Like any two-class split of one image, the automatic (Otsu, k-means) variants
always mark one class as shadow (the darker one; for CBS the higher-ratio one),
also on images with no shadow at all.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray
from skimage.feature import local_binary_pattern
from skimage.filters import threshold_otsu
from sklearn.cluster import KMeans

from qdcnn._threads import single_thread
from qdcnn._validation import check_input_shape
from qdcnn.errors import InputError, ParameterError

__all__ = ["detect_cbs", "detect_ibt", "detect_lbp", "hsi_hue_intensity", "to_grey"]


def _check_image(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    arr = np.asarray(image)
    if arr.dtype != np.uint8:
        raise InputError("image", f"expected uint8 pixels, got {arr.dtype}")
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    check_input_shape("image", arr, "H,W,3|H,W")
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise InputError("image", f"image is empty, shape {arr.shape}")
    return arr


def to_grey(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """Greyscale ``uint8`` version of an RGB or greyscale image (ITU-R BT.601 luma, as OpenCV)."""
    arr = _check_image(image)
    if arr.ndim == 2:
        return arr
    return np.asarray(cv2.cvtColor(np.ascontiguousarray(arr), cv2.COLOR_RGB2GRAY), dtype=np.uint8)


def detect_ibt(image: NDArray[np.uint8], *, threshold: int | None = None) -> NDArray[np.bool_]:
    """Intensity-based thresholding (IBT): dark pixels are shadow.

    The image is converted to greyscale and every pixel whose intensity is at
    or below one global threshold is shadow. By default the threshold is chosen
    from the grey-level histogram by Otsu's method [1]_ (maximum between-class
    variance), the usual automatic form of intensity thresholding for shadows.

    Parameters
    ----------
    image : ndarray of uint8, shape (H, W, 3) or (H, W)
        RGB or greyscale image.
    threshold : int or None
        Fixed grey level in [0, 255]; pixels ``<= threshold`` are shadow.
        ``None`` (default) uses Otsu's threshold for this image.

    Returns
    -------
    ndarray of bool, shape (H, W)
        Shadow mask. With Otsu's threshold a constant image gives all ``False``;
        with a fixed threshold it is all ``True`` or all ``False``.

    References
    ----------
    .. [1] N. Otsu, "A threshold selection method from gray-level histograms",
       IEEE Trans. Systems, Man, and Cybernetics 9(1):62-66, 1979.
    """
    if threshold is not None and (
        isinstance(threshold, bool)
        or not isinstance(threshold, (int, np.integer))
        or not 0 <= threshold <= 255
    ):
        raise ParameterError("threshold", threshold, "None or an integer grey level in [0, 255]")
    grey = to_grey(image)
    if threshold is None:
        if grey.min() == grey.max():
            return np.zeros(grey.shape, dtype=bool)
        level, _ = cv2.threshold(grey, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
        threshold = int(level)
    return np.asarray(grey <= threshold)


def hsi_hue_intensity(image: NDArray[np.uint8]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Hue (degrees in [0, 360)) and intensity ((R + G + B) / 3 in [0, 255]) of the HSI model.

    The hue is the angle of the pixel in the chromaticity plane,
    ``atan2(sqrt(3) (G - B), 2R - G - B)``, which equals the usual
    ``arccos`` form of the HSI hue (Gonzalez & Woods) but needs no division:
    red is 0, green 120, blue 240 degrees. Grey pixels (R = G = B) get hue 0.
    A greyscale image is treated as R = G = B.
    """
    arr = _check_image(image)
    if arr.ndim == 2:
        arr = np.repeat(arr[:, :, None], 3, axis=2)
    rgb = arr.astype(np.float64)
    r, g, b = rgb[:, :, 0], rgb[:, :, 1], rgb[:, :, 2]
    hue = np.degrees(np.arctan2(np.sqrt(3.0) * (g - b), 2.0 * r - g - b)) % 360.0
    intensity = (r + g + b) / 3.0
    return hue, intensity


def detect_cbs(image: NDArray[np.uint8], *, equalize: bool = True) -> NDArray[np.bool_]:
    """Chromaticity-based shadow detection (CBS) with Tsai's hue/intensity ratio map.

    Shadows in outdoor colour images are darker and, lit only by the bluish
    skylight, shifted towards higher hue than their lit surroundings. Tsai [1]_
    combines the two in the ratio map ``r = (H_e + 1) / (I_e + 1)`` of the hue
    and intensity of the HSI model, each histogram-equalised and scaled to
    [0, 1], and thresholds it with Otsu's method [2]_: pixels with ``r``
    above the threshold are shadow. This is Tsai's HSI variant (the paper also
    evaluates HSV, HCV, YIQ and YCbCr), without the later region refinement.

    Parameters
    ----------
    image : ndarray of uint8, shape (H, W, 3) or (H, W)
        RGB image. A greyscale image has hue 0 everywhere, so the ratio map
        reduces to an inverse-intensity map.
    equalize : bool
        Histogram-equalise hue and intensity before the ratio, as in [1]_
        (default); ``False`` uses them as scaled.

    Returns
    -------
    ndarray of bool, shape (H, W)
        Shadow mask; all ``False`` when the ratio map is constant.

    Notes
    -----
    Hue is circular, so red and magenta surfaces (hue near 360 degrees) also
    get a high ratio; this is a known weakness of the method, kept as
    published. It shows on Udacity simulator frames, whose lit asphalt is a
    magenta-tinted grey (hue about 280-330 degrees) above the blue of shadowed
    asphalt (about 230 degrees): there the ratio separates them poorly.

    References
    ----------
    .. [1] V. J. D. Tsai, "A comparative study on shadow compensation of color
       aerial images in invariant color models", IEEE Trans. Geoscience and
       Remote Sensing 44(6):1661-1671, 2006.
    .. [2] N. Otsu, "A threshold selection method from gray-level histograms",
       IEEE Trans. Systems, Man, and Cybernetics 9(1):62-66, 1979.
    """
    hue, intensity = hsi_hue_intensity(image)
    hue8 = np.minimum(hue * (256.0 / 360.0), 255.0).astype(np.uint8)
    int8 = np.clip(np.rint(intensity), 0, 255).astype(np.uint8)
    if equalize:
        hue8 = np.asarray(cv2.equalizeHist(hue8), dtype=np.uint8)
        int8 = np.asarray(cv2.equalizeHist(int8), dtype=np.uint8)
    # Both components in [0, 1], so the +1 bounds the ratio to [0.5, 2] rather
    # than only guarding the division (as in common re-implementations of [1]).
    ratio = (hue8 / 255.0 + 1.0) / (int8 / 255.0 + 1.0)
    if ratio.min() == ratio.max():
        return np.zeros(ratio.shape, dtype=bool)
    return np.asarray(ratio > threshold_otsu(ratio))


def _local_lbp_features(
    grey: NDArray[np.uint8], points: int, radius: float, window: int
) -> NDArray[np.float32]:
    """Per-pixel features: local mean intensity in [0, 1], then the local uniform-LBP histogram."""
    codes = local_binary_pattern(grey, points, radius, method="uniform").astype(np.intp)
    n_bins = points + 2  # P + 1 rotation-invariant uniform patterns and one "non-uniform" bin
    onehot = np.zeros((*grey.shape, n_bins + 1), dtype=np.float32)
    onehot[:, :, 0] = grey.astype(np.float32) / 255.0
    np.put_along_axis(onehot, codes[:, :, None] + 1, 1.0, axis=2)
    # A normalised box filter turns the one-hot codes into each pixel's local
    # histogram and the grey channel into its local mean, in one pass.
    local = cv2.boxFilter(onehot, -1, (window, window), borderType=cv2.BORDER_REFLECT)
    return np.asarray(local, dtype=np.float32).reshape(onehot.shape)


def detect_lbp(
    image: NDArray[np.uint8],
    *,
    points: int = 8,
    radius: float = 1.0,
    window: int = 9,
    texture_weight: float = 0.5,
    max_samples: int = 20_000,
    seed: int = 0,
) -> NDArray[np.bool_]:
    """Texture-based shadow detection with local binary patterns (LBP).

    Texture-based shadow detectors rest on the observation that a cast shadow
    darkens a surface but keeps its texture, which gray-scale-invariant
    texture descriptors such as LBP [1]_ capture (see the survey [2]_; a
    single-image learned detector using texture cues is [3]_). This detector is
    the unsupervised single-image form of that idea: every pixel is described
    by the uniform rotation-invariant LBP histogram (``P + 2`` bins) of the
    ``window x window`` patch around it, together with the patch's mean
    intensity; k-means (two clusters, fitted on a random subsample of pixels)
    splits the pixels into two classes, and the class with the darker centre
    is shadow. The paper names LBP without details (NOTES 4); this is the
    form suggested for the project, chosen for being single-image and
    unsupervised like the other baselines.

    In practice the split is driven by local intensity with texture as a
    secondary term: on synthetic road scenes, dark non-shadow patches (smooth
    or striped) still fall into the shadow class, and on Udacity frames the
    mask is close to a smoothed intensity threshold at the default weight.

    Parameters
    ----------
    image : ndarray of uint8, shape (H, W, 3) or (H, W)
        RGB or greyscale image (converted to greyscale).
    points : int
        Number of LBP neighbours ``P`` (default 8), in [4, 24].
    radius : float
        LBP radius ``R`` in pixels (default 1), in (0, 16].
    window : int
        Odd side of the patch for local histograms and means (default 9), in [3, 255].
    texture_weight : float
        Weight of the LBP histogram relative to the mean intensity (in [0, 1])
        in the k-means distance (default 0.5); 0 clusters on local intensity
        only. On Udacity simulator frames, weights of about 0.7 and above let
        texture dominate (rock walls against road) rather than illumination.
    max_samples : int
        Pixels drawn to fit k-means (all pixels are then assigned), >= 100.
    seed : int
        Seed of the pixel subsample and the k-means initialisation.

    Returns
    -------
    ndarray of bool, shape (H, W)
        Shadow mask; all ``False`` for an image with no intensity contrast.

    References
    ----------
    .. [1] T. Ojala, M. Pietikainen, T. Maenpaa, "Multiresolution gray-scale and
       rotation invariant texture classification with local binary patterns",
       IEEE Trans. Pattern Analysis and Machine Intelligence 24(7):971-987, 2002.
    .. [2] A. Sanin, C. Sanderson, B. C. Lovell, "Shadow detection: a survey and
       comparative evaluation of recent methods", Pattern Recognition
       45(4):1684-1695, 2012.
    .. [3] J. Zhu, K. G. G. Samuel, S. Z. Masood, M. F. Tappen, "Learning to
       recognize shadows in monochromatic natural images", Proc. IEEE CVPR,
       pp. 223-230, 2010.
    """
    _check_lbp_arguments(points, radius, window, texture_weight, max_samples)
    grey = to_grey(image)
    if grey.min() == grey.max():
        return np.zeros(grey.shape, dtype=bool)

    features = _local_lbp_features(grey, int(points), float(radius), int(window))
    features[:, :, 1:] *= texture_weight
    shadow = _darker_class(features.reshape(-1, features.shape[2]), max_samples, seed)
    if shadow is None:
        return np.zeros(grey.shape, dtype=bool)
    return shadow.reshape(grey.shape)


def _check_lbp_arguments(
    points: int, radius: float, window: int, texture_weight: float, max_samples: int
) -> None:
    if not isinstance(points, (int, np.integer)) or not 4 <= points <= 24:
        raise ParameterError("points", points, "an integer in [4, 24]")
    if not 0 < radius <= 16:
        raise ParameterError("radius", radius, "a number in (0, 16]")
    if not isinstance(window, (int, np.integer)) or window % 2 == 0 or not 3 <= window <= 255:
        raise ParameterError("window", window, "an odd integer in [3, 255]")
    if not 0 <= texture_weight <= 100:
        raise ParameterError("texture_weight", texture_weight, "a number in [0, 100]")
    if not isinstance(max_samples, (int, np.integer)) or max_samples < 100:
        raise ParameterError("max_samples", max_samples, "an integer >= 100")


def _darker_class(
    flat: NDArray[np.float32], max_samples: int, seed: int
) -> NDArray[np.bool_] | None:
    """Pixels (rows of ``flat``) in the darker of two k-means classes, fitted on at most
    ``max_samples`` of them; None when the sample holds fewer than two distinct rows."""
    rng = np.random.default_rng(seed)
    fit = flat if len(flat) <= max_samples else flat[rng.choice(len(flat), max_samples, False)]
    if len(np.unique(fit, axis=0)) < 2:
        return None
    # One OpenMP thread: the problem is small, and scikit-learn's threaded
    # k-means slows down by orders of magnitude when the cores are busy.
    with single_thread():
        kmeans = KMeans(n_clusters=2, n_init=3, random_state=seed).fit(fit)
        labels = kmeans.predict(flat)
    shadow_cluster = int(np.argmin(kmeans.cluster_centers_[:, 0]))
    return np.asarray(labels == shadow_cluster)
