"""Compiled per-block steps of the UU-dagger shadow detector (issue 22), with Numba.

The NumPy detector (:mod:`qdcnn.vision.shadows`) spends most of a 320x160 frame on
the fixed cost of some forty small array calls: the block sums, the per-image
calibration (Otsu's split and the propagation's fixed point), the decisions and the
expansion of the block mask with its median filter. These kernels do the same
arithmetic in one compiled loop each:

- :func:`block_sums`: the sum of each block's pixels (what the summed-area corners give);
- :func:`band_mask`, :func:`score_mask`, :func:`shot_mask`: the decisions of a repeated
  centroid's band, of the exact scores, and of one uniform per circuit with shots;
- :func:`calibrate`: Otsu's two-class split of the block means (numpy's histogram
  bins and scikit-image's float32 sums, as :func:`~qdcnn.vision.otsu.otsu_threshold`)
  and the propagation's fixed point by Newton's method
  (:func:`~qdcnn.quantum.centroid.propagation_fixed_point`);
- :func:`expand_median`: the block mask at image size, median filtered with replicated
  borders (a box sum, as :func:`~qdcnn.vision.shadows.binary_median`).

Every kernel gives the NumPy path's results bit for bit, except the calibrated centroid,
whose Newton steps use libm's tangent and sequential dot products instead of NumPy's
SIMD tangent and BLAS: it agrees to a few units in the last place
(``tests/vision/test_block_kernels.py``). Compiled code is cached on disk
(``cache=True``), so a process pays for compilation only the first time.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

_JIT: dict[str, Any] = {"cache": True, "nogil": True, "boundscheck": False}


@njit(**_JIT)
def block_sums(grey: Any, row_edges: Any, col_edges: Any, area: Any) -> Any:
    """Pixel sum and mean of each block of a ``uint8`` image; blocks span
    ``row_edges[i]:row_edges[i + 1]`` by ``col_edges[j]:col_edges[j + 1]`` (pixels) and
    hold ``area[i, j]`` pixels. Where every column edge falls on a group of four pixels
    (the default downsampling, 4) the rows are read as 32-bit words
    (:func:`_block_sums_by_word`); else pixel by pixel."""
    if _in_words(grey, row_edges, col_edges):
        sums = _block_sums_by_word(grey.view(np.uint32), row_edges, col_edges)
    else:
        sums = _block_sums_by_pixel(grey, row_edges, col_edges)
    return sums, _means(sums, row_edges, col_edges, area)


@njit(**_JIT)
def _means(sums: Any, row_edges: Any, col_edges: Any, area: Any) -> Any:
    """``sums / area``, ``area`` being each block's height times its width (as the edges
    give them). Where every block's height and width are powers of two (the default
    geometry at 320x160) each sum is multiplied by its block's inverse area instead, the
    same number exactly and a quarter of the time of 3,160 divisions."""
    heights, widths = np.diff(row_edges), np.diff(col_edges)
    for extent in (heights, widths):
        for k in range(extent.size):
            if extent[k] & (extent[k] - 1):
                return sums / area
    means = np.empty(sums.shape, np.float64)
    inverse_widths = 1.0 / widths
    for i in range(sums.shape[0]):
        inverse_height = 1.0 / heights[i]
        for j in range(sums.shape[1]):
            means[i, j] = sums[i, j] * (inverse_height * inverse_widths[j])
    return means


@njit(**_JIT)
def _in_words(grey: Any, row_edges: Any, col_edges: Any) -> bool:
    """Whether :func:`_block_sums_by_word` can sum these blocks of a ``uint8`` image (its
    bytes are read as unsigned): rows of aligned 4-pixel words, increasing column edges on
    word boundaries, and blocks at most 128 rows tall (each 16-bit lane of a word's
    accumulator adds two pixels a row, at most 510)."""
    if grey.shape[1] % 4 or grey.strides[1] != 1 or grey.strides[0] % 4 or grey.ctypes.data % 4:
        return False
    for j in range(col_edges.size):
        if col_edges[j] % 4 or (j and col_edges[j] <= col_edges[j - 1]):
            return False
    for i in range(row_edges.size - 1):
        if row_edges[i + 1] - row_edges[i] > 128:
            return False
    return True


@njit(**_JIT)
def _block_sums_by_pixel(grey: Any, row_edges: Any, col_edges: Any) -> Any:
    """:func:`block_sums`' sums: each block row's pixel columns summed, then a prefix sum
    along the row and its differences at the column edges."""
    gh, gw = row_edges.size - 1, col_edges.size - 1
    width = grey.shape[1]
    sums = np.empty((gh, gw), np.int64)
    acc = np.empty(width, np.int32)
    prefix = np.empty(width + 1, np.int64)
    prefix[0] = 0
    for i in range(gh):
        acc[:] = 0
        for r in range(row_edges[i], row_edges[i + 1]):
            for c in range(width):
                acc[c] += grey[r, c]
        total = 0
        for c in range(width):
            total += acc[c]
            prefix[c + 1] = total
        for j in range(gw):
            sums[i, j] = prefix[col_edges[j + 1]] - prefix[col_edges[j]]
    return sums


@njit(**_JIT)
def _block_sums_by_word(words: Any, row_edges: Any, col_edges: Any) -> Any:
    """:func:`block_sums`' sums from rows read as 32-bit words of four pixels. Each word's
    bytes are added in pairs (two 16-bit lanes, masks and a shift the compiler
    vectorises), the lanes of a block row's words give its 4-pixel column sums, and each
    block is the column sum of its first word plus those of any further words. The prefix
    sum along every pixel row and its differences cost 7 of 11 us at 320x160, a chain of
    dependent adds and a gather per block that stayed scalar; here 5.9 us."""
    gh, gw = row_edges.size - 1, col_edges.size - 1
    first, extra_block, extra_word = _words_of_blocks(col_edges)
    sums = np.empty((gh, gw), np.int64)
    lanes = np.empty(words.shape[1], np.uint32)
    quads = np.empty(words.shape[1], np.int64)
    for i in range(gh):
        lanes[:] = 0
        for r in range(row_edges[i], row_edges[i + 1]):
            for c in range(lanes.size):
                w = words[r, c]
                lanes[c] += (w & 0x00FF00FF) + ((w >> 8) & 0x00FF00FF)
        for c in range(lanes.size):
            quads[c] = (lanes[c] & 0xFFFF) + (lanes[c] >> 16)
        row = sums[i]
        for j in range(gw):
            row[j] = quads[first[j]]
        for k in range(extra_block.size):
            row[extra_block[k]] += quads[extra_word[k]]
    return sums


@njit(**_JIT)
def _words_of_blocks(col_edges: Any) -> Any:
    """Each block's first word, and (block, word) for every further word of a block wider
    than four pixels."""
    gw = col_edges.size - 1
    first = col_edges[:-1] >> 2
    n_extra = (col_edges[-1] - col_edges[0]) // 4 - gw
    extra_block = np.empty(n_extra, np.intp)
    extra_word = np.empty(n_extra, np.intp)
    k = 0
    for j in range(gw):
        for m in range(first[j] + 1, col_edges[j + 1] >> 2):
            extra_block[k], extra_word[k] = j, m
            k += 1
    return first, extra_block, extra_word


@njit(**_JIT)
def calibrate_blocks(
    grey: Any,
    row_edges: Any,
    col_edges: Any,
    area: Any,
    tan_table: Any,
    settings: Any,
) -> Any:
    """:func:`block_sums` and :func:`calibrate_with` in one call."""
    sums, means = block_sums(grey, row_edges, col_edges, area)
    return sums, means, calibrate_with(means.ravel(), tan_table, settings)


@njit(**_JIT)
def calibrate_with(values: Any, tan_table: Any, settings: Any) -> float:
    """:func:`calibrate` of block means ``values``; ``settings`` holds its numbers (bin
    width, angle per value, iterations, tolerance, spread)."""
    bin_width, angle_per_value, tol, spread = settings[0], settings[1], settings[3], settings[4]
    return calibrate(values, bin_width, angle_per_value, tan_table, int(settings[2]), tol, spread)


@njit(**_JIT)
def detect_calibrated(
    grey: Any,
    edges: Any,
    tan_table: Any,
    settings: Any,
    amplitudes: Any,
    threshold: float,
    row_of: Any,
    col_of: Any,
    ksize: int,
) -> Any:
    """:func:`calibrate_blocks` and :func:`detect_scores` in one call: the exact
    detection with the centroid calibrated on the frame (``edges``: the block edges in
    pixels and the areas; ``settings[5]``: value per angle). The centroid comes back in
    value units, clipped to ``[0, 255]``; NaN, with empty scores and masks, where the
    fixed point has no answer (the caller then calibrates with NumPy)."""
    sums, means, theta = calibrate_blocks(grey, *edges, tan_table, settings)
    if np.isnan(theta):
        empty = np.empty((0, 0), np.uint8)
        return sums, means, theta, np.empty(0), empty, empty.view(np.bool_)
    centroid, cos_c, sin_c = _centroid_state(theta, settings)
    scores, blocks, mask = detect_scores(
        sums, amplitudes, cos_c, sin_c, threshold, row_of, col_of, ksize
    )
    return sums, means, centroid, scores, blocks, mask


@njit(**_JIT)
def detect_calibrated_shots(
    grey: Any,
    edges: Any,
    tan_table: Any,
    settings: Any,
    amplitudes: Any,
    u: Any,
    tables: Any,
    grid: int,
    row_of: Any,
    col_of: Any,
    ksize: int,
) -> Any:
    """:func:`calibrate_blocks` and :func:`detect_shots` in one call: the shot-sampled
    detection with the centroid calibrated on the frame, one uniform per block in ``u``.
    The centroid as in :func:`detect_calibrated` (NaN, with empty results, where the
    fixed point has no answer)."""
    sums, means, theta = calibrate_blocks(grey, *edges, tan_table, settings)
    if np.isnan(theta):
        empty = np.empty((0, 0), np.uint8)
        return sums, means, theta, np.empty(0), empty, np.empty(0, np.intp), empty.view(np.bool_)
    centroid, cos_c, sin_c = _centroid_state(theta, settings)
    p, blocks, unsure, mask = detect_shots(
        sums, amplitudes, cos_c, sin_c, u, tables, grid, row_of, col_of, ksize
    )
    return sums, means, centroid, p, blocks, unsure, mask


@njit(**_JIT)
def _centroid_state(theta: float, settings: Any) -> Any:
    """The calibrated centroid in value units, clipped to ``[0, 255]``, and the cosine and
    sine of its half angle (``settings[5]``: value per angle, ``settings[1]``: angle per
    value), as the two fused detections take them."""
    centroid = min(max(theta * settings[5], 0.0), 255.0)
    half = centroid * settings[1] / 2.0
    return centroid, math.cos(half), math.sin(half)


@njit(**_JIT)
def band_mask(sums: Any, size_index: Any, low: Any, width: Any) -> Any:
    """Blocks whose sum lies in its size's band ``low <= sum <= low + width``."""
    out = np.empty(sums.shape, np.uint8)
    flat, decided = sums.ravel(), out.ravel()
    for b in range(flat.size):
        s = size_index[b]
        decided[b] = np.uint64(flat[b] - low[s]) <= width[s]
    return out


