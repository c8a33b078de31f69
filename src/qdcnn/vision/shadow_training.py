"""Training UU-dagger shadow models: the paper's centroid and the multi-centroid extension.

The paper trains one parameter, the centroid, by its propagation algorithm
(:mod:`qdcnn.quantum.centroid`) on a crop of a shadow region (:func:`train_from_crop`).
:func:`train_shadow_model` does the same on every block that is at least half shadow in
a training set of images with masks, and can pick the threshold with the lowest
training BER. :func:`train_multi_shadow_model` (not in the paper) trains ``k``
components, each with a centroid and a threshold per feature, tested together by
:func:`~qdcnn.vision.shadows.multi_centroid_test`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from qdcnn.config import ShadowConfig
from qdcnn.errors import ParameterError
from qdcnn.quantum.centroid import propagate_centroid
from qdcnn.quantum.uu_dagger import angle_to_value, fidelity, value_to_angle
from qdcnn.vision.shadows import (
    FEATURES,
    ShadowModel,
    block_grid,
    block_means,
    feature_input,
    feature_map,
)


def block_shadow_fraction(mask: NDArray[np.bool_], config: ShadowConfig) -> NDArray[np.float64]:
    """Fraction of shadow pixels of a ground-truth mask in each block of ``config``'s grid."""
    geometry = block_grid(mask.shape[:2], config.downsample, config.grid)
    return block_means(mask.astype(np.uint8), geometry, config.downsample)


