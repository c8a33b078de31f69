"""Block-wise UU-dagger shadow detection (paper Sec. II-A-2, Alg. 2; NOTES 2-4).

The image is turned into a feature map (intensity or chromaticity), downsampled
by an integer factor and cut into a grid of blocks (79 x 79 by default). Each
block's mean value is compared with a shadow centroid by the one-qubit UU-dagger
circuit; blocks whose fidelity reaches the threshold are shadow. The block mask
is expanded back to the input size and median filtered.

The centroid comes from, in order of precedence: an explicit value, a trained
:class:`ShadowModel`, or per-image calibration (a two-means clustering start on the
block values refined by the propagation algorithm, which the paper allows).
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field, replace
from functools import lru_cache
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn.config import ShadowConfig
from qdcnn.errors import InputError, ParameterError
from qdcnn.quantum.centroid import propagate_centroid
from qdcnn.quantum.noise import NoiseSpec
from qdcnn.quantum.uu_dagger import angle_to_value, fidelity, value_to_angle

FEATURES = ("intensity", "chromaticity")


def feature_map(image: NDArray[np.uint8], feature: str = "intensity") -> NDArray[np.float32]:
    """Per-pixel block input in ``[0, 255]``.

    Parameters
    ----------
    image : ndarray of uint8, shape (H, W, 3) or (H, W)
        RGB image (greyscale is accepted for ``intensity``).
    feature : {"intensity", "chromaticity"}
        ``intensity`` is the luma of ITU-R BT.601 (OpenCV's greyscale).
        ``chromaticity`` is the ``c3`` invariant ``arctan(B / max(R, G))`` of
        Gevers & Smeulders (1999), scaled from ``[0, pi/2]`` to ``[0, 255]``; it
        rises in shadows lit by bluish skylight (Salvador, Cavallaro & Ebrahimi,
        "Cast shadow segmentation using invariant color features", CVIU 95, 2004).

    Returns
    -------
    ndarray of float32, shape (H, W)
    """
    if feature == "intensity":
        grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
        return grey.astype(np.float32)
    if feature == "chromaticity":
        if image.ndim != 3:
            raise ParameterError("feature", feature, "an RGB image for chromaticity")
        rgb = image.astype(np.float32)
        rg = np.maximum(rgb[..., 0], rgb[..., 1])
        c3 = np.arctan2(rgb[..., 2], rg)  # arctan(B / max(R, G)), 0 for B = 0, pi/4 for grey
        return (c3 * np.float32(255.0 / (np.pi / 2))).astype(np.float32)
    raise ParameterError("feature", feature, "'intensity' or 'chromaticity'")


def feature_input(image: NDArray[np.uint8], feature: str) -> NDArray[np.generic]:
    """:func:`feature_map`, kept as ``uint8`` greyscale for intensity (exact block sums)."""
    if feature == "intensity":
        return image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    return feature_map(image, feature)


@dataclass(frozen=True)
class BlockGrid:
    """Geometry of the block grid for one image size.

    ``row_edges``/``col_edges`` are block boundaries in downsampled pixels;
    ``row_of``/``col_of`` give the block of every full-resolution row/column.
    """

    shape: tuple[int, int]
    downsampled: tuple[int, int]
    row_edges: NDArray[np.intp]
    col_edges: NDArray[np.intp]
    row_of: NDArray[np.intp]
    col_of: NDArray[np.intp]

    @property
    def grid_shape(self) -> tuple[int, int]:
        return len(self.row_edges) - 1, len(self.col_edges) - 1


@lru_cache(maxsize=64)
def block_grid(shape: tuple[int, int], downsample: int, grid: int) -> BlockGrid:
    """Block geometry for an ``(H, W)`` image, downsampling factor and grid size.

    The downsampled image is ``(H // d, W // d)``; an axis with fewer than
    ``grid`` downsampled pixels gets one block per pixel.
    """
    h, w = shape
    hd, wd = h // downsample, w // downsample
    if hd < 1 or wd < 1:
        raise ParameterError(
            "image size",
            f"{w}x{h}",
            f"at least {downsample}x{downsample} pixels for downsample {downsample}",
        )
    gh, gw = min(grid, hd), min(grid, wd)
    row_edges = np.round(np.linspace(0, hd, gh + 1)).astype(np.intp)
    col_edges = np.round(np.linspace(0, wd, gw + 1)).astype(np.intp)
    # full-res pixel -> downsampled pixel (proportional, covers the remainder rows) -> block
    rows_ds = np.minimum(np.arange(h) * hd // h, hd - 1)
    cols_ds = np.minimum(np.arange(w) * wd // w, wd - 1)
    row_of = np.searchsorted(row_edges, rows_ds, side="right") - 1
    col_of = np.searchsorted(col_edges, cols_ds, side="right") - 1
    for arr in (row_edges, col_edges, row_of, col_of):
        arr.setflags(write=False)
    return BlockGrid((h, w), (hd, wd), row_edges, col_edges, row_of, col_of)


def block_means(
    values: NDArray[np.generic], geometry: BlockGrid, downsample: int
) -> NDArray[np.float64]:
    """Mean of each block of the ``downsample``-times area-downsampled ``values``.

    Area downsampling by an integer factor followed by block averaging is the
    mean over the block's full-resolution pixels, so it is computed exactly from
    one summed-area table (:func:`cv2.integral`) without building the small image.
    """
    table = cv2.integral(values)
    r = geometry.row_edges * downsample
    c = geometry.col_edges * downsample
    sums = table[r[1:, None], c[None, 1:]] - table[r[:-1, None], c[None, 1:]]
    sums = sums - table[r[1:, None], c[None, :-1]] + table[r[:-1, None], c[None, :-1]]
    return sums / np.outer(np.diff(r), np.diff(c))


def expand_blocks(block_mask: NDArray[np.bool_], geometry: BlockGrid) -> NDArray[np.bool_]:
    """Expand a block-level mask to the full image size."""
    rows = np.bincount(geometry.row_of, minlength=geometry.grid_shape[0])
    cols = np.bincount(geometry.col_of, minlength=geometry.grid_shape[1])
    return np.repeat(np.repeat(block_mask, rows, axis=0), cols, axis=1)


def binary_median(mask: NDArray[np.uint8], ksize: int) -> NDArray[np.uint8]:
    """Median filter of a 0/1 mask: equal to :func:`cv2.medianBlur` with replicated borders.

    For binary images the median of a ``k x k`` window is 1 exactly when more
    than half of its pixels are 1, so a box sum is enough (and for ``k >= 5``
    much faster than OpenCV's histogram median).
    """
    if ksize * ksize > 255:
        return cv2.medianBlur(mask, ksize) if ksize <= 5 else _median_large(mask, ksize)
    sums = cv2.boxFilter(mask, -1, (ksize, ksize), normalize=False, borderType=cv2.BORDER_REPLICATE)
    return (sums > (ksize * ksize) // 2).astype(np.uint8)


def _median_large(mask: NDArray[np.uint8], ksize: int) -> NDArray[np.uint8]:
    sums = cv2.boxFilter(
        mask.astype(np.float32),
        -1,
        (ksize, ksize),
        normalize=False,
        borderType=cv2.BORDER_REPLICATE,
    )
    return (sums > (ksize * ksize) // 2).astype(np.uint8)


def two_means_cluster(values: NDArray[np.float64], pick: str = "lowest") -> NDArray[np.float64]:
    """Values in the lower (or upper) cluster of the optimal 1-D two-means split.

    For one-dimensional data, Otsu's threshold maximises the between-class
    variance, which is the global optimum of two-cluster k-means (Otsu 1979;
    scikit-image's :func:`~skimage.filters.threshold_otsu` computes it), so this
    is a deterministic k-means clustering that costs microseconds per image.
    """
    from skimage.filters import threshold_otsu

    v = np.asarray(values, dtype=np.float64).ravel()
    if np.ptp(v) == 0:
        return v
    t = threshold_otsu(v, nbins=256)
    return v[v <= t] if pick == "lowest" else v[v > t]


CALIBRATION_BIN = 0.25  # value units: block means are binned this finely for calibration


def calibrate_centroid(
    block_values: NDArray[np.float64],
    feature: str = "intensity",
    config: ShadowConfig | None = None,
) -> float:
    """Per-image centroid: two-means start on the shadow side, refined by propagation.

    Shadows are the dark cluster of intensity and the high cluster of the
    chromaticity ``c3`` (bluish skylight). The propagation algorithm then starts
    at that cluster's mean and runs on its block values, binned to
    :data:`CALIBRATION_BIN` value units (a histogram keeps each iteration
    independent of the image size). Returns the centroid in value units.
    """
    cfg = config or ShadowConfig()
    cluster = two_means_cluster(block_values, "lowest" if feature == "intensity" else "highest")
    start = float(cluster.mean())
    counts = np.bincount(np.round(cluster / CALIBRATION_BIN).astype(np.intp))
    levels = np.flatnonzero(counts)
    res = propagate_centroid(
        value_to_angle(levels * CALIBRATION_BIN),
        float(value_to_angle(start)),
        iterations=cfg.propagation_iterations,
        tol=cfg.propagation_tol,
        weights=counts[levels],
    )
    return float(np.clip(angle_to_value(res.theta), 0.0, 255.0))


@dataclass
class ShadowDetection:
    """Result of :func:`detect_shadows_uu`.

    Attributes
    ----------
    mask : ndarray of bool, shape (H, W)
        Shadow pixels at input size.
    block_values, block_scores : ndarray, shape (gh, gw)
        Mean feature value and UU-dagger score of every block.
    centroid : float
        Centroid in value units ``[0, 255]``.
    threshold : float
        Score at or above which a block is shadow.
    centroid_source : str
        ``"given"``, ``"model"`` or ``"calibrated"``.
    """

    mask: NDArray[np.bool_]
    block_values: NDArray[np.float64]
    block_scores: NDArray[np.float64]
    centroid: float
    threshold: float
    feature: str
    centroid_source: str

    @property
    def shadow_fraction(self) -> float:
        return float(self.mask.mean())


@dataclass(frozen=True)
class ShadowModel:
    """A trained UU-dagger shadow centroid, saved as JSON.

    Attributes
    ----------
    feature : str
        Block input the centroid was trained on.
    centroid : float
        Centroid in value units.
    threshold : float
        Fidelity threshold.
    meta : dict
        Provenance (how and on what it was trained).
    """

    feature: str
    centroid: float
    threshold: float
    meta: dict[str, Any] = field(default_factory=dict)

    def save(self, path: str | os.PathLike[str]) -> Path:
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(json.dumps({"kind": "qdcnn-shadow-model", **asdict(self)}, indent=2))
        return p

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> ShadowModel:
        p = Path(path)
        try:
            data = json.loads(p.read_text())
        except FileNotFoundError:
            raise InputError(p, "model file not found") from None
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise InputError(p, f"not a qdcnn shadow model (unreadable JSON: {exc})") from None
        if not isinstance(data, dict) or data.get("kind") != "qdcnn-shadow-model":
            raise InputError(p, "not a qdcnn shadow model (missing kind 'qdcnn-shadow-model')")
        try:
            model = cls(
                str(data["feature"]),
                float(data["centroid"]),
                float(data["threshold"]),
                dict(data.get("meta", {})),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(p, f"shadow model is missing or has a bad field: {exc}") from None
        ShadowConfig(feature=model.feature, centroid=model.centroid, threshold=model.threshold)  # type: ignore[arg-type]
        return model


def detect_shadows_uu(
    image: NDArray[np.uint8],
    config: ShadowConfig | None = None,
    *,
    model: ShadowModel | None = None,
    backend: str = "numpy",
    noise: NoiseSpec | None = None,
    rng: int | np.random.Generator | None = None,
) -> ShadowDetection:
    """Detect shadows with the block-wise UU-dagger classifier.

    Parameters
    ----------
    image : ndarray of uint8, shape (H, W, 3)
        RGB image.
    config : ShadowConfig, optional
        Feature, downsampling, grid, threshold, shots (``None`` = exact) and median
        filter size; paper defaults.
    model : ShadowModel, optional
        Trained centroid and threshold; ``config.centroid`` overrides its centroid.
    backend : {"numpy", "aer"}
        Batched NumPy simulation or Qiskit Aer (all blocks in one run).
    noise : NoiseSpec, optional
        Quantum noise on the fidelity circuits.
    rng : int or Generator, optional
        Seed for shot sampling.

    Returns
    -------
    ShadowDetection
    """
    cfg = config or ShadowConfig()
    if model is not None:
        cfg = replace(cfg, feature=model.feature, threshold=model.threshold)  # type: ignore[arg-type]
    values = feature_input(image, cfg.feature)
    geometry = block_grid(values.shape[:2], cfg.downsample, cfg.grid)
    blocks = block_means(values, geometry, cfg.downsample)
    if cfg.centroid is not None:
        centroid, source = float(cfg.centroid), "given"
    elif model is not None:
        centroid, source = model.centroid, "model"
    else:
        centroid, source = calibrate_centroid(blocks, cfg.feature, cfg), "calibrated"
    scores = fidelity(
        value_to_angle(centroid),
        value_to_angle(blocks.ravel()),
        shots=cfg.shots,
        backend=backend,
        noise=noise,
        rng=rng,
    ).reshape(blocks.shape)
    full = expand_blocks(scores >= cfg.threshold, geometry).view(np.uint8)
    if cfg.median_ksize > 1:
        full = binary_median(full, cfg.median_ksize)
    return ShadowDetection(
        full.astype(bool), blocks, scores, centroid, cfg.threshold, cfg.feature, source
    )


def block_shadow_fraction(mask: NDArray[np.bool_], config: ShadowConfig) -> NDArray[np.float64]:
    """Fraction of shadow pixels of a ground-truth mask in each block of ``config``'s grid."""
    geometry = block_grid(mask.shape[:2], config.downsample, config.grid)
    return block_means(mask.astype(np.uint8), geometry, config.downsample)


def train_centroid(
    values: NDArray[np.float64], config: ShadowConfig | None = None, start: float | None = None
) -> float:
    """Centroid (value units) trained on shadow values by the propagation algorithm.

    Parameters
    ----------
    values : ndarray
        Feature values of shadow pixels or blocks (e.g. a shadow crop).
    config : ShadowConfig, optional
        Iterations and tolerance of the propagation algorithm.
    start : float, optional
        Initial guess in value units; the median of ``values`` by default.
    """
    cfg = config or ShadowConfig()
    res = propagate_centroid(
        value_to_angle(values),
        None if start is None else float(value_to_angle(start)),
        iterations=cfg.propagation_iterations,
        tol=cfg.propagation_tol,
    )
    return float(np.clip(angle_to_value(res.theta), 0.0, 255.0))


def train_from_crop(
    image: NDArray[np.uint8],
    box: tuple[int, int, int, int],
    config: ShadowConfig | None = None,
) -> ShadowModel:
    """Train the centroid on a crop ``(x0, y0, x1, y1)`` of a shadow region (the paper's way)."""
    cfg = config or ShadowConfig()
    x0, y0, x1, y1 = box
    h, w = image.shape[:2]
    if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
        raise ParameterError("box", box, f"x0 < x1 <= {w} and y0 < y1 <= {h} (pixels)")
    crop = feature_map(image[y0:y1, x0:x1], cfg.feature)
    centroid = train_centroid(crop.ravel().astype(np.float64), cfg)
    return ShadowModel(
        cfg.feature, centroid, cfg.threshold, {"trained_on": "crop", "box": list(box)}
    )


def train_shadow_model(
    images: list[NDArray[np.uint8]],
    masks: list[NDArray[np.bool_]],
    config: ShadowConfig | None = None,
    thresholds: tuple[float, ...] | None = None,
) -> ShadowModel:
    """Train a centroid (and optionally pick a threshold) on images with shadow masks.

    Blocks that are at least half shadow in the ground truth form the training
    set of the propagation algorithm. With ``thresholds``, the one giving the
    lowest block-level balanced error rate on the training set is kept;
    otherwise ``config.threshold``.
    """
    cfg = config or ShadowConfig()
    if len(images) != len(masks) or not images:
        raise ParameterError(
            "images/masks", f"{len(images)}/{len(masks)}", "equal, non-zero counts"
        )
    values, fractions = [], []
    for image, mask in zip(images, masks, strict=True):
        geometry = block_grid(image.shape[:2], cfg.downsample, cfg.grid)
        values.append(
            block_means(feature_input(image, cfg.feature), geometry, cfg.downsample).ravel()
        )
        fractions.append(block_shadow_fraction(mask, cfg).ravel())
    v, f = np.concatenate(values), np.concatenate(fractions)
    shadow = f >= 0.5
    if not shadow.any():
        raise ParameterError("masks", "no shadow blocks", "at least one block that is half shadow")
    centroid = train_centroid(v[shadow], cfg)
    threshold = cfg.threshold
    if thresholds:
        scores = fidelity(value_to_angle(centroid), value_to_angle(v), shots=None)
        bers = [_block_ber(scores >= t, shadow) for t in thresholds]
        threshold = float(thresholds[int(np.argmin(bers))])
    meta = {"trained_on": "images+masks", "images": len(images), "shadow_blocks": int(shadow.sum())}
    return ShadowModel(cfg.feature, centroid, threshold, meta)


def _block_ber(pred: NDArray[np.bool_], gt: NDArray[np.bool_]) -> float:
    pos, neg = gt.sum(), (~gt).sum()
    fnr = (~pred & gt).sum() / pos if pos else 0.0
    fpr = (pred & ~gt).sum() / neg if neg else 0.0
    return float(50.0 * (fnr + fpr))
