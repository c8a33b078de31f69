"""Block-wise UU-dagger shadow detection (paper Sec. II-A-2, Alg. 2; NOTES 2-4).

The image is turned into a feature map (intensity or chromaticity), downsampled
by an integer factor and cut into a grid of blocks (79 x 79 by default). Each
block's mean value is compared with a shadow centroid by the one-qubit UU-dagger
circuit; blocks whose fidelity reaches the threshold are shadow. The block mask
is expanded back to the input size and median filtered.

The centroid comes from, in order of precedence: an explicit value, a trained
:class:`ShadowModel`, or per-image calibration (a two-means clustering start on the
block values refined by the propagation algorithm, which the paper allows; a 3- or
4-class multi-Otsu start is the option ``ShadowConfig.calibration_classes``).

Beyond the paper, :func:`~qdcnn.vision.shadow_training.train_multi_shadow_model`
trains a multi-centroid model: ``k`` components (shadow on different surfaces), each
with a centroid and a fidelity threshold per feature (intensity and chromaticity by
default). A block is shadow when every feature's one-qubit UU-dagger test passes for some component
(:func:`multi_centroid_test`); the paper's model is the case ``k = 1`` with one feature.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import lru_cache, partial
from pathlib import Path
from types import ModuleType
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn.config import ShadowConfig
from qdcnn.errors import InputError, ParameterError
from qdcnn.quantum.centroid import (
    MAX_FAST_SPREAD,
    propagate_centroid,
    propagation_fixed_point,
)
from qdcnn.quantum.noise import NoiseSpec
from qdcnn.quantum.sampling import (
    CDF_GRID,
    as_generator,
    binomial_at_most,
    cdf_table,
    coarse_cdf_brackets,
    inverse_binomial,
    settle_between_brackets,
)
from qdcnn.quantum.uu_dagger import (
    VALUE_SCALE,
    angle_to_value,
    fidelity,
    overlap_fidelity,
    value_to_angle,
)
from qdcnn.vision.block_decisions import band_bounds, joined_state_tables, row_compression
from qdcnn.vision.compiled import compiled
from qdcnn.vision.otsu import otsu_threshold
from qdcnn.vision.shadow_model_file import read_shadow_model, write_shadow_model

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
        red, green, blue = cv2.split(np.ascontiguousarray(image, dtype=np.uint8))
        index = (blue.astype(np.uint16) << 8) | cv2.max(red, green)
        return _c3_table().take(index)
    raise ParameterError("feature", feature, "'intensity' or 'chromaticity'")


@lru_cache(maxsize=1)
def _c3_table() -> NDArray[np.float32]:
    """``c3`` for every 8-bit ``(B, max(R, G))`` pair, flattened as ``B * 256 + max(R, G)``.

    A look-up table gives the same float32 values as evaluating ``arctan2`` per
    pixel, at a fraction of the cost.
    """
    level = np.arange(256, dtype=np.float32)
    c3 = np.arctan2(level[:, None], level[None, :])  # arctan(B / max(R, G)); pi/4 for grey
    table = (c3 * np.float32(255.0 / (np.pi / 2))).astype(np.float32).ravel()
    table.setflags(write=False)
    return table


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
    #: (table width, downsample) -> summed-area corner indices and block areas
    corner_cache: dict[tuple[int, int], tuple[NDArray[np.intp], NDArray[np.float64]]] = field(
        default_factory=dict, compare=False, repr=False
    )
    #: (table width, downsample) -> block sizes and per-block offsets into their joined
    #: RY state tables (None: too large for tables)
    state_cache: dict[
        tuple[int, int],
        tuple[tuple[int, ...], NDArray[np.intp], tuple[int, ...], NDArray[np.intp]] | None,
    ] = field(default_factory=dict, compare=False, repr=False)

    #: downsample -> block edges in full-resolution pixels (rows, columns) and block areas
    pixel_cache: dict[int, tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]] = field(
        default_factory=dict, compare=False, repr=False
    )

    #: median aperture -> :func:`~qdcnn.vision.block_decisions.row_compression` of row_of
    median_cache: dict[int, tuple[NDArray[np.intp], NDArray[np.intp]] | None] = field(
        default_factory=dict, compare=False, repr=False
    )

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
    sums, area = _block_sums(values, geometry, downsample)
    return (sums / area).reshape(geometry.grid_shape)


def _block_sums(
    values: NDArray[np.generic], geometry: BlockGrid, downsample: int
) -> tuple[NDArray[Any], NDArray[np.float64]]:
    """Sum of the full-resolution ``values`` in each block and the block's pixel count.

    Both are flat, in row-major grid order; the sums are integers for integer
    ``values`` (:func:`cv2.integral` of ``uint8`` is ``int32``). The summed-area table
    is read once at the ``(gh + 1) x (gw + 1)`` block corners; each block's sum is
    ``bottom-right - top-right - bottom-left + top-left``, in that order.
    """
    corners, area = _cached_corners(geometry, values.shape[1], downsample)
    at = cv2.integral(values).ravel().take(corners)  # (gh + 1, gw + 1)
    sums = at[1:, 1:] - at[:-1, 1:]
    sums -= at[1:, :-1]
    sums += at[:-1, :-1]
    return sums.ravel(), area


def _cached_corners(
    geometry: BlockGrid, width: int, downsample: int
) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    key = (width, downsample)
    cached = geometry.corner_cache.get(key)
    if cached is None:
        cached = _block_corners(
            width, geometry.row_edges * downsample, geometry.col_edges * downsample
        )
        geometry.corner_cache[key] = cached
    return cached


def _block_corners(
    width: int, r: NDArray[np.intp], c: NDArray[np.intp]
) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Flat indices into a ``width + 1`` wide summed-area table of the block corners,
    shape ``(len(r), len(c))``, and the block areas (flat)."""
    corners = r[:, None] * (width + 1) + c[None, :]
    area = np.outer(np.diff(r), np.diff(c)).ravel().astype(np.float64)
    corners.setflags(write=False)
    area.setflags(write=False)
    return corners, area