def _train_centroid(
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
    centroid = _train_centroid(crop.ravel().astype(np.float64), cfg)
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
    centroid = _train_centroid(v[shadow], cfg)
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


def halfwidth_threshold(halfwidth: float) -> float:
    """Fidelity threshold whose exact band is ``+-halfwidth`` value units around a centroid."""
    return float(np.cos(value_to_angle(halfwidth) / 2.0) ** 2)


#: Share of a cluster's blocks inside the starting band of each of its features.
_START_COVERAGE = 0.9

#: Candidate per-feature thresholds of :func:`train_multi_shadow_model`: the bands
#: +-2, +-6, ..., +-126 value units.
MULTI_THRESHOLD_GRID: tuple[float, ...] = tuple(
    sorted(halfwidth_threshold(h) for h in range(2, 130, 4))
)


def train_multi_shadow_model(
    images: list[NDArray[np.uint8]],
    masks: list[NDArray[np.bool_]],
    config: ShadowConfig | None = None,
    *,
    features: tuple[str, ...] = FEATURES,
    n_centroids: int = 3,
    thresholds: tuple[float, ...] = MULTI_THRESHOLD_GRID,
    seed: int = 0,
    max_rounds: int = 10,
) -> ShadowModel:
    """Train a multi-centroid UU-dagger shadow model on images with shadow masks.

    Shadow looks different on different surfaces (dark and bluish on grey
    asphalt, brown on dry verges), so one centroid per feature is a poor model
    of it. Here the blocks that are at least half shadow are clustered by
    k-means in feature space (the paper's clustering start, Sec. II-A-1); each
    cluster's centroid is then trained per feature by the propagation algorithm
    (:func:`_train_centroid`, started at the cluster mean). Finally each
    (component, feature) fidelity threshold is picked from ``thresholds`` by
    coordinate descent on the training set's pixel-weighted balanced error rate
    (each block counts with its shadow and non-shadow pixel fractions), starting
    from the narrowest bands that hold :data:`_START_COVERAGE` of each cluster's
    blocks, until no single change lowers it. Where a range of thresholds gives
    the same training error, the middle of the range is taken.

    Parameters
    ----------
    images, masks : list of ndarray
        Training images (RGB ``uint8``) and their ground-truth shadow masks.
    config : ShadowConfig, optional
        Block geometry and propagation settings.
    features : tuple of str
        Block features, tested in this order at detection time.
    n_centroids : int
        Number of components ``k`` (1 to 8).
    thresholds : tuple of float
        Candidate fidelity thresholds; by default the bands of +-2 to +-126 value
        units in steps of 4 (:data:`MULTI_THRESHOLD_GRID`).
    seed : int
        ``random_state`` of :class:`sklearn.cluster.KMeans`.
    max_rounds : int
        Maximum passes of the coordinate descent.

    Returns
    -------
    ShadowModel
        With ``features``, ``centroids`` and ``thresholds`` set; ``meta`` records
        the training set size and the final training error.
    """
    cfg = config or ShadowConfig()
    grid = _check_multi_arguments(images, masks, features, n_centroids, thresholds)
    v, frac = _block_values(images, masks, cfg, features)
    shadow_values = _shadow_blocks(v, frac, n_centroids)
    labels, centroids, order = _cluster_centroids(shadow_values, cfg, n_centroids, seed)
    start = _start_thresholds(shadow_values, labels, centroids, order, grid)
    chosen, ber = _fit_thresholds(v, frac, centroids, grid, start, max_rounds)
    meta = {
        "trained_on": "images+masks",
        "images": len(images),
        "shadow_blocks": len(shadow_values),
        "n_centroids": n_centroids,
        "downsample": cfg.downsample,
        "grid": cfg.grid,
        "training_ber": round(ber, 4),
    }
    return ShadowModel(
        features[0],
        float(centroids[0, 0]),
        float(chosen[0, 0]),
        meta,
        tuple(features),
        tuple(tuple(float(c) for c in row) for row in centroids),
        tuple(tuple(float(t) for t in row) for row in chosen),
    )


def _check_multi_arguments(
    images: list[NDArray[np.uint8]],
    masks: list[NDArray[np.bool_]],
    features: tuple[str, ...],
    n_centroids: int,
    thresholds: tuple[float, ...],
) -> NDArray[np.float64]:
    """Check :func:`train_multi_shadow_model`'s arguments; the sorted threshold grid."""
    if len(images) != len(masks) or not images:
        raise ParameterError(
            "images/masks", f"{len(images)}/{len(masks)}", "equal, non-zero counts"
        )
    if not features or any(f not in FEATURES for f in features):
        raise ParameterError("features", features, "a non-empty tuple of " + str(FEATURES))
    if (
        isinstance(n_centroids, bool)
        or not isinstance(n_centroids, int)
        or not 1 <= n_centroids <= 8
    ):
        raise ParameterError("n_centroids", n_centroids, "an integer in [1, 8]")
    grid = np.unique(np.asarray(thresholds, dtype=np.float64))
    if grid.size == 0 or grid[0] < 0.0 or grid[-1] > 1.0:
        raise ParameterError("thresholds", thresholds, "a non-empty set of numbers in [0, 1]")
    return grid


def _block_values(
    images: list[NDArray[np.uint8]],
    masks: list[NDArray[np.bool_]],
    cfg: ShadowConfig,
    features: tuple[str, ...],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Block means of every feature ``(n_features, n_blocks)`` and the blocks' shadow
    fractions, over all images."""
    values, fractions = [], []
    for image, mask in zip(images, masks, strict=True):
        geometry = block_grid(image.shape[:2], cfg.downsample, cfg.grid)
        values.append(
            np.stack(
                [
                    block_means(feature_input(image, f), geometry, cfg.downsample).ravel()
                    for f in features
                ]
            )
        )
        fractions.append(block_shadow_fraction(mask, cfg).ravel())
    return np.concatenate(values, axis=1), np.concatenate(fractions)


def _shadow_blocks(
    values: NDArray[np.float64], fraction: NDArray[np.float64], n_centroids: int
) -> NDArray[np.float64]:
    """Feature values ``(n_blocks, n_features)`` of the blocks that are at least half shadow."""
    shadow_values = values[:, fraction >= 0.5].T
    if len(shadow_values) < n_centroids:
        raise ParameterError(
            "masks",
            f"{len(shadow_values)} shadow blocks",
            f"at least {n_centroids} blocks that are half shadow",
        )
    return shadow_values


def _cluster_centroids(
    shadow_values: NDArray[np.float64], cfg: ShadowConfig, n_centroids: int, seed: int
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.intp]]:
    """K-means labels of the shadow blocks, the trained centroids ``(k, n_features)`` in a
    deterministic order, and that order (cluster of each centroid row)."""
    from sklearn.cluster import KMeans

    labels = KMeans(n_clusters=n_centroids, n_init=10, random_state=seed).fit_predict(shadow_values)
    centroids = np.array(
        [
            [
                _train_centroid(
                    shadow_values[labels == j, f],
                    cfg,
                    start=float(shadow_values[labels == j, f].mean()),
                )
                for f in range(shadow_values.shape[1])
            ]
            for j in range(n_centroids)
        ]
    )
    order = np.lexsort(centroids.T[::-1])  # a deterministic component order
    return labels, centroids[order], order


def _start_thresholds(
    shadow_values: NDArray[np.float64],
    labels: NDArray[np.int64],
    centroids: NDArray[np.float64],
    order: NDArray[np.intp],
    grid: NDArray[np.float64],
) -> NDArray[np.intp]:
    """Per (component, feature): the grid index of the narrowest candidate band that holds
    :data:`_START_COVERAGE` of the component's cluster."""
    start = np.zeros(centroids.shape, dtype=np.intp)
    for j, cluster in enumerate(order):
        for f in range(centroids.shape[1]):
            members = fidelity(
                value_to_angle(centroids[j, f]),
                value_to_angle(shadow_values[labels == cluster, f]),
                shots=None,
            )
            q = np.quantile(members, 1.0 - _START_COVERAGE)
            start[j, f] = max(int(np.searchsorted(grid, q, side="right")) - 1, 0)
    return start


def _fit_thresholds(
    values: NDArray[np.float64],
    fraction: NDArray[np.float64],
    centroids: NDArray[np.float64],
    grid: NDArray[np.float64],
    start: NDArray[np.intp],
    max_rounds: int,
) -> tuple[NDArray[np.float64], float]:
    """Coordinate descent of the (k, F) threshold indices on the pixel-weighted BER."""
    k, n_features = centroids.shape
    n = values.shape[1]
    level = np.empty((k, n_features, n), dtype=np.intp)  # passes grid[t] <=> level > t
    for j in range(k):
        for f in range(n_features):
            scores = fidelity(
                value_to_angle(centroids[j, f]), value_to_angle(values[f]), shots=None
            )
            level[j, f] = np.searchsorted(grid, scores, side="right")
    index = start.copy()
    shadow_total, lit_total = fraction.sum(), (1.0 - fraction).sum()

    def passes(j: int, skip: int | None = None) -> NDArray[np.bool_]:
        ok = np.ones(n, dtype=bool)
        for f in range(n_features):
            if f != skip:
                ok &= level[j, f] > index[j, f]
        return ok

    def ber(accepted: NDArray[np.bool_]) -> float:
        missed = shadow_total - fraction[accepted].sum()
        false = (1.0 - fraction[accepted]).sum()
        return float(50.0 * (missed / max(shadow_total, 1e-12) + false / max(lit_total, 1e-12)))

    best = ber(np.any([passes(j) for j in range(k)], axis=0))
    for _ in range(max_rounds):
        improved = False
        for j in range(k):
            others = np.zeros(n, dtype=bool)
            for jj in range(k):
                if jj != j:
                    others |= passes(jj)
            for f in range(n_features):
                cand = ~others & passes(j, skip=f)
                lv = level[j, f, cand]
                bins = len(grid) + 1
                sh = np.bincount(lv, weights=fraction[cand], minlength=bins)
                lit = np.bincount(lv, weights=1.0 - fraction[cand], minlength=bins)
                # accepted at index t: level > t, i.e. the suffix sums from t + 1
                sh_acc = np.cumsum(sh[::-1])[::-1][1:] + fraction[others].sum()
                lit_acc = np.cumsum(lit[::-1])[::-1][1:] + (1.0 - fraction[others]).sum()
                curve = 50.0 * (
                    (shadow_total - sh_acc) / max(shadow_total, 1e-12)
                    + lit_acc / max(lit_total, 1e-12)
                )
                t = _middle_of_minimum(curve)
                if curve[t] < best - 1e-12:
                    improved = True
                if curve[t] <= best + 1e-12:
                    best, index[j, f] = min(best, float(curve[t])), t
        if not improved:
            break
    return grid[index], best


def _middle_of_minimum(curve: NDArray[np.float64]) -> int:
    """Index in the middle of the run of minimal values that holds the first minimum.

    Ties (a range of thresholds with the same training error, common on clean data) are
    broken towards the middle of the range: the widest margin on both sides.
    """
    first = int(np.argmin(curve))
    low = curve <= curve[first] + 1e-12
    last = first
    while last + 1 < len(curve) and low[last + 1]:
        last += 1
    return (first + last) // 2