@njit(**_JIT)
def detect_band(
    grey: Any,
    row_edges: Any,
    col_edges: Any,
    area: Any,
    band: Any,
    row_of: Any,
    col_of: Any,
    ksize: int,
) -> Any:
    """:func:`block_sums`, :func:`band_mask` (``band``: size index per block, band
    starts and widths per size) and :func:`expand_median` in one call: a repeated
    centroid's exact detection."""
    sums, means = block_sums(grey, row_edges, col_edges, area)
    decided = band_mask(sums, band[0], band[1], band[2])
    return sums, means, decided, expand_median(decided, row_of, col_of, ksize)


@njit(**_JIT)
def _scores(
    sums: Any, offsets: Any, cos_half: Any, sin_half: Any, cos_c: float, sin_c: float
) -> Any:
    """Exact fidelities ``(cos_x cos_c + sin_x sin_c)^2`` of the looked-up test states."""
    flat = sums.ravel()
    out = np.empty(flat.size, np.float64)
    for b in range(flat.size):
        k = offsets[b] + flat[b]
        amp = cos_half[k] * cos_c
        amp += sin_half[k] * sin_c
        out[b] = amp * amp
    return out


@njit(**_JIT)
def score_mask(
    sums: Any,
    offsets: Any,
    cos_half: Any,
    sin_half: Any,
    cos_c: float,
    sin_c: float,
    threshold: float,
) -> Any:
    """Exact scores of the blocks and the blocks at or above ``threshold``."""
    scores = _scores(sums, offsets, cos_half, sin_half, cos_c, sin_c)
    return scores, (scores >= threshold).view(np.uint8)