@dataclass(frozen=True)
class StateLookup:
    """RY state amplitudes of every possible ``uint8`` block mean, indexed by block sum.

    ``offsets[b] + sum_b`` indexes ``cos_half``/``sin_half`` (the joined
    :func:`~qdcnn.quantum.uu_dagger.ry_state_table` of each block size); the table of
    block size (pixel count) ``sizes[i]`` starts at ``starts[i]``; ``size_index`` gives
    each block's ``i``.
    """

    offsets: NDArray[np.intp]
    cos_half: NDArray[np.float64]
    sin_half: NDArray[np.float64]
    sizes: tuple[int, ...] = ()
    starts: tuple[int, ...] = ()
    #: per block, its size's position in ``sizes``
    size_index: NDArray[np.intp] | None = None


#: Largest joined state table (entries, 16 bytes each) worth building; bigger blocks (images
#: of several megapixels) use one cosine per block.
MAX_STATE_TABLE = 1 << 18


def state_lookup(geometry: BlockGrid, width: int, downsample: int) -> StateLookup | None:
    """:class:`StateLookup` for ``uint8`` values of this width, or ``None`` if too large.

    The grid keeps only its per-block offsets; the tables are shared by every grid with
    the same block sizes and only the most recent few are kept, so memory stays bounded
    however many image sizes pass through.
    """
    key = (width, downsample)
    if key not in geometry.state_cache:
        geometry.state_cache[key] = _state_entry(geometry, width, downsample)
    entry = geometry.state_cache[key]
    recent = _RECENT_LOOKUP.get("entry")
    if recent is not None and recent[0] is entry:  # the last frame's grid: 1 us a frame less
        return recent[1]
    if entry is None:
        return None
    cos_half, sin_half = joined_state_tables(entry[0])
    lookup = StateLookup(entry[1], cos_half, sin_half, entry[0], entry[2], entry[3])
    _RECENT_LOOKUP["entry"] = (entry, lookup)
    return lookup


def _state_entry(
    geometry: BlockGrid, width: int, downsample: int
) -> tuple[tuple[int, ...], NDArray[np.intp], tuple[int, ...], NDArray[np.intp]] | None:
    """The grid's block sizes, per-block table offsets, table starts and size indices;
    None where the joined tables would be larger than :data:`MAX_STATE_TABLE`."""
    _, area = _cached_corners(geometry, width, downsample)
    sizes, inverse = np.unique(area.astype(np.intp), return_inverse=True)
    lengths = int(VALUE_SCALE) * sizes + 1
    if int(lengths.sum()) > MAX_STATE_TABLE:
        return None
    starts = np.concatenate([[0], np.cumsum(lengths)[:-1]]).astype(np.intp)
    offsets = starts[inverse.ravel()]
    offsets.setflags(write=False)
    size_index = inverse.ravel().astype(np.intp)
    size_index.setflags(write=False)
    return tuple(int(n) for n in sizes), offsets, tuple(int(i) for i in starts), size_index


#: the last lookup built and the grid's cache entry it came from: one, so that the tables
#: it holds stay bounded
_RECENT_LOOKUP: dict[str, tuple[object, StateLookup]] = {}


def expand_blocks(block_mask: NDArray[np.bool_], geometry: BlockGrid) -> NDArray[np.bool_]:
    """Expand a block-level mask to the full image size (columns first: the smaller copy)."""
    return block_mask.take(geometry.col_of, axis=1).take(geometry.row_of, axis=0)


