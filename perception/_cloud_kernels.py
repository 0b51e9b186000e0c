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
  ``np.unique`` numbers them, by a rank table over the grid instead of a sort; the caller
  falls back to the numpy chain when the grid is too large for a table
  (:data:`MAX_GRID_CELLS`).
- :func:`hand_keep`: the mask of the points near the TCP, in front of the palm and outside the
  gripper's boxes (:func:`ipbench.perception.segmentation.segment_in_hand`).

No fast-math: no reassociation and no fused multiply-adds, so results do not depend on the
processor's vector width. Compiled on first use and cached next to this file
(``cache=True``; a read-only install compiles once per process).
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["MAX_GRID_CELLS", "box_members", "hand_keep", "voxel_assign"]

MAX_GRID_CELLS = 1 << 23
"""Largest voxel grid (cells of the points' bounding box) ranked by a table (32 MiB of int32);
larger grids go through ``np.unique``. The work table's pass-through box at 5 mm is 3.2 M."""

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


@_jit
def _keys(points: np.ndarray, size: float) -> tuple[np.ndarray, np.ndarray]:
    """Integer voxel keys (N, 3) of ``floor(p / size)`` shifted to start at 0, and the span
    (3,) of the grid they occupy."""
    n = points.shape[0]
    keys = np.empty((n, 3), np.int64)
    low = np.empty(3, np.int64)
    high = np.empty(3, np.int64)
    for a in range(3):
        low[a] = np.iinfo(np.int64).max
        high[a] = np.iinfo(np.int64).min
    for i in range(n):
        for a in range(3):
            k = np.int64(math.floor(points[i, a] / size))
            keys[i, a] = k
            low[a] = min(low[a], k)
            high[a] = max(high[a], k)
    for i in range(n):
        for a in range(3):
            keys[i, a] -= low[a]
    return keys, high - low + 1


@_jit
def _ranked(points: np.ndarray, keys: np.ndarray, span: np.ndarray):
    n = points.shape[0]
    flat = (keys[:, 0] * span[1] + keys[:, 1]) * span[2] + keys[:, 2]
    rank = np.zeros(span[0] * span[1] * span[2], np.int32)
    for i in range(n):
        rank[flat[i]] = 1
    v = 0
    for c in range(rank.shape[0]):
        if rank[c]:
            rank[c] = v
            v += 1
    voxel_of = np.empty(n, np.int64)
    counts = np.zeros(v, np.int64)
    sums = np.zeros((v, 3))
    for i in range(n):
        k = np.int64(rank[flat[i]])
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
    :data:`MAX_GRID_CELLS` (the caller then uses ``np.unique``)."""
    keys, span = _keys(points, size)
    if int(span[0]) * int(span[1]) * int(span[2]) > MAX_GRID_CELLS:
        return None
    return _ranked(points, keys, span)


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
