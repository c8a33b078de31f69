"""Training the UU-dagger centroid: the paper's propagation algorithm (Sec. II-A-1; NOTES 3).

``R(a) R(-b)`` is a rotation by ``tau = a - b`` with trace ``D = 2 cos(tau)``. The
paper's update ``theta_{n+1} - theta_n = (d theta / dD) delta_D`` with
``delta_D = 2 cos(tau_n) - 2`` is a Newton step towards perfect overlap ``D = 2``.
With ``tau = x - theta`` it reads ``theta_{n+1} = theta_n + tan((x - theta_n) / 2)``,
which converges to ``x`` for ``|x - theta| < pi`` (the opposite sign diverges).
Because ``D`` has a double root at ``tau = 0`` the convergence is linear, not
quadratic: near the solution each step halves the distance.
Over a training set of angles ``x_i`` the step is averaged over ``i``; its fixed
point is where ``mean_i tan((x_i - theta)/2) = 0``, which for a tight cluster is
its mean.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from qdcnn.errors import ParameterError

# tan((x - theta)/2) diverges as |x - theta| -> pi; a step is capped at this size
# (radians) so that a far outlier cannot throw the centroid out of [0, pi].
_MAX_STEP = np.pi / 4


@dataclass
class PropagationResult:
    """Outcome of :func:`propagate_centroid`.

    Attributes
    ----------
    theta : float
        Trained centroid angle.
    history : list of float
        Angle after each iteration, starting with the initial guess.
    converged : bool
        Whether the last step was smaller than the tolerance.
    """

    theta: float
    history: list[float] = field(default_factory=list)
    converged: bool = False

    @property
    def iterations(self) -> int:
        return len(self.history) - 1


def propagation_step(
    theta: float, x: NDArray[np.float64], weights: NDArray[np.float64] | None = None
) -> float:
    """One averaged Newton step ``mean_i tan((x_i - theta) / 2)``, capped at :data:`_MAX_STEP`."""
    half = np.subtract(x, theta) * 0.5
    np.tan(np.clip(half, -1.5, 1.5, out=half), out=half)
    step = float(half.mean()) if weights is None else float(half @ weights) / float(weights.sum())
    return min(max(step, -_MAX_STEP), _MAX_STEP)


def propagate_centroid(
    angles: ArrayLike,
    theta0: float | None = None,
    *,
    iterations: int = 50,
    tol: float = 1e-9,
    weights: ArrayLike | None = None,
) -> PropagationResult:
    """Train a centroid angle on training angles with the propagation algorithm.

    Parameters
    ----------
    angles : array_like
        Training angles in radians (e.g. :func:`~qdcnn.quantum.uu_dagger.value_to_angle`
        of the values in a shadow crop).
    theta0 : float or None
        Initial guess; ``None`` starts from the median of ``angles``.
    iterations : int
        Maximum number of updates.
    tol : float
        Stop when an update moves the angle by less than this.
    weights : array_like, optional
        Non-negative weight of each angle (e.g. histogram counts).

    Returns
    -------
    PropagationResult
    """
    x = np.asarray(angles, dtype=np.float64).ravel()
    w = None if weights is None else np.asarray(weights, dtype=np.float64).ravel()
    if w is not None and (w.shape != x.shape or (w < 0).any()):
        raise ParameterError("weights", f"shape {w.shape}", f"non-negative, shape {x.shape}")
    keep = np.isfinite(x) if w is None else np.isfinite(x) & (w > 0)
    x, w = x[keep], None if w is None else w[keep]
    if x.size == 0:
        raise ParameterError("angles", "no finite values", "at least one training value")
    if iterations < 1:
        raise ParameterError("iterations", iterations, "at least 1")
    theta = float(np.median(x)) if theta0 is None else float(theta0)
    result = PropagationResult(theta, [theta])
    for _ in range(iterations):
        step = propagation_step(theta, x, w)
        theta += step
        result.history.append(theta)
        if abs(step) < tol:
            result.converged = True
            break
    result.theta = theta
    return result


def kmeans_start(
    values: ArrayLike, *, n_clusters: int = 2, seed: int = 0, pick: str = "lowest"
) -> float:
    """Initial centroid from scikit-learn k-means: the centre of the lowest (or highest) cluster.

    Parameters
    ----------
    values : array_like
        One-dimensional training values.
    n_clusters : int
        Clusters to fit.
    seed : int
        ``random_state`` of :class:`sklearn.cluster.KMeans`.
    pick : {"lowest", "highest"}
        Which cluster centre to return.
    """
    from sklearn.cluster import KMeans

    v = np.asarray(values, dtype=np.float64).reshape(-1, 1)
    k = min(n_clusters, len(np.unique(v)))
    if k < 1:
        raise ParameterError("values", "empty", "at least one value")
    centres = KMeans(n_clusters=k, n_init=1, random_state=seed).fit(v).cluster_centers_.ravel()
    if pick not in ("lowest", "highest"):
        raise ParameterError("pick", pick, "'lowest' or 'highest'")
    return float(centres.min() if pick == "lowest" else centres.max())


#: Widest spread of training angles for which :func:`propagation_fixed_point` answers:
#: below ``2 pi / 3`` the averaged step has one root in the angles' range and the
#: propagation iteration contracts towards it (``|d theta_{n+1} / d theta_n| < 1``).
MAX_FAST_SPREAD = 2.0 * np.pi / 3.0 - 1e-3


def propagation_fixed_point(
    sorted_angles: NDArray[np.float64],
    weights: NDArray[np.float64],
    theta0: float,
    *,
    iterations: int = 50,
    tol: float = 1e-9,
) -> float | None:
    """The centroid :func:`propagate_centroid` converges to, found by Newton's method.

    The propagation iteration ``theta += mean_w tan((x - theta) / 2)`` converges
    linearly (about one bit per step) to the root of ``F(theta) = sum_i w_i tan((x_i -
    theta) / 2)``; Newton's method on ``F`` (``F' = -sum_i w_i (1 + tan^2) / 2``) reaches
    the same root quadratically, in three or four steps instead of thirty. The answer
    is that root, which the propagation result approaches to within its tolerance.

    Returns ``None`` (the caller then runs :func:`propagate_centroid`) unless the
    propagation is known to reach the root within ``iterations`` steps: with ``d`` the
    distance from ``theta0`` to the root, every iterate stays within ``d`` of it, so
    ``|x_i - theta| <= spread + d``; below ``2 pi / 3`` the iteration is then a
    contraction with factor ``rho = max(1/2, sec^2((spread + d) / 2) / 2 - 1)`` (no
    step is clipped, and ``d <= pi / 8`` keeps steps under the cap), and ``rho`` gives
    at most ``iterations`` steps to ``tol``.

    Parameters
    ----------
    sorted_angles : ndarray
        Training angles in increasing order.
    weights : ndarray
        Positive weight of each angle.
    theta0 : float
        Start of the propagation.
    """
    lo, hi = float(sorted_angles[0]), float(sorted_angles[-1])
    if hi - lo >= MAX_FAST_SPREAD:
        return None
    theta = _newton_root(sorted_angles * 0.5, weights, theta0)
    if theta is None:
        return None
    distance = abs(theta - theta0)
    reach = hi - lo + distance
    if reach >= MAX_FAST_SPREAD or distance > np.pi / 8:
        return None
    rho = max(0.5, 0.5 / np.cos(reach / 2.0) ** 2 - 1.0)
    needed = 0.0 if distance <= tol else np.log(tol / distance) / np.log(rho) + 2.0
    return theta if needed <= iterations else None


def _newton_root(
    half_angles: NDArray[np.float64], weights: NDArray[np.float64], theta: float
) -> float | None:
    """Root of ``sum_i w_i tan(x_i / 2 - theta / 2)`` by Newton's method from ``theta``;
    ``None`` if it has not settled within a dozen steps."""
    total = float(weights.sum())
    for _ in range(12):
        t = np.subtract(half_angles, 0.5 * theta)
        np.tan(t, out=t)
        step = 2.0 * float(t @ weights) / (float((t * t) @ weights) + total)
        theta += step
        if abs(step) < 1e-8:  # quadratic convergence: what is left is below 1e-15
            return theta
    return None