def binary_median(mask: NDArray[np.uint8], ksize: int) -> NDArray[np.uint8]:
    """Median filter of a 0/1 mask: equal to :func:`cv2.medianBlur` with replicated borders.

    For binary images the median of a ``k x k`` window is 1 exactly when more
    than half of its pixels are 1, so a box sum is enough (and for ``k >= 5``
    much faster than OpenCV's histogram median).
    """
    if ksize * ksize > 255:
        return cv2.medianBlur(mask, ksize) if ksize <= 5 else _median_large(mask, ksize)
    sums = cv2.boxFilter(mask, -1, (ksize, ksize), normalize=False, borderType=cv2.BORDER_REPLICATE)
    cv2.threshold(sums, (ksize * ksize) // 2, 1, cv2.THRESH_BINARY, dst=sums)  # in place: 0/1
    return sums


def _median_large(mask: NDArray[np.uint8], ksize: int) -> NDArray[np.uint8]:
    sums = cv2.boxFilter(
        mask.astype(np.float32),
        -1,
        (ksize, ksize),
        normalize=False,
        borderType=cv2.BORDER_REPLICATE,
    )
    return (sums > (ksize * ksize) // 2).astype(np.uint8)


_MULTI_OTSU_BINS = 32  # histogram bins of the 3- and 4-class splits (4 classes x 256 bins: ~50 ms)


def extreme_cluster(
    values: NDArray[np.float64], classes: int = 2, pick: str = "lowest"
) -> NDArray[np.float64]:
    """Values in the lowest (or highest) class of a 1-D Otsu split into ``classes`` classes.

    Two classes use Otsu's threshold on 256 bins (the optimal 1-D two-means split);
    three or four use the multi-level Otsu thresholds (Liao, Chen & Chung, "A
    fast algorithm for multilevel thresholding", J. Inf. Sci. Eng. 17, 2001;
    :func:`skimage.filters.threshold_multiotsu`) on :data:`_MULTI_OTSU_BINS`
    bins, the maximum of the between-class variance, i.e. a deterministic
    ``classes``-means clustering of the values.
    """
    if pick not in ("lowest", "highest"):
        raise ParameterError("pick", pick, "'lowest' or 'highest'")
    v = np.asarray(values, dtype=np.float64).ravel()
    first, last = float(v.min()), float(v.max())
    if first == last:
        return v
    if classes == 2:
        t = otsu_threshold(v, 256, (first, last))
        return v[v <= t] if pick == "lowest" else v[v > t]
    from skimage.filters import threshold_multiotsu

    try:
        ts = threshold_multiotsu(v, classes=classes, nbins=_MULTI_OTSU_BINS)
    except ValueError:  # fewer distinct levels than classes: fall back to two classes
        return extreme_cluster(v, 2, pick)
    part = v[v <= ts[0]] if pick == "lowest" else v[v > ts[-1]]
    return part if part.size else extreme_cluster(v, 2, pick)


_CALIBRATION_BIN = 0.25  # value units: block means are binned this finely for calibration


def calibrate_centroid(
    block_values: NDArray[np.float64],
    feature: str = "intensity",
    config: ShadowConfig | None = None,
) -> float:
    """Per-image centroid: clustering start on the shadow side, refined by propagation.

    Shadows are the dark cluster of intensity and the high cluster of the
    chromaticity ``c3`` (bluish skylight). The clusters are the two-means split
    (``config.calibration_classes == 2``, the paper's setting) or the extreme
    class of a 3- or 4-class multi-Otsu split (:func:`extreme_cluster`). The
    propagation algorithm then starts at that cluster's mean and runs on its
    block values, binned to :data:`_CALIBRATION_BIN` value units (a histogram
    keeps each iteration independent of the image size). Its fixed point is found
    by Newton's method where the propagation provably converges to it within
    ``config.propagation_iterations`` steps
    (:func:`~qdcnn.quantum.centroid.propagation_fixed_point`; the centroid then
    differs from the iterated one by less than ``config.propagation_tol``), and by
    iterating otherwise. Returns the centroid in value units.
    """
    cfg = config or ShadowConfig()
    cluster = extreme_cluster(
        block_values, cfg.calibration_classes, "lowest" if feature == "intensity" else "highest"
    )
    start = float(cluster.sum()) / cluster.size  # cluster.mean(), fewer layers
    scaled = cluster / _CALIBRATION_BIN
    counts = np.bincount(np.rint(scaled, out=scaled).astype(np.intp))
    levels = counts.nonzero()[0]
    angles = np.multiply(levels, _CALIBRATION_BIN, dtype=np.float64)
    angles *= np.pi / VALUE_SCALE  # value_to_angle
    weights = counts.take(levels).astype(np.float64)
    theta0 = start * (np.pi / VALUE_SCALE)
    iterations, tol = cfg.propagation_iterations, cfg.propagation_tol
    theta = propagation_fixed_point(angles, weights, theta0, iterations=iterations, tol=tol)
    if theta is None:
        theta = propagate_centroid(
            angles, theta0, iterations=iterations, tol=tol, weights=weights
        ).theta
    return float(np.clip(angle_to_value(theta), 0.0, 255.0))


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
    block_mask : ndarray of bool, shape (gh, gw), optional
        Blocks classified as shadow (before expansion and median filtering).
    feature_values : ndarray, shape (F, gh, gw), optional
        For a multi-centroid model: the block value of each of its features
        (``block_values`` is the first); ``block_scores`` is then the highest
        product of per-feature fidelities over the components whose circuits all
        ran (0 where the cascade stopped early for every component).
    """

    mask: NDArray[np.bool_]
    block_values: NDArray[np.float64]
    #: the block scores, or a function that computes them on first use of ``block_scores``
    scores: NDArray[np.float64] | Callable[[], NDArray[np.float64]] = field(repr=False)
    centroid: float
    threshold: float
    feature: str
    centroid_source: str
    block_mask: NDArray[np.bool_] | None = None
    feature_values: NDArray[np.float64] | None = None

    @property
    def block_scores(self) -> NDArray[np.float64]:
        """Score of every block, shape ``(gh, gw)``.

        The fast intensity path decides the blocks from their sums without the scores
        (:func:`~qdcnn.vision.block_decisions.band_bounds`, or one uniform per block with
        shots); it computes them here, on first use, with the same formula and uniforms.
        """
        if callable(self.scores):
            self.scores = self.scores()
        return self.scores

    @property
    def shadow_fraction(self) -> float:
        return float(self.mask.mean())


@dataclass(frozen=True)
class ShadowModel:
    """A trained UU-dagger shadow model, saved as JSON.

    The paper's model is one centroid on one feature with one threshold. A
    multi-centroid model (:func:`train_multi_shadow_model`) has ``k`` components,
    each a centroid per feature with its own fidelity threshold per feature: a
    block is shadow when, for some component, every feature's UU-dagger test
    passes (one circuit per feature and component). ``feature``, ``centroid``
    and ``threshold`` then repeat the first component's first entry, so code
    that reads only them still sees a sensible value.

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
    features : tuple of str
        Multi-centroid models only: the block features, in test order.
    centroids, thresholds : tuple of tuple of float
        Multi-centroid models only: ``(k, F)`` centroids (value units) and
        fidelity thresholds.
    """

    feature: str
    centroid: float
    threshold: float
    meta: dict[str, Any] = field(default_factory=dict)
    features: tuple[str, ...] = ()
    centroids: tuple[tuple[float, ...], ...] = ()
    thresholds: tuple[tuple[float, ...], ...] = ()

    def __post_init__(self) -> None:
        if not (self.features or self.centroids or self.thresholds):
            return
        n = len(self.features)
        if n == 0 or any(f not in FEATURES for f in self.features):
            raise ParameterError("features", self.features, "a non-empty tuple of " + str(FEATURES))
        if not self.centroids or any(len(c) != n for c in self.centroids):
            raise ParameterError("centroids", self.centroids, f"one {n}-tuple per component")
        if len(self.thresholds) != len(self.centroids) or any(len(t) != n for t in self.thresholds):
            raise ParameterError("thresholds", self.thresholds, "the shape of centroids")
        for c in np.ravel(self.centroids):
            _check_value_range("centroids", float(c), 0.0, 255.0)
        for t in np.ravel(self.thresholds):
            _check_value_range("thresholds", float(t), 0.0, 1.0)

    @property
    def is_multi(self) -> bool:
        """Whether this is a multi-centroid (or multi-feature) model."""
        return bool(self.centroids)

    def to_dict(self) -> dict[str, Any]:
        """Plain values for JSON output (the multi-centroid fields only when used)."""
        out: dict[str, Any] = {
            "feature": self.feature,
            "centroid": self.centroid,
            "threshold": self.threshold,
            **self.meta,
        }
        if self.is_multi:
            out.update(
                features=list(self.features),
                centroids=[list(c) for c in self.centroids],
                thresholds=[list(t) for t in self.thresholds],
            )
        return out

    def describe(self) -> str:
        """One line for people: the centroid(s) and threshold(s)."""
        if not self.is_multi:
            return f"{self.feature} centroid {self.centroid:.2f}, threshold {self.threshold}"
        parts = [
            " & ".join(
                f"{f} {c:.1f} (>= {t:.4f})" for f, c, t in zip(self.features, cs, ts, strict=True)
            )
            for cs, ts in zip(self.centroids, self.thresholds, strict=True)
        ]
        return f"{len(parts)} components: " + "; ".join(parts)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the model as a JSON model file (format version 2), atomically.

        See :mod:`qdcnn.vision.shadow_model_file` for the layout.
        """
        fields: dict[str, Any] = {
            "feature": self.feature,
            "centroid": self.centroid,
            "threshold": self.threshold,
            "provenance": self.meta,
        }
        if self.is_multi:
            fields.update(
                features=list(self.features),
                centroids=[list(c) for c in self.centroids],
                thresholds=[list(t) for t in self.thresholds],
            )
        return write_shadow_model(path, fields)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> ShadowModel:
        """Read a model written by :meth:`save` (format versions 1 and 2).

        Raises
        ------
        InputError
            Any unusable file or field, in one line naming the file
            (:func:`~qdcnn.vision.shadow_model_file.read_shadow_model`).
        """
        fields = read_shadow_model(path)
        try:
            model = cls(
                fields["feature"],
                fields["centroid"],
                fields["threshold"],
                dict(fields["provenance"]),
                fields.get("features", ()),
                fields.get("centroids", ()),
                fields.get("thresholds", ()),
            )
            ShadowConfig(feature=model.feature, centroid=model.centroid, threshold=model.threshold)  # type: ignore[arg-type]
        except ParameterError as exc:
            raise InputError(path, f"bad field: {exc}") from None
        return model


def _check_value_range(name: str, value: float, lo: float, hi: float) -> None:
    if not (np.isfinite(value) and lo <= value <= hi):
        raise ParameterError(name, value, f"numbers in [{lo}, {hi}]")


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

    Notes
    -----
    For ``uint8`` intensity blocks on the noise-free NumPy backend, the exact
    scores come from :func:`~qdcnn.quantum.uu_dagger.overlap_fidelity` with the
    test states looked up by block sum (:func:`state_lookup`): the same
    statevector result as simulating each block's circuit (tested to 1e-12, and
    against Aer), without a cosine per block. The exact decisions are those scores
    thresholded, found from the block sums directly
    (:func:`~qdcnn.vision.block_decisions.band_bounds`); ``block_scores`` is then
    computed on first use. On the NumPy backend shots are drawn from the exact (or
    noisy) probabilities by :func:`sampled_decisions`: the binomial statistics of
    measuring each circuit ``shots`` times, one uniform per circuit (Aer samples its
    own).
    """
    cfg = config or ShadowConfig()
    if model is not None and model.is_multi:
        return _detect_multi(image, cfg, model, backend, noise, rng)
    if model is not None:
        cfg = replace(cfg, feature=model.feature, threshold=model.threshold)  # type: ignore[arg-type]
    values = feature_input(image, cfg.feature)
    geometry = block_grid(values.shape[:2], cfg.downsample, cfg.grid)
    ideal = backend == "numpy" and (noise is None or noise.is_ideal)
    kernels = compiled_kernels() if ideal and values.dtype == np.uint8 else None
    if kernels is not None:
        lookup = state_lookup(geometry, values.shape[1], cfg.downsample)
        if lookup is not None:
            return _detect_compiled(kernels, values, geometry, lookup, cfg, model, rng)
    sums, area = _block_sums(values, geometry, cfg.downsample)
    blocks = (sums / area).reshape(geometry.grid_shape)
    centroid, source = _centroid_of(cfg, model, blocks)
    lookup = None
    if ideal and values.dtype == np.uint8:
        lookup = state_lookup(geometry, values.shape[1], cfg.downsample)
    if lookup is not None:
        decided, scores = _looked_up(lookup, sums, centroid, cfg, rng, source != "calibrated")
    else:
        decided, scores = _simulated(blocks, centroid, cfg, backend, noise, rng)
    mask = _to_image_mask(decided.reshape(blocks.shape), geometry, cfg.median_ksize)
    return _detection(mask, blocks, scores, centroid, cfg, source, decided)


def compiled_kernels() -> ModuleType | None:
    """:mod:`qdcnn.vision.block_kernels`, or ``None`` when Numba is missing or
    ``QDCNN_KERNELS=numpy`` asks for the NumPy detector (the reference the kernels are
    tested against, and what the benchmarks compare them with)."""
    return compiled("block_kernels")


def _detect_compiled(
    kernels: ModuleType,
    grey: NDArray[Any],
    geometry: BlockGrid,
    lookup: StateLookup,
    cfg: ShadowConfig,
    model: ShadowModel | None,
    rng: int | np.random.Generator | None,
) -> ShadowDetection:
    """:func:`detect_shadows_uu` on ``uint8`` intensity with the compiled kernels: the
    same block sums, decisions and mask as the NumPy path (the calibrated centroid to a
    few units in the last place), in one or two kernel calls."""
    edges = _pixel_edges(geometry, cfg.downsample)
    rows, cols, area = edges
    calibrated = cfg.centroid is None and model is None
    # the kernels calibrate on two classes only; other splits are calibrated with NumPy
    in_two = cfg.calibration_classes == 2
    if calibrated and in_two and cfg.median_ksize**2 <= 255:
        if cfg.shots is None:
            return _detect_calibrated(kernels, grey, edges, geometry, lookup, cfg)
        return _detect_calibrated_shots(kernels, grey, edges, geometry, lookup, cfg, rng)
    if calibrated:
        if in_two:
            sums, blocks, theta = kernels.calibrate_blocks(
                grey, rows, cols, area, _half_angle_tangents(), _calibration_settings(cfg)
            )
        else:
            (sums, blocks), theta = kernels.block_sums(grey, rows, cols, area), math.nan
        centroid, source = _calibrated_value(theta, blocks, cfg), "calibrated"
    else:
        centroid, source = _repeated_centroid(cfg, model)
        if cfg.shots is not None and cfg.median_ksize**2 <= 255:
            return _detect_shot_table(kernels, grey, geometry, lookup, cfg, centroid, source, rng)
        band = _band(lookup, centroid, cfg)
        if band is not None:
            sums, blocks, decided, mask = kernels.detect_band(
                grey, rows, cols, area, band, geometry.row_of, geometry.col_of, cfg.median_ksize
            )
            exact = partial(_overlap_scores, lookup, sums.ravel(), centroid)
            return _detection(mask, blocks, exact, centroid, cfg, source, decided)
        sums, blocks = kernels.block_sums(grey, rows, cols, area)
    u = None if cfg.shots is None else as_generator(rng).random(sums.size)
    scores, decided, mask = _compiled_decisions(kernels, lookup, sums, centroid, cfg, u, geometry)
    return _detection(mask, blocks, scores, centroid, cfg, source, decided)


def _detect_calibrated(
    kernels: ModuleType,
    grey: NDArray[Any],
    edges: tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]],
    geometry: BlockGrid,
    lookup: StateLookup,
    cfg: ShadowConfig,
) -> ShadowDetection:
    """The exact detection with the centroid calibrated on the frame, in one kernel call
    (:func:`block_kernels.detect_calibrated`). Where the kernel's fixed point has no
    answer, its block sums are calibrated with NumPy (:func:`_calibrated_value`) and
    decided as a given centroid's."""
    sums, blocks, centroid, scores, decided, mask = kernels.detect_calibrated(
        grey,
        edges,
        _half_angle_tangents(),
        _calibration_settings(cfg),
        (lookup.offsets, lookup.cos_half, lookup.sin_half),
        cfg.threshold,
        geometry.row_of,
        geometry.col_of,
        cfg.median_ksize,
    )
    if math.isnan(centroid):
        centroid = _calibrated_value(centroid, blocks, cfg)
        scores, decided, mask = _compiled_decisions(
            kernels, lookup, sums, centroid, cfg, None, geometry
        )
    return _detection(mask, blocks, scores, centroid, cfg, "calibrated", decided)


def _detect_calibrated_shots(
    kernels: ModuleType,
    grey: NDArray[Any],
    edges: tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]],
    geometry: BlockGrid,
    lookup: StateLookup,
    cfg: ShadowConfig,
    rng: int | np.random.Generator | None,
) -> ShadowDetection:
    """:func:`_detect_calibrated` with shots, in one kernel call
    (:func:`block_kernels.detect_calibrated_shots`): the uniforms, brackets and decisions
    of :func:`sampled_decisions`."""
    shots = int(cfg.shots or 0)
    tables, limit = _shot_tables(shots, cfg.threshold)
    u = as_generator(rng).random(int(edges[2].size))
    image = (geometry.row_of, geometry.col_of, cfg.median_ksize)
    sums, blocks, centroid, p, decided, unsure, mask = kernels.detect_calibrated_shots(
        grey,
        edges,
        _half_angle_tangents(),
        _calibration_settings(cfg),
        (lookup.offsets, lookup.cos_half, lookup.sin_half),
        u,
        tables,
        CDF_GRID,
        *image,
    )
    if math.isnan(centroid):
        centroid = _calibrated_value(centroid, blocks, cfg)
        scores, decided, mask = _compiled_decisions(
            kernels, lookup, sums, centroid, cfg, u, geometry
        )
        return _detection(mask, blocks, scores, centroid, cfg, "calibrated", decided)
    scores, mask = _settled(kernels, decided, unsure, (p, u, shots, limit), mask, image)
    return _detection(mask, blocks, scores, centroid, cfg, "calibrated", decided)