@njit(**_JIT)
def detect_shot_table(
    grey: Any,
    row_edges: Any,
    col_edges: Any,
    area: Any,
    offsets: Any,
    passing: Any,
    u: Any,
    row_of: Any,
    col_of: Any,
    ksize: int,
) -> Any:
    """A repeated centroid's detection with shots: :func:`block_sums`, each block passing
    when its uniform is at most ``passing[offsets[b] + sum_b]`` (the probability that the
    circuit of that block sum passes, :func:`~qdcnn.quantum.sampling.binomial_at_most`),
    and :func:`expand_median`, in one call."""
    sums, means = block_sums(grey, row_edges, col_edges, area)
    decided = np.empty(sums.shape, np.uint8)
    flat, out = sums.ravel(), decided.ravel()
    for b in range(flat.size):
        out[b] = u[b] <= passing[offsets[b] + flat[b]]
    return sums, means, decided, expand_median(decided, row_of, col_of, ksize)


@njit(**_JIT)
def detect_scores(
    sums: Any,
    amplitudes: Any,
    cos_c: float,
    sin_c: float,
    threshold: float,
    row_of: Any,
    col_of: Any,
    ksize: int,
) -> Any:
    """:func:`score_mask` and :func:`expand_median` in one call; ``amplitudes`` is the
    looked-up tables ``(offsets, cos_half, sin_half)``."""
    scores, decided = score_mask(sums, *amplitudes, cos_c, sin_c, threshold)
    blocks = decided.reshape(sums.shape)
    return scores, blocks, expand_median(blocks, row_of, col_of, ksize)


