"""Shot sampling with exactly the statistics of measuring a circuit.

Measuring ``shots`` copies of a state in the computational basis gives counts
that are multinomial with the outcome probabilities (binomial for one qubit).
These functions draw those counts for a whole batch at once from a seeded
:class:`numpy.random.Generator`.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from qdcnn._validation import check_shots


def as_generator(seed: int | np.random.Generator | None) -> np.random.Generator:
    """A :class:`numpy.random.Generator` from a seed, or the generator itself."""
    return seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)


def sample_counts(
    probs: NDArray[np.float64], shots: int, rng: int | np.random.Generator | None = None
) -> NDArray[np.int64]:
    """Counts per outcome for each circuit, shape ``(B, d)``, summing to ``shots``.

    Parameters
    ----------
    probs : ndarray, shape (B, d)
        Exact outcome probabilities per circuit.
    shots : int
        Measurements per circuit.
    rng : int, Generator or None
        Seed or generator.
    """
    shots = check_shots(shots)
    gen = as_generator(rng)
    p = np.clip(np.asarray(probs, dtype=np.float64), 0.0, 1.0)
    if p.shape[-1] == 2:
        ones = gen.binomial(shots, p[:, 1] / (p[:, 0] + p[:, 1]))
        return np.stack([shots - ones, ones], axis=1).astype(np.int64)
    p = p / p.sum(axis=1, keepdims=True)
    return gen.multinomial(shots, p).astype(np.int64)


def sample_probabilities(
    probs: NDArray[np.float64], shots: int, rng: int | np.random.Generator | None = None
) -> NDArray[np.float64]:
    """Shot-estimated probabilities: :func:`sample_counts` divided by ``shots``."""
    return sample_counts(probs, shots, rng) / float(shots)


#: Probability grid of the binomial tables: one alias table per ``j / _GRID``, ``j <= _GRID / 2``.
_GRID = 2048
#: Probability mass left out of each table's window of counts (each tail below this).
_TAIL = 1e-18
#: Largest shot count with tables (about 2 MiB at 1024 shots); above it
#: :func:`binomial_counts` uses numpy's sampler.
MAX_TABLE_SHOTS = 4096


def binomial_counts(
    p: NDArray[np.float64], shots: int, rng: int | np.random.Generator | None = None
) -> NDArray[np.int64]:
    """Counts of outcome 1 in ``shots`` measurements of one-qubit circuits with ``P(1) = p``.

    The distribution of ``rng.binomial(shots, p)`` (binomial statistics, up to ~1e-12
    relative rounding of the tabulated probabilities and tails below 1e-18), drawn
    several times faster for thousands of circuits: with ``q = min(p, 1 - p)`` and
    ``q0 = floor(q * 2048) / 2048``, a count is ``X1 + X2``, where ``X1 ~ Bin(shots, q0)``
    comes from a cached alias table of ``q0`` (Walker's alias method: one uniform, two
    look-ups) and ``X2 ~ Bin(shots - X1, (q - q0) / (1 - q0))`` (each trial not yet a
    success succeeds with the remaining probability, so ``X1 + X2 ~ Bin(shots, q)``) has
    a mean below one half and is inverted term by term. ``p > 1/2`` counts the other
    outcome.

    Parameters
    ----------
    p : ndarray, shape (B,)
        ``P(1)`` of each circuit.
    shots : int
        Measurements per circuit.
    rng : int, Generator or None
        Seed or generator (two uniforms per circuit, in one draw).
    """
    shots = check_shots(shots)
    gen = as_generator(rng)
    prob = np.clip(np.asarray(p, dtype=np.float64).ravel(), 0.0, 1.0)
    if shots > MAX_TABLE_SHOTS:
        return gen.binomial(shots, prob).astype(np.int64)
    flip = prob > 0.5
    q = np.minimum(prob, 1.0 - prob)
    row = (q * _GRID).astype(np.intp)
    base = row * (1.0 / _GRID)
    uniform = gen.random(2 * q.size)
    counts = _alias_counts(row, uniform[: q.size], shots)
    q -= base
    q /= 1.0 - base  # what each trial not yet a success still succeeds with
    counts += _small_binomial(shots - counts, q, uniform[q.size :])
    np.subtract(shots, counts, out=counts, where=flip)
    return counts.astype(np.int64, copy=False)


def _alias_counts(row: NDArray[np.intp], u: NDArray[np.float64], shots: int) -> NDArray[np.intp]:
    """``Bin(shots, row / _GRID)`` draws by the alias method: the integer part of
    ``u * width`` picks a cell of the row's window, the fraction keeps its count or takes
    its alias's (one table read per draw: a cell holds ``alias + keep``)."""
    start, width, shift, cells = _alias_tables(shots)
    spot = u * width.take(row)
    cell = spot.astype(np.intp)
    spot -= cell
    cell += start.take(row)
    code = cells.take(cell)
    alias = code.astype(np.intp)
    code -= alias  # the probability of keeping the cell's own count
    return np.where(spot < code, cell + shift.take(row), alias)