def _detect_shot_table(
    kernels: ModuleType,
    grey: NDArray[np.uint8],
    geometry: BlockGrid,
    lookup: StateLookup,
    cfg: ShadowConfig,
    centroid: float,
    source: str,
    rng: int | np.random.Generator | None,
) -> ShadowDetection:
    """A repeated centroid with shots: one uniform per block against the pass probability
    of its sum (:func:`_passing_table`, cached), so the decisions are those of
    :func:`sampled_decisions`; the scores are computed on first use from the same uniforms."""
    rows, cols, area = _pixel_edges(geometry, cfg.downsample)
    shots = int(cfg.shots or 0)
    u = as_generator(rng).random(int(area.size))
    passing = _passing_table(lookup.sizes, lookup.starts, centroid, cfg.threshold, shots)
    sums, blocks, decided, mask = kernels.detect_shot_table(
        grey,
        rows,
        cols,
        area,
        lookup.offsets,
        passing,
        u,
        geometry.row_of,
        geometry.col_of,
        cfg.median_ksize,
    )
    exact = partial(_overlap_scores, lookup, sums.ravel(), centroid)
    limit = _most_ones(shots, cfg.threshold)
    passed = decided.ravel().view(np.bool_)
    scores = partial(_inverse_scores_of, exact, u, passed, shots, limit)
    return _detection(mask, blocks, scores, centroid, cfg, source, decided)