@njit(**_JIT)
def detect_shots(
    sums: Any,
    amplitudes: Any,
    cos_c: float,
    sin_c: float,
    u: Any,
    tables: Any,
    grid: int,
    row_of: Any,
    col_of: Any,
    ksize: int,
) -> Any:
    """:func:`shot_mask` and :func:`expand_median` in one call (``tables``: the fine and
    coarse CDF brackets). Blocks left between the brackets are in the mask with their
    first guess: the caller settles them and expands again if one of them changed."""
    p, passed, unsure = shot_mask(sums, *amplitudes, cos_c, sin_c, u, tables, grid)
    blocks = passed.view(np.uint8).reshape(sums.shape)
    return p, blocks, unsure, expand_median(blocks, row_of, col_of, ksize)


@njit(**_JIT)
def shot_mask(
    sums: Any,
    offsets: Any,
    cos_half: Any,
    sin_half: Any,
    cos_c: float,
    sin_c: float,
    u: Any,
    tables: Any,
    grid: int,
) -> Any:
    """``P(1) = 1 - score`` of each block, its decision ``u <= F(limit)`` from the
    bracketing CDF tables, and the blocks whose ``u`` falls between the brackets (decided
    here by a first guess, the CDF interpolated across the cell; the caller settles those
    with the CDF at their own ``p``), as
    :func:`~qdcnn.quantum.sampling.binomial_at_most`. ``tables`` is the fine brackets
    ``(lower, upper)`` per grid cell and the coarse ones ``(low, high)`` per
    :data:`~qdcnn.quantum.sampling.COARSE_CELLS` cells (the lowest and highest fine
    bracket in them, a few kilobytes): most blocks are settled by the coarse ones, so few
    reads go to the megabyte of fine tables."""
    lower, upper, low, high = tables
    p = _scores(sums, offsets, cos_half, sin_half, cos_c, sin_c)
    cells = np.empty(p.size, np.int32)
    for b in range(p.size):  # the grid cells first, a loop the compiler vectorises
        p[b] = 1.0 - p[b]
        cells[b] = min(max(int(p[b] * grid), 0), grid)
    passed = np.empty(p.size, np.bool_)
    unsure = np.empty(p.size, np.intp)
    n_unsure = 0
    shift = int(math.log2(grid // (low.size - 1)))
    for b in range(p.size):
        cell = cells[b]
        coarse = cell >> shift
        if u[b] <= low[coarse] or u[b] > high[coarse]:
            passed[b] = u[b] <= low[coarse]
            continue
        passed[b] = u[b] <= lower[cell]
        if (u[b] <= upper[cell]) != passed[b]:
            # a first guess from the CDF interpolated across the cell (the caller settles
            # the block): right unless u lies between that line and the curve, so the
            # mask seldom has to be expanded again
            guess = upper[cell] + (lower[cell] - upper[cell]) * (p[b] * grid - cell)
            passed[b] = u[b] <= guess
            unsure[n_unsure] = b
            n_unsure += 1
    return p, passed, unsure[:n_unsure]


@njit(**_JIT)
def expand_median(block_mask: Any, row_of: Any, col_of: Any, ksize: int) -> Any:
    """The 0/1 block mask at image size (``row_of``/``col_of``: each pixel's block), then
    the ``ksize`` median with replicated borders: 1 where more than half of the window is
    1 (``ksize * ksize <= 255``). Each block row is expanded and box-summed along the
    columns once, and the image rows are running sums of those."""
    height, width = row_of.size, col_of.size
    rad = ksize // 2
    half = np.uint8((ksize * ksize) // 2)
    rows = _row_box_sums(block_mask, col_of, rad)
    out = np.empty((height, width), np.uint8)
    acc = np.zeros(width, np.uint8)
    for d in range(-rad, rad + 1):
        top = row_of[min(max(d, 0), height - 1)]
        for c in range(width):
            acc[c] += rows[top, c]
    for r in range(height):
        if r > 0:
            enter, leave = row_of[min(r + rad, height - 1)], row_of[max(r - rad - 1, 0)]
            for c in range(width):
                acc[c] = acc[c] + rows[enter, c] - rows[leave, c]
        for c in range(width):
            out[r, c] = acc[c] > half
    return out.view(np.bool_)


@njit(**_JIT)
def _row_box_sums(block_mask: Any, col_of: Any, rad: int) -> Any:
    """Each block row expanded to image width and summed over ``2 rad + 1`` columns
    (replicated borders). Where every aligned group of four columns lies in one block
    (the default downsampling, 4, on a width it divides), a row is expanded four pixels
    at a time (:func:`_row_box_sums_by_four`); else pixel by pixel."""
    if _in_groups_of_four(col_of):
        return _row_box_sums_by_four(block_mask, col_of, rad)
    return _row_box_sums_by_pixel(block_mask, col_of, rad)


@njit(**_JIT)
def _row_box_sums_by_pixel(block_mask: Any, col_of: Any, rad: int) -> Any:
    """:func:`_row_box_sums`: each row is written once into a buffer padded with ``rad``
    copies of its end pixels, and the window sums are ``2 rad + 1`` shifted adds of that
    buffer, loops the compiler vectorises."""
    gh, width = block_mask.shape[0], col_of.size
    rows = np.zeros((gh, width), np.uint8)
    padded = np.empty(width + 2 * rad, np.uint8)
    for i in range(gh):
        blocks = block_mask[i]
        for c in range(width):
            padded[rad + c] = blocks[col_of[c]]
        for c in range(rad):
            padded[c] = padded[rad]
            padded[rad + width + c] = padded[rad + width - 1]
        row = rows[i]
        for d in range(2 * rad + 1):
            for c in range(width):
                row[c] += padded[c + d]
    return rows


@njit(**_JIT)
def _in_groups_of_four(col_of: Any) -> bool:
    """Whether every aligned group of four columns lies in one block."""
    if col_of.size % 4:
        return False
    for c in range(col_of.size):
        if col_of[c] != col_of[c - c % 4]:
            return False
    return True


@njit(**_JIT)
def _row_box_sums_by_four(block_mask: Any, col_of: Any, rad: int) -> Any:
    """:func:`_row_box_sums_by_pixel` with each row expanded by one 32-bit word per group
    of four pixels (the block's 0 or 1 in each byte): a quarter of the reads of the block
    row, which were the expansion's cost (7.7 -> 4.3 us at 320x160). The row is then
    copied into the padded buffer, whose 4-byte words sit ``rad`` bytes off alignment.

    The two functions repeat their window sums on purpose: with both expansions in one
    function, or the shared loops in a helper, the compiler left the sums unvectorised
    (14-22 us; docs/speed-kernels.md)."""
    gh, width = block_mask.shape[0], col_of.size
    rows = np.zeros((gh, width), np.uint8)
    line = np.empty(width, np.uint8)
    words = line.view(np.uint32)
    padded = np.empty(width + 2 * rad, np.uint8)
    for i in range(gh):
        blocks = block_mask[i]
        for k in range(width // 4):
            words[k] = np.uint32(blocks[col_of[4 * k]]) * np.uint32(0x01010101)
        for c in range(width):
            padded[rad + c] = line[c]
        for c in range(rad):
            padded[c] = padded[rad]
            padded[rad + width + c] = padded[rad + width - 1]
        row = rows[i]
        for d in range(2 * rad + 1):
            for c in range(width):
                row[c] += padded[c + d]
    return rows


@njit(**_JIT)
def _pairwise_block(a: Any, lo: int, n: int) -> float:
    """NumPy's pairwise sum of at most 128 values: eight running sums, then a tree."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    # eight scalars, not an array of eight: no allocation per block (18 at 320x160)
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - n % 8:
        j = lo + i
        r0, r1, r2, r3 = r0 + a[j], r1 + a[j + 1], r2 + a[j + 2], r3 + a[j + 3]
        r4, r5, r6, r7 = r4 + a[j + 4], r5 + a[j + 5], r6 + a[j + 6], r7 + a[j + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    for k in range(lo + i, lo + n):
        res += a[k]
    return res


@njit(**_JIT)
def _pairwise_sum(a: Any, lo: int, n: int) -> float:
    """NumPy's pairwise summation of ``a[lo:lo + n]`` (``np.add.reduce``), bit for bit:
    halves (the first a multiple of 8 long) summed separately down to 128 values. Its
    recursion runs on an explicit stack (a recursive kernel does not cache)."""
    starts = np.empty(64, np.intp)
    sizes = np.empty(64, np.intp)
    left = np.empty(64, np.float64)
    stage = np.zeros(64, np.int8)  # 0: new, 1: left half pending, 2: right half pending
    top = 0
    starts[0], sizes[0], stage[0] = lo, n, 0
    while True:
        m = sizes[top]
        if m > 128 and stage[top] == 0:
            half = m // 2 - (m // 2) % 8
            stage[top] = 1
            starts[top + 1], sizes[top + 1], stage[top + 1] = starts[top], half, 0
            top += 1
            continue
        value = _pairwise_block(a, starts[top], m)
        top -= 1
        while top >= 0 and stage[top] == 2:
            value = left[top] + value
            top -= 1
        if top < 0:
            return value
        left[top], stage[top] = value, 2
        half = sizes[top] // 2 - (sizes[top] // 2) % 8
        starts[top + 1], sizes[top + 1], stage[top + 1] = starts[top] + half, sizes[top] - half, 0
        top += 1


@njit(**_JIT)
def _value_range(values: Any) -> Any:
    """The smallest and largest of ``values`` (not NaN), in four running pairs: one pair
    is a chain of dependent comparisons (2.2 against 1.1 us for 3,160 values)."""
    lo0 = lo1 = lo2 = lo3 = hi0 = hi1 = hi2 = hi3 = values[0]
    n4 = values.size - values.size % 4
    for t in range(0, n4, 4):
        v0, v1, v2, v3 = values[t], values[t + 1], values[t + 2], values[t + 3]
        lo0, hi0 = (v0 if v0 < lo0 else lo0), (v0 if v0 > hi0 else hi0)
        lo1, hi1 = (v1 if v1 < lo1 else lo1), (v1 if v1 > hi1 else hi1)
        lo2, hi2 = (v2 if v2 < lo2 else lo2), (v2 if v2 > hi2 else hi2)
        lo3, hi3 = (v3 if v3 < lo3 else lo3), (v3 if v3 > hi3 else hi3)
    first, last = min(min(lo0, lo1), min(lo2, lo3)), max(max(hi0, hi1), max(hi2, hi3))
    for t in range(n4, values.size):
        first, last = min(first, values[t]), max(last, values[t])
    return first, last


@njit(**_JIT)
def _levels(values: Any, bin_width: float) -> Any:
    """``rint(values / bin_width)``. A power-of-two width divides exactly as a product
    with its inverse, which the compiler vectorises better (the calibration's width,
    0.25); any other divides."""
    level = np.empty(values.size, np.intp)
    if math.frexp(bin_width)[0] == 0.5:
        per_bin = 1.0 / bin_width
        for t in range(values.size):  # vectorised: no branch
            level[t] = int(np.rint(values[t] * per_bin))
    else:
        for t in range(values.size):
            level[t] = int(np.rint(values[t] / bin_width))
    return level


@njit(**_JIT)
def otsu_threshold(values: Any, nbins: int, first: float, last: float) -> float:
    """:func:`qdcnn.vision.otsu.otsu_threshold` of values spanning ``[first, last]``,
    ``first < last``: numpy's bins (edges ``first + i * step``, the last one ``last``,
    each value moved at most one bin to its side of them), scikit-image's float32 weights
    and float64 moments summed in the same order, and the first largest between-class
    variance. Each value's bin is found in a loop without branches, which the compiler
    vectorises (a branch per value cost more than the counting); few other arrays."""
    step = (last - first) / nbins
    scale = nbins / (last - first)
    bins = np.empty(values.size, np.intp)
    for t in range(values.size):
        x = values[t]
        b = min(int((x - first) * scale), nbins - 1)
        upper = (b + 1) * step + first if b + 1 < nbins else last
        below = x < b * step + first
        bins[t] = b - below + (not below and b < nbins - 1 and x >= upper)
    counts = np.zeros(nbins, np.intp)
    for b in bins:
        counts[b] += 1
    # suffix weights and moments (the reversed cumulative sums), then one forward pass
    tail = np.empty((2, nbins), np.float64)
    weight2, moment2 = np.float32(0.0), 0.0
    for i in range(nbins - 1, -1, -1):
        weight2 += np.float32(counts[i])
        moment2 += counts[i] * _centre(i, nbins, step, first, last)
        tail[0, i], tail[1, i] = weight2, moment2 / np.float64(weight2)
    weight1, moment1, best, at = np.float32(0.0), 0.0, -np.inf, 0
    for i in range(nbins - 1):
        weight1 += np.float32(counts[i])
        moment1 += counts[i] * _centre(i, nbins, step, first, last)
        gap = moment1 / np.float64(weight1) - tail[1, i + 1]
        variance = np.float64(weight1 * np.float32(tail[0, i + 1])) * (gap * gap)
        if variance > best:
            best, at = variance, i
    return _centre(at, nbins, step, first, last)


@njit(**_JIT)
def _centre(i: int, nbins: int, step: float, first: float, last: float) -> float:
    """Centre of bin ``i``: the mean of its two numpy edges."""
    upper = (i + 1) * step + first if i + 1 < nbins else last
    return (i * step + first + upper) / 2.0


@njit(**_JIT)
def _newton_root(tan_half: Any, weights: Any, theta: float) -> float:
    """:func:`qdcnn.quantum.centroid._newton_root` from ``tan(x_i / 2)``: each
    ``tan(x_i / 2 - theta / 2)`` by the difference formula, one tangent a step; NaN
    where it does not settle."""
    total = _pairwise_sum(weights, 0, weights.size)
    for _ in range(12):
        tb = math.tan(0.5 * theta)
        num, den = 0.0, 0.0
        for i in range(tan_half.size):
            t = (tan_half[i] - tb) / (1.0 + tan_half[i] * tb)
            num += t * weights[i]
            den += t * t * weights[i]
        step = 2.0 * num / (den + total)
        theta += step
        if abs(step) < 1e-8:
            return theta
    return np.nan


@njit(**_JIT)
def fixed_point(
    angles: Any,
    tan_half: Any,
    weights: Any,
    theta0: float,
    iterations: int,
    tol: float,
    max_spread: float,
) -> float:
    """:func:`qdcnn.quantum.centroid.propagation_fixed_point`; NaN where it has no answer."""
    lo, hi = angles[0], angles[-1]
    if hi - lo >= max_spread:
        return np.nan
    theta = _newton_root(tan_half, weights, theta0)
    if np.isnan(theta):
        return theta
    distance = abs(theta - theta0)
    reach = hi - lo + distance
    if reach >= max_spread or distance > np.pi / 8:
        return np.nan
    rho = max(0.5, 0.5 / math.cos(reach / 2.0) ** 2 - 1.0)
    needed = 0.0 if distance <= tol else math.log(tol / distance) / math.log(rho) + 2.0
    return theta if needed <= iterations else np.nan


@njit(**_JIT)
def calibrate(
    values: Any,
    bin_width: float,
    angle_per_value: float,
    tan_table: Any,
    iterations: int,
    tol: float,
    max_spread: float,
) -> float:
    """The calibrated centroid angle of :func:`~qdcnn.vision.shadows.calibrate_centroid`
    (two classes, intensity: the dark class of Otsu's split, all values when constant);
    NaN where the fixed point has no answer (the caller then runs the NumPy calibration
    and its propagation). ``tan_table[k]`` is the tangent of half the angle of level
    ``k`` (value ``k * bin_width``)."""
    first, last = _value_range(values)
    cut = otsu_threshold(values, 256, first, last) if first < last else last
    level = _levels(values, bin_width)
    cluster = np.empty(values.size, np.float64)
    counts = np.zeros(int(np.rint(last / bin_width)) + 1, np.intp)
    n = 0
    for t in range(values.size):  # the dark class, in order, without a branch per value
        dark = values[t] <= cut
        cluster[n] = values[t]
        n += dark
        counts[level[t]] += dark
    start = _pairwise_sum(cluster, 0, n) / n
    levels = np.flatnonzero(counts)
    angles = levels.astype(np.float64) * bin_width
    angles *= angle_per_value
    weights = np.empty(levels.size, np.float64)
    tan_half = np.empty(levels.size, np.float64)
    for i in range(levels.size):
        k = levels[i]
        weights[i] = counts[k]
        tan_half[i] = tan_table[k] if k < tan_table.size else math.tan(0.5 * angles[i])
    theta0 = start * angle_per_value
    return fixed_point(angles, tan_half, weights, theta0, iterations, tol, max_spread)