@lru_cache(maxsize=2)
def _binomial_pmf(shots: int) -> NDArray[np.float64]:
    """``P(X = k)`` for ``X ~ Bin(shots, j / _GRID)``, rows ``j = 0 .. _GRID / 2``."""
    from scipy.special import gammaln, xlog1py, xlogy

    k = np.arange(shots + 1, dtype=np.float64)
    p = np.arange(_GRID // 2 + 1)[:, None] / _GRID
    log_choose = gammaln(shots + 1.0) - gammaln(k + 1.0) - gammaln(shots - k + 1.0)
    pmf = np.exp(log_choose + xlogy(k, p) + xlog1py(shots - k, -p))
    return pmf / pmf.sum(axis=1, keepdims=True)


@lru_cache(maxsize=2)
def _window_low(shots: int) -> NDArray[np.intp]:
    """First count of each row's window (tails below :data:`_TAIL` left out)."""
    cdf = np.cumsum(_binomial_pmf(shots), axis=1)
    return (cdf < _TAIL).sum(axis=1).astype(np.intp)


@lru_cache(maxsize=2)
def _alias_tables(
    shots: int,
) -> tuple[NDArray[np.intp], NDArray[np.float64], NDArray[np.intp], NDArray[np.float64]]:
    """Joined alias tables of every row: start and width of each row's window of counts,
    the shift from a cell's joined index to its count, and per cell ``alias + keep``: the
    count of its alias plus the probability (below 1) of keeping its own count.

    One float per cell keeps the table at about 1.8 MiB for 1024 shots (two arrays read
    at random cost twice the cache misses); ``keep`` is then resolved to 2^-42.
    """
    pmf = _binomial_pmf(shots)
    low = _window_low(shots)
    high = shots + 1 - (np.cumsum(pmf[:, ::-1], axis=1) < _TAIL).sum(axis=1)
    width = (high - low).astype(np.intp)
    start = np.concatenate([[0], np.cumsum(width)[:-1]]).astype(np.intp)
    cells = np.empty(int(width.sum()))
    for j in range(pmf.shape[0]):
        window = pmf[j, low[j] : high[j]]
        keep, alias = _vose(window / window.sum())
        always = keep >= 1.0  # no alias: "alias" is the cell itself, never kept
        keep[always], alias[always] = 0.0, np.flatnonzero(always)
        cells[start[j] : start[j] + width[j]] = alias + low[j] + keep
    shift = low - start
    tables = (start, width.astype(np.float64), shift, cells)
    for table in tables:
        table.setflags(write=False)
    return tables


def _vose(prob: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Vose's alias table of ``prob``: per cell, the probability of keeping it and its alias."""
    scaled = prob * prob.size
    keep = np.ones(prob.size)
    alias = np.arange(prob.size, dtype=np.intp)
    small = [i for i in range(prob.size) if scaled[i] < 1.0]
    large = [i for i in range(prob.size) if scaled[i] >= 1.0]
    while small and large:
        s, big = small.pop(), large.pop()
        keep[s], alias[s] = scaled[s], big
        scaled[big] -= 1.0 - scaled[s]
        (small if scaled[big] < 1.0 else large).append(big)
    return keep, alias  # cells left over keep (rounding) weight 1


def _small_binomial(
    trials: NDArray[np.intp], p: NDArray[np.float64], u: NDArray[np.float64]
) -> NDArray[np.intp]:
    """Inverse CDF of ``Bin(trials, p)`` at ``u``, term by term (for small means)."""
    term = np.exp(trials * np.log1p(-p))  # P(0)
    counts = np.zeros(trials.size, dtype=np.intp)
    open_ = np.flatnonzero(u >= term)  # at least one success
    if open_.size == 0:
        return counts
    n, ratio, u = trials.take(open_), p.take(open_), u.take(open_)
    ratio /= 1.0 - ratio
    term = term.take(open_)
    cdf = term.copy()
    extra = np.zeros(open_.size, dtype=np.intp)
    limit = int(n.max())
    for k in range(1, limit + 1):
        term *= (n - (k - 1)) * (ratio / k)  # P(k) from P(k - 1)
        cdf += term
        beyond = u >= cdf
        if not beyond.any():
            break
        extra += beyond
    counts[open_] = np.minimum(extra + 1, n)
    return counts


# --- inverse-CDF sampling with one uniform per circuit -------------------------------------
#
# A count drawn as ``min{k : F(k) >= u}`` with ``F`` the binomial CDF and ``u`` uniform on
# [0, 1) has exactly the binomial distribution, and "count <= limit" is then the event
# ``u <= F(limit)``. So a decision about the count (a block's sampled score reaching the
# threshold) needs one uniform and one CDF value per circuit, not the count itself; the
# count, from the same uniform, can be found later and agrees with the decision.

#: Probability grid of the CDF tables of :func:`binomial_at_most` (a power of two, so the
#: grid cell of ``p`` is exact).
CDF_GRID = 1 << 16


@lru_cache(maxsize=4)
def cdf_table(shots: int, limit: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``P(Bin(shots, j / G) <= limit)`` at the lower (``upper``) and upper (``lower``)
    grid point of each cell ``j = 0 .. G`` (the cell of ``p = 1`` is the point itself)."""
    from scipy.special import bdtr

    cdf = bdtr(limit, shots, np.arange(CDF_GRID + 1) / CDF_GRID)
    upper = cdf
    lower = np.append(cdf[1:], cdf[-1])
    for table in (upper, lower):
        table.setflags(write=False)
    return upper, lower


#: Grid cells per cell of :func:`coarse_cdf_brackets` (a power of two).
COARSE_CELLS = 64


@lru_cache(maxsize=4)
def coarse_cdf_brackets(shots: int, limit: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The lowest and highest of both :func:`cdf_table` brackets over each run of
    :data:`COARSE_CELLS` grid cells: a uniform at most the lowest passes, above the
    highest fails, in every cell of the run (the same decisions as the fine brackets)."""
    upper, lower = cdf_table(shots, limit)
    starts = np.arange(0, CDF_GRID + 1, COARSE_CELLS)
    low = np.minimum.reduceat(np.minimum(upper, lower), starts)
    high = np.maximum.reduceat(np.maximum(upper, lower), starts)
    for table in (low, high):
        table.setflags(write=False)
    return low, high


def binomial_at_most(
    p: NDArray[np.float64], shots: int, limit: int, u: NDArray[np.float64]
) -> NDArray[np.bool_]:
    """Whether the count ``min{k : P(Bin(shots, p) <= k) >= u}`` is at most ``limit``.

    That is ``u <= P(Bin(shots, p) <= limit)``, exactly: the CDF is decreasing in ``p``,
    so the tabulated values at the two grid points around ``p`` bracket it and settle
    almost every circuit; the few whose ``u`` falls between them (about one in a thousand
    of those near the limit) get the CDF at their own ``p`` (:func:`scipy.special.bdtr`).

    Parameters
    ----------
    p : ndarray
        ``P(1)`` of each circuit, in ``[0, 1]``.
    shots, limit : int
        Measurements per circuit and the largest count that passes.
    u : ndarray
        One uniform on ``[0, 1)`` per circuit.
    """
    if limit < 0:
        return np.zeros(np.shape(p), dtype=bool)
    if limit >= shots:
        return np.ones(np.shape(p), dtype=bool)
    upper, lower = cdf_table(shots, limit)
    cell = np.multiply(p, CDF_GRID).astype(np.intp)
    np.clip(cell, 0, CDF_GRID, out=cell)
    passed = u <= lower.take(cell)
    unsure = np.flatnonzero((u <= upper.take(cell)) != passed)
    settle_between_brackets(passed, unsure, p, u, shots, limit)
    return passed


def settle_between_brackets(
    passed: NDArray[np.bool_],
    unsure: NDArray[np.intp],
    p: NDArray[np.float64],
    u: NDArray[np.float64],
    shots: int,
    limit: int,
) -> bool:
    """Decide, in ``passed``, the circuits ``unsure`` whose uniform fell between the two
    tabulated brackets: ``u <= P(Bin(shots, p) <= limit)`` with the CDF at their own ``p``
    (:func:`scipy.special.bdtr`); whether a decision in ``passed`` changed. There are one
    or two such circuits in a frame, settled one by one with Python numbers: NumPy's cost
    per call on arrays that small (takes, a clip) was three times the work."""
    if unsure.size == 0:
        return False
    from scipy.special import bdtr

    changed = False
    for b in unsure.tolist():
        decision = bool(u[b] <= bdtr(limit, shots, min(max(float(p[b]), 0.0), 1.0)))
        changed |= decision != bool(passed[b])
        passed[b] = decision
    return changed


def inverse_binomial(
    p: NDArray[np.float64], shots: int, u: NDArray[np.float64]
) -> NDArray[np.int64]:
    """``min{k : P(Bin(shots, p) <= k) >= u}`` for each circuit: a ``Bin(shots, p)`` count
    from the uniform ``u`` (inverse transform sampling), the count that
    :func:`binomial_at_most` decides about."""
    from scipy.special import bdtr
    from scipy.stats import binom

    prob = np.clip(np.asarray(p, dtype=np.float64), 0.0, 1.0)
    with np.errstate(invalid="ignore"):
        guess = binom.ppf(u, shots, prob)
    counts = np.clip(np.nan_to_num(guess, nan=0.0), 0, shots).astype(np.int64)
    for _ in range(shots + 1):  # settle rounding in the guess: F(k) >= u > F(k - 1)
        up = (counts < shots) & (bdtr(counts, shots, prob) < u)
        down = (counts > 0) & (bdtr(counts - 1, shots, prob) >= u)
        if not (up.any() or down.any()):
            break
        counts += up
        counts -= down
    return counts