@lru_cache(maxsize=8)
def _passing_table(
    sizes: tuple[int, ...], starts: tuple[int, ...], centroid: float, threshold: float, shots: int
) -> NDArray[np.float64]:
    """For every entry of the joined state tables (a block size and sum), the probability
    ``P(Bin(shots, 1 - score) <= limit)`` that its circuit passes with ``shots`` shots: a
    block passes when its uniform is at most that (-1 or 2 where no count or every count
    passes)."""
    from scipy.special import bdtr

    limit = _most_ones(shots, threshold)
    cos_half, sin_half = joined_state_tables(sizes)
    p = 1.0 - overlap_fidelity(float(value_to_angle(centroid)), cos_half, sin_half)
    if limit < 0 or limit >= shots:
        table = np.full(p.size, 2.0 if limit >= shots else -1.0)
    else:
        table = bdtr(limit, shots, np.clip(p, 0.0, 1.0))
    table.setflags(write=False)
    return table


def _inverse_scores_of(
    exact: Callable[[], NDArray[np.float64]],
    u: NDArray[np.float64],
    passed: NDArray[np.bool_],
    shots: int,
    limit: int,
) -> NDArray[np.float64]:
    """:func:`_inverse_scores` of the exact scores computed now."""
    return _inverse_scores(1.0 - exact(), u, passed, shots, limit)


