"""Compiled kernels of the point-cloud stages (numba, single-threaded, no fast-math).

Each kernel does in one or two passes over the points what a chain of numpy operations of
:mod:`ipbench.perception.cloud` did, with the same float64 operations in the same order, so
its output is bit-identical to that chain (``tests/test_cloud_kernels.py`` holds each one to
the numpy chain it replaces, kept there as the reference):

- :func:`box_members`: ``np.flatnonzero(np.all(np.abs(points - center) <= half, axis=1))``.
- :func:`voxel_assign`: ``np.floor(points / size).astype(np.int64)``, the keys' flat index in
  their bounding grid, ``np.unique(flat, return_inverse=True, return_counts=True)`` and the
  per-voxel coordinate sums of ``np.bincount(voxel_of, points[:, i])`` (which add the points
  in their order, as the loop here does). The voxels are numbered in increasing flat key, as
  ``np.unique`` numbers them, by ranking the occupied cells in a bit set over the grid (a
  rank/select bit vector, Jacobson, FOCS 1989) instead of a sort: three passes over the
  points and one over the set's words, which fit in the cache for a table top; the caller
  falls back to the numpy chain when the grid is too large (:data:`MAX_GRID_CELLS`).
- :func:`hand_keep`: the mask of the points near the TCP, in front of the palm and outside the
  gripper's boxes (:func:`ipbench.perception.segmentation.segment_in_hand`).
- :func:`hull_members`: which points lie over the table's hull,
  ``np.all(flat @ equations[:, :2].T + equations[:, 2] <= HULL_LIMIT, axis=1)`` of their plane
  coordinates ``flat``. Those products go through BLAS, whose rounding (summation order,
  fused multiply-adds) is its own; the kernel decides only the points whose every facet value
  is farther from the limit than any rounding of either way (a bound of a few ulps of the
  coordinates, with a margin of several hundredfold) and reports the rest undecided (NaN
  included), for which the caller takes the numpy expression, so the mask is always numpy's.

No fast-math: no reassociation and no fused multiply-adds, so results do not depend on the
processor's vector width. Compiled on first use and cached next to this file
(``cache=True``; a read-only install compiles once per process).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = [
    "HULL_LIMIT",
    "MAX_GRID_CELLS",
    "box_members",
    "hand_keep",
    "hull_members",
    "voxel_assign",
]

HULL_LIMIT = 1e-9
"""A point is over the hull when no facet has it farther outside than this (m)."""

MAX_GRID_CELLS = 1 << 26
"""Largest voxel grid (cells of the points' bounding box) ranked by a bit set (8 MiB, and
8 MiB of running counts); larger grids go through ``np.unique``. The work table's
pass-through box at 5 mm is 3.2 M cells (400 KiB of bits)."""

_jit = numba.njit(cache=True, nogil=True, error_model="numpy")


@_jit
def box_members(points: np.ndarray, center: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Indices (M,) int64, increasing, of the rows of ``points`` (N, 3) inside the box
    ``|p - center| <= half`` on every axis (m)."""
    n = points.shape[0]
    out = np.empty(n, np.int64)
    m = 0
    for i in range(n):
        if (
            abs(points[i, 0] - center[0]) <= half[0]
            and abs(points[i, 1] - center[1]) <= half[1]
            and abs(points[i, 2] - center[2]) <= half[2]
        ):
            out[m] = i
            m += 1
    return out[:m]


_ONE = np.uint64(1)


@_jit
def _popcount(word: np.uint64) -> np.int64:
    """Set bits of a 64-bit word (the SWAR sum; LLVM emits one ``popcnt`` for it)."""
    word = word - ((word >> _ONE) & np.uint64(0x5555555555555555))
    word = (word & np.uint64(0x3333333333333333)) + (
        (word >> np.uint64(2)) & np.uint64(0x3333333333333333)
    )
    word = (word + (word >> np.uint64(4))) & np.uint64(0x0F0F0F0F0F0F0F0F)
    return np.int64((word * np.uint64(0x0101010101010101)) >> np.uint64(56))


@_jit
def _grid(points: np.ndarray, size: float) -> tuple[np.ndarray, np.ndarray]:
    """Lowest voxel key (3,) of ``floor(p / size)`` over the points and the span (3,) of the
    grid they occupy; span 0 when a coordinate is not finite or its key not an int64.
    ``floor(p / size)`` is non-decreasing in ``p`` (correctly rounded division by
    ``size > 0``), so its extremes are those of the extreme coordinates: one pass of
    comparisons, one division per axis."""
    low = np.zeros(3, np.int64)
    span = np.zeros(3, np.int64)
    for a in range(3):
        lo = hi = points[0, a]
        for i in range(points.shape[0]):
            x = points[i, a]
            if x < lo:
                lo = x
            elif x > hi:
                hi = x
            elif x != x:  # NaN
                return low, np.zeros(3, np.int64)
        if not (abs(lo / size) < 2.0**62 and abs(hi / size) < 2.0**62):  # also NaN, inf
            return low, np.zeros(3, np.int64)
        low[a] = np.int64(math.floor(lo / size))
        span[a] = np.int64(math.floor(hi / size)) - low[a] + 1
    return low, span