def _detection(
    mask: NDArray[np.bool_],
    blocks: NDArray[np.float64],
    scores: NDArray[np.float64] | Callable[[], NDArray[np.float64]],
    centroid: float,
    cfg: ShadowConfig,
    source: str,
    decided: NDArray[np.bool_] | NDArray[np.uint8],
) -> ShadowDetection:
    """The detection of decisions ``decided`` (0/1 or bool, the blocks' shape or flat)."""
    return ShadowDetection(
        mask,
        blocks,
        _reshaped(scores, blocks.shape),
        centroid,
        cfg.threshold,
        cfg.feature,
        source,
        decided.reshape(blocks.shape).view(np.bool_),
    )


def _band(
    lookup: StateLookup, centroid: float, cfg: ShadowConfig
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.uint64]] | None:
    """The exact band of a repeated centroid for :func:`block_kernels.detect_band`; None
    with shots, a median the kernels do not take, or a band that cannot be certified."""
    if cfg.shots is not None or lookup.size_index is None or cfg.median_ksize**2 > 255:
        return None
    bounds = band_bounds(lookup.sizes, lookup.starts, centroid, cfg.threshold)
    return None if bounds is None else (lookup.size_index, *bounds)


def _pixel_edges(
    geometry: BlockGrid, downsample: int
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]]:
    """Block edges in full-resolution pixels (rows, columns) and the block areas, (gh, gw)."""
    cached = geometry.pixel_cache.get(downsample)
    if cached is None:
        rows = np.ascontiguousarray(geometry.row_edges * downsample, dtype=np.intp)
        cols = np.ascontiguousarray(geometry.col_edges * downsample, dtype=np.intp)
        area = np.outer(np.diff(rows), np.diff(cols)).astype(np.float64)
        cached = geometry.pixel_cache[downsample] = (rows, cols, area)
    return cached


def _calibration_settings(cfg: ShadowConfig) -> NDArray[np.float64]:
    """The numbers :func:`block_kernels.calibrate` takes besides the values and tables
    (cached by the two settings they hold: hashing the whole config costs 0.6 us a frame)."""
    return _calibration_numbers(cfg.propagation_iterations, cfg.propagation_tol)


@lru_cache(maxsize=8)
def _calibration_numbers(iterations: int, tol: float) -> NDArray[np.float64]:
    settings = np.array(
        [
            _CALIBRATION_BIN,
            np.pi / VALUE_SCALE,
            iterations,
            tol,
            MAX_FAST_SPREAD,
            VALUE_SCALE / np.pi,
        ]
    )
    settings.setflags(write=False)
    return settings


def _calibrated_value(theta: float, blocks: NDArray[np.float64], cfg: ShadowConfig) -> float:
    """The centroid (value units) of the kernel's calibrated angle; where the kernel has
    no certified fixed point (NaN), :func:`calibrate_centroid`'s propagation."""
    if theta != theta:
        return calibrate_centroid(blocks, cfg.feature, cfg)
    return min(max(theta * (VALUE_SCALE / np.pi), 0.0), 255.0)  # angle_to_value, clipped


@lru_cache(maxsize=1)
def _half_angle_tangents() -> NDArray[np.float64]:
    """``tan(theta / 2)`` of every calibration level (value ``k * _CALIBRATION_BIN``)."""
    levels = np.arange(int(VALUE_SCALE / _CALIBRATION_BIN) + 1)
    angles = np.multiply(levels, _CALIBRATION_BIN, dtype=np.float64)
    angles *= np.pi / VALUE_SCALE
    table = np.tan(angles * 0.5)
    table.setflags(write=False)
    return table


def _compiled_decisions(
    kernels: ModuleType,
    lookup: StateLookup,
    sums: NDArray[np.int64],
    centroid: float,
    cfg: ShadowConfig,
    u: NDArray[np.float64] | None,
    geometry: BlockGrid,
) -> tuple[
    NDArray[np.float64] | Callable[[], NDArray[np.float64]], NDArray[np.uint8], NDArray[np.bool_]
]:
    """Scores (or how to get them), 0/1 decisions and image mask of the ``(gh, gw)`` block
    sums without a band: the exact scores thresholded, or with shots the uniforms ``u``,
    one per block (:func:`_looked_up`)."""
    half = float(value_to_angle(centroid)) / 2.0
    amplitudes = (lookup.offsets, lookup.cos_half, lookup.sin_half)
    ksize = cfg.median_ksize
    image = (geometry.row_of, geometry.col_of, 1 if ksize**2 > 255 else ksize)  # big: below
    if cfg.shots is None:
        scores, decided, mask = kernels.detect_scores(
            sums, amplitudes, np.cos(half), np.sin(half), cfg.threshold, *image
        )
        outcome: tuple[Any, Any, Any] = (scores, decided, mask)
    else:
        assert u is not None
        outcome = _compiled_shots(
            kernels, amplitudes, (np.cos(half), np.sin(half)), sums, cfg, u, image
        )
    if ksize**2 > 255:
        mask = _to_image_mask(
            outcome[1].reshape(geometry.grid_shape).view(np.bool_), geometry, ksize
        )
        outcome = (outcome[0], outcome[1], mask)
    return outcome


def _compiled_shots(
    kernels: ModuleType,
    amplitudes: tuple[Any, ...],
    centroid_state: tuple[float, float],
    sums: NDArray[np.int64],
    cfg: ShadowConfig,
    u: NDArray[np.float64],
    image: tuple[Any, ...],
) -> tuple[Callable[[], NDArray[np.float64]], NDArray[np.uint8], NDArray[np.bool_]]:
    """:func:`sampled_decisions` by :func:`block_kernels.detect_shots`: the same uniforms,
    brackets and decisions."""
    shots = int(cfg.shots or 0)
    tables, limit = _shot_tables(shots, cfg.threshold)
    p, decided, unsure, mask = kernels.detect_shots(
        sums, amplitudes, *centroid_state, u, tables, CDF_GRID, *image
    )
    scores, mask = _settled(kernels, decided, unsure, (p, u, shots, limit), mask, image)
    return scores, decided, mask


@lru_cache(maxsize=8)
def _shot_tables(shots: int, threshold: float) -> tuple[tuple[NDArray[np.float64], ...], int]:
    """The fine and coarse CDF brackets the shot kernels take, and the largest passing
    count of ones (out of ``0 .. shots - 1`` it is decided by :func:`_settled`)."""
    limit = _most_ones(shots, threshold)
    table_limit = min(max(limit, 0), shots - 1)  # any valid table
    return (*cdf_table(shots, table_limit)[::-1], *coarse_cdf_brackets(shots, table_limit)), limit


def _settled(
    kernels: ModuleType,
    decided: NDArray[np.uint8],
    unsure: NDArray[np.intp],
    sampling: tuple[NDArray[np.float64], NDArray[np.float64], int, int],
    mask: NDArray[np.bool_],
    image: tuple[Any, ...],
) -> tuple[Callable[[], NDArray[np.float64]], NDArray[np.bool_]]:
    """The sampled scores (computed on first use) and the image mask of a shot kernel's
    decisions, after settling in ``decided`` the blocks it left between its CDF brackets
    with first guesses (``sampling``: the blocks' ``p``, the uniforms, shots and limit), or
    deciding every block where the limit lies outside the tables (none or all pass). The
    kernel's ``mask`` is kept when no decision changed, else the whole mask is expanded
    again."""
    p, u, shots, limit = sampling
    passed = decided.ravel().view(np.bool_)
    scores = partial(_inverse_scores, p, u, passed, shots, limit)
    if 0 <= limit < shots:
        if not settle_between_brackets(passed, unsure, p, u, shots, limit):
            return scores, mask
    else:
        passed[:] = limit >= shots
    return scores, kernels.expand_median(decided, *image)


def _simulated(
    blocks: NDArray[np.float64],
    centroid: float,
    cfg: ShadowConfig,
    backend: str,
    noise: NoiseSpec | None,
    rng: int | np.random.Generator | None,
) -> tuple[NDArray[np.bool_], NDArray[np.float64] | Callable[[], NDArray[np.float64]]]:
    """Decisions and scores of the blocks from their circuits (Aer, or NumPy with noise or
    float block values): exact or Aer-sampled scores thresholded, or NumPy's exact
    probabilities sampled by :func:`sampled_decisions`."""
    exact = fidelity(
        value_to_angle(centroid),
        value_to_angle(blocks.ravel()),
        shots=cfg.shots if backend == "aer" else None,
        backend=backend,
        noise=noise,
        rng=rng,
    )
    if backend != "aer" and cfg.shots is not None:
        return sampled_decisions(exact, cfg.shots, cfg.threshold, rng)
    return exact >= cfg.threshold, exact


def _centroid_of(
    cfg: ShadowConfig, model: ShadowModel | None, blocks: NDArray[np.float64]
) -> tuple[float, str]:
    """The centroid to test against and where it comes from: the config's, the model's or
    calibrated on this image's blocks."""
    if cfg.centroid is None and model is None:
        return calibrate_centroid(blocks, cfg.feature, cfg), "calibrated"
    return _repeated_centroid(cfg, model)


def _repeated_centroid(cfg: ShadowConfig, model: ShadowModel | None) -> tuple[float, str]:
    """The config's centroid, else the model's (one of them must be there), and its source."""
    if cfg.centroid is not None:
        return float(cfg.centroid), "given"
    if model is None:
        raise ParameterError("model", None, "a model or a centroid")
    return model.centroid, "model"


def _looked_up(
    lookup: StateLookup,
    sums: NDArray[Any],
    centroid: float,
    cfg: ShadowConfig,
    rng: int | np.random.Generator | None,
    repeated: bool,
) -> tuple[NDArray[np.bool_], NDArray[np.float64] | Callable[[], NDArray[np.float64]]]:
    """Decisions of the blocks from their sums, and their scores (or how to compute them).

    Exact, with a centroid that repeats from frame to frame (given or trained,
    ``repeated``): the band of passing sums of the centroid (:func:`band_bounds`, cached),
    the scores left for later; with a centroid calibrated on this frame computing the
    scores costs less than finding a new band. With shots: :func:`sampled_decisions`.
    """
    exact = partial(_overlap_scores, lookup, sums, centroid)
    if cfg.shots is None:
        bounds = (
            band_bounds(lookup.sizes, lookup.starts, centroid, cfg.threshold) if repeated else None
        )
        if bounds is not None and lookup.size_index is not None:
            low, width = bounds
            offset = np.subtract(sums, low.take(lookup.size_index))
            return offset.view(np.uint64) <= width.take(lookup.size_index), exact
        scores = exact()
        return scores >= cfg.threshold, scores
    return sampled_decisions(exact(), cfg.shots, cfg.threshold, rng)


def sampled_decisions(
    exact: NDArray[np.float64],
    shots: int,
    threshold: float,
    rng: int | np.random.Generator | None,
) -> tuple[NDArray[np.bool_], Callable[[], NDArray[np.float64]]]:
    """Shot-sampled decisions ``score >= threshold`` of circuits with exact scores ``P(0)``,
    and a function giving their sampled scores (the fraction of ``shots`` measurements
    giving 0).

    Each circuit's count of outcome 1 is ``min{k : F(k) >= u}`` for one uniform ``u``
    (``F`` the CDF of ``Bin(shots, 1 - exact)``): exactly binomial. Its score passes when
    the count is at most the largest passing count ``limit``, that is when
    ``u <= F(limit)`` (:func:`~qdcnn.quantum.sampling.binomial_at_most`); the counts
    themselves (:func:`~qdcnn.quantum.sampling.inverse_binomial`, same uniforms) are only
    found when the scores are asked for.
    """
    p = 1.0 - exact
    u = as_generator(rng).random(p.size)
    limit = _most_ones(shots, threshold)
    passed = binomial_at_most(p, shots, limit, u)
    return passed, partial(_inverse_scores, p, u, passed, shots, limit)