@_jit
def _ranked(points: np.ndarray, size: float, low: np.ndarray, span: np.ndarray):
    """Voxel of every point, counts and coordinate sums, voxels numbered by increasing flat
    key: the occupied cells are bits of a bit set over the grid, and a cell's number is the
    count of occupied cells before it (the set bits of the words before it, kept as running
    sums, plus those below it in its own word)."""
    n = points.shape[0]
    flat = np.empty(n, np.int64)
    bits = np.zeros((span[0] * span[1] * span[2] + 63) >> 6, np.uint64)
    for i in range(n):
        k0 = np.int64(math.floor(points[i, 0] / size)) - low[0]
        k1 = np.int64(math.floor(points[i, 1] / size)) - low[1]
        k2 = np.int64(math.floor(points[i, 2] / size)) - low[2]
        f = (k0 * span[1] + k1) * span[2] + k2
        flat[i] = f
        bits[f >> 6] |= _ONE << np.uint64(f & 63)
    before = np.empty(bits.shape[0], np.int64)
    v = 0
    for w in range(bits.shape[0]):
        before[w] = v
        v += _popcount(bits[w])
    voxel_of = np.empty(n, np.int64)
    counts = np.zeros(v, np.int64)
    sums = np.zeros((v, 3))
    for i in range(n):
        f = flat[i]
        below = bits[f >> 6] & ((_ONE << np.uint64(f & 63)) - _ONE)
        k = before[f >> 6] + _popcount(below)
        voxel_of[i] = k
        counts[k] += 1
        sums[k, 0] += points[i, 0]
        sums[k, 1] += points[i, 1]
        sums[k, 2] += points[i, 2]
    return voxel_of, counts, sums


def voxel_assign(points: np.ndarray, size: float):
    """``(voxel_of (N,) int64, counts (V,) int64, sums (V, 3) float64)`` of the non-empty
    ``points`` (N, 3) float64 C-contiguous, m, in a grid of edge ``size`` (m) anchored at the
    origin; voxels numbered by increasing flat key. None when the grid exceeds
    :data:`MAX_GRID_CELLS` or a coordinate is not finite (the caller then uses
    ``np.unique``)."""
    low, span = _grid(points, size)
    cells = int(span[0]) * int(span[1]) * int(span[2])
    if cells <= 0 or cells > MAX_GRID_CELLS:
        return None
    return _ranked(points, size, low, span)


@_jit
def hand_keep(
    local: np.ndarray, radius: float, palm_front: float, centres: np.ndarray, halves: np.ndarray
) -> np.ndarray:
    """Mask (N,) of the points ``local`` (N, 3) in the TCP frame (m) within ``radius`` of the
    TCP, in front of ``palm_front`` (z, m) and outside every box ``(centres[b], halves[b])``
    ((B, 3) each, m): ``(np.linalg.norm(local, axis=1) <= radius) & (local[:, 2] >
    palm_front) & ~np.all(np.abs(local - centres[b]) <= halves[b], axis=1)`` for every b (the
    norm adds the squares in numpy's order, ``(x x + y y) + z z``)."""
    n = local.shape[0]
    keep = np.empty(n, np.bool_)
    for i in range(n):
        x, y, z = local[i, 0], local[i, 1], local[i, 2]
        ok = math.sqrt((x * x + y * y) + z * z) <= radius and z > palm_front
        for b in range(centres.shape[0]):
            if (
                abs(x - centres[b, 0]) <= halves[b, 0]
                and abs(y - centres[b, 1]) <= halves[b, 1]
                and abs(z - centres[b, 2]) <= halves[b, 2]
            ):
                ok = False
        keep[i] = ok
    return keep


@_jit
def hull_members(
    points: np.ndarray, index: np.ndarray, e1: np.ndarray, e2: np.ndarray, equations: np.ndarray
) -> tuple[bool, np.ndarray]:
    """``(decided, inside)``: ``inside`` (M,) bool says whether ``points[index]`` ((N, 3), m;
    ``index`` (M,) int64) lies in the convex hull with facets ``equations`` (F, 3) in the plane
    coordinates ``(p . e1, p . e2)`` (unit ``e1``, ``e2`` (3,)), each facet value within
    :data:`HULL_LIMIT`; ``decided`` is False when some point's answer is within rounding of
    the limit (the answer then is not this kernel's to give)."""
    inside = np.empty(index.shape[0], np.bool_)
    scale = 0.0  # largest |p0| + |p1| + |p2|: bounds |x|, |y|
    for t in range(index.shape[0]):
        i = index[t]
        scale = max(scale, abs(points[i, 0]) + abs(points[i, 1]) + abs(points[i, 2]))
    ab = c_max = 0.0
    for f in range(equations.shape[0]):
        ab = max(ab, abs(equations[f, 0]) + abs(equations[f, 1]))
        c_max = max(c_max, abs(equations[f, 2]))
    # BLAS and this loop each round x, y and a facet value within ~1e-15 (1 + ab scale + |c|)
    # of the exact value; 1e-12 times that is far beyond either
    tol = 1e-12 * (1.0 + ab * scale + c_max)
    surely_out, surely_in = HULL_LIMIT + tol, HULL_LIMIT - tol
    for t in range(index.shape[0]):
        i = index[t]
        p0, p1, p2 = points[i, 0], points[i, 1], points[i, 2]
        x = p0 * e1[0] + p1 * e1[1] + p2 * e1[2]
        y = p0 * e2[0] + p1 * e2[1] + p2 * e2[2]
        ok, unsure = True, False
        for f in range(equations.shape[0]):
            value = x * equations[f, 0] + y * equations[f, 1] + equations[f, 2]
            if value > surely_out:  # outside, whatever the other facets say
                ok = False
                break
            unsure = unsure or not value < surely_in  # (NaN: unsure)
        if ok and unsure:
            return False, inside
        inside[t] = ok
    return True, inside