def _overlap_scores(lookup: StateLookup, sums: NDArray[Any], centroid: float) -> NDArray[Any]:
    """Exact block fidelities from the test states looked up by block sum."""
    index = lookup.offsets + sums
    return overlap_fidelity(
        float(value_to_angle(centroid)), lookup.cos_half.take(index), lookup.sin_half.take(index)
    )


@lru_cache(maxsize=16)
def _most_ones(shots: int, threshold: float) -> int:
    """Largest count of outcome 1 whose score ``(shots - count) / shots`` (as
    :func:`_inverse_scores` computes it) reaches ``threshold``; -1 if none does."""
    scores = (shots - np.arange(shots + 1)) / float(shots)
    return int(np.count_nonzero(scores >= threshold)) - 1


def _inverse_scores(
    p: NDArray[np.float64],
    u: NDArray[np.float64],
    passed: NDArray[np.bool_],
    shots: int,
    limit: int,
) -> NDArray[np.float64]:
    """Sampled scores from the uniforms of :func:`_looked_up`: the counts by inverse
    transform, held to the side of ``limit`` the decisions took (they differ only where
    rounding in two CDF evaluations disagrees)."""
    counts = inverse_binomial(p, shots, u)
    counts = np.where(passed, np.minimum(counts, limit), np.maximum(counts, limit + 1))
    return (shots - counts) / float(shots)


def _reshaped(
    scores: NDArray[np.float64] | Callable[[], NDArray[np.float64]], shape: tuple[int, ...]
) -> NDArray[np.float64] | Callable[[], NDArray[np.float64]]:
    if callable(scores):
        return lambda: scores().reshape(shape)
    return scores.reshape(shape)


def _to_image_mask(
    block_mask: NDArray[np.bool_], geometry: BlockGrid, median_ksize: int
) -> NDArray[np.bool_]:
    """The block mask at the image size, median filtered; blocks taller than the filter
    are filtered on their kept rows only (:func:`~qdcnn.vision.block_decisions.row_compression`)."""
    if 1 < median_ksize and median_ksize * median_ksize <= 255:
        if median_ksize not in geometry.median_cache:
            geometry.median_cache[median_ksize] = row_compression(geometry.row_of, median_ksize)
        rows = geometry.median_cache[median_ksize]
        if rows is not None:
            kept = block_mask.take(geometry.col_of, axis=1).take(rows[0], axis=0)
            return binary_median(kept.view(np.uint8), median_ksize).take(rows[1], axis=0).view(bool)
    full = expand_blocks(block_mask, geometry)
    if median_ksize > 1:
        full = binary_median(full.view(np.uint8), median_ksize).view(bool)  # 0/1 bytes
    return full


def _detect_multi(
    image: NDArray[np.uint8],
    cfg: ShadowConfig,
    model: ShadowModel,
    backend: str,
    noise: NoiseSpec | None,
    rng: int | np.random.Generator | None,
) -> ShadowDetection:
    if cfg.centroid is not None:
        raise ParameterError(
            "shadow.centroid", cfg.centroid, "None with a multi-centroid model (it has its own)"
        )
    geometry = block_grid(image.shape[:2], cfg.downsample, cfg.grid)
    values = np.stack(
        [block_means(feature_input(image, f), geometry, cfg.downsample) for f in model.features]
    )
    accepted, scores = multi_centroid_test(
        values.reshape(len(model.features), -1),
        np.asarray(model.centroids),
        np.asarray(model.thresholds),
        shots=cfg.shots,
        backend=backend,
        noise=noise,
        rng=rng,
    )
    block_mask = accepted.reshape(geometry.grid_shape)
    return ShadowDetection(
        _to_image_mask(block_mask, geometry, cfg.median_ksize),
        values[0],
        scores.reshape(geometry.grid_shape),
        model.centroid,
        model.threshold,
        "+".join(model.features),
        "model",
        block_mask,
        values,
    )


def multi_centroid_test(
    values: NDArray[np.float64],
    centroids: NDArray[np.float64],
    thresholds: NDArray[np.float64],
    *,
    shots: int | None = 1024,
    backend: str = "numpy",
    noise: NoiseSpec | None = None,
    rng: int | np.random.Generator | None = None,
) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
    """UU-dagger tests of ``N`` blocks against ``k`` components of ``F`` features each.

    A block belongs to a component when every feature's one-qubit fidelity
    with that component's centroid reaches its threshold, and is shadow when it
    belongs to any component. The features are tested in order as a cascade:
    the circuit of feature ``f`` runs only for the (block, component) pairs that
    passed features ``0 .. f-1`` (the others cannot pass any more), in one
    batched run per feature. The decisions are those of running every circuit.

    Parameters
    ----------
    values : ndarray, shape (F, N)
        Block values in value units.
    centroids, thresholds : ndarray, shape (k, F)
        Centroids (value units) and fidelity thresholds.
    shots, backend, noise, rng
        As for :func:`qdcnn.quantum.uu_dagger.fidelity`.

    Returns
    -------
    accepted : ndarray of bool, shape (N,)
    scores : ndarray of float64, shape (N,)
        Highest product of the fidelities over the components whose circuits all
        ran for the block; 0 where none did.
    """
    gen = None if shots is None else as_generator(rng)
    k, n_features = centroids.shape
    n = values.shape[1]
    theta_c = value_to_angle(centroids)
    theta_x = value_to_angle(values)
    pairs = np.arange(k * n)  # (component, block) pairs still alive, component-major
    product = np.ones(k * n)
    for f in range(n_features):
        if pairs.size == 0:
            break
        comp, block = np.divmod(pairs, n)
        s = fidelity(
            theta_c[comp, f], theta_x[f, block], shots=shots, backend=backend, noise=noise, rng=gen
        )
        passed = s >= thresholds[comp, f]
        product[pairs] *= s
        if f < n_features - 1:
            product[pairs[~passed]] = 0.0  # the cascade stops here for these pairs
        pairs = pairs[passed]
    accepted = np.zeros(n, dtype=bool)
    accepted[pairs % n] = True
    return accepted, product.reshape(k, n).max(axis=0)
