"""Compiled Euclidean clustering: connected components of the radius graph of voxel centres.

PCL's ``EuclideanClusterExtraction`` joins two points at most a tolerance ``eps`` apart, and
:mod:`ipbench.perception.segmentation` takes the connected components of that graph. The
reference is scipy: ``cKDTree.query_pairs(eps)`` (the pairs at distance ``<= eps``) and
``scipy.sparse.csgraph.connected_components`` of them, whose labels number the components in
the order of their smallest vertex (vertex 0's component is 0, the next unlabelled vertex's
is 1, ...). :func:`radius_components` finds the same pairs in a uniform grid of cells just
wider than ``eps`` (two vertices closer than ``eps`` sit in the same or adjacent cells) and
joins them by union-find (Tarjan, JACM 22(2), 1975), instead of building a sparse matrix and
sorting it; the labels are numbered as scipy numbers them.

Certified equality: the kd-tree and the grid compute a pair's squared distance with their own
rounding (the tree also accepts whole node pairs by the distance bounds of their boxes, kept
by running sums), so a pair within rounding of ``eps`` may be in one graph and not the other.
Both are within ~1e-13 m^2 of the exact value for coordinates of a few metres. A pair whose
squared distance is within :func:`margin` of ``eps^2`` is left out of the union-find and
checked at the end: when its two vertices are in one component anyway, whether the pair is
an edge changes nothing; otherwise the kernel gives up (returns None) and the caller takes
the scipy path. Every answer given is scipy's.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["MAX_CELLS", "margin", "radius_components"]

MAX_CELLS = 1 << 22
"""Largest grid (cells of the vertices' bounding box) the kernel indexes (32 MiB of cell
starts); larger ones are left to the kd-tree. A 1 m x 1 m x 0.3 m prism at 15 mm: 90 k."""

_MAX_UNSURE = 1024  # pairs within the margin of eps kept for the final check (then: give up)
_WIDEN = 1.0 + 1e-6  # cell edge / eps: a pair at eps stays within adjacent cells after rounding

_jit = numba.njit(cache=True, nogil=True, error_model="numpy")


def margin(extent: float) -> float:
    """Half-width (m^2) of the band around ``eps^2`` where the kernel does not decide, for
    coordinates up to ``extent`` (m) in magnitude: 1e-12 m^2 per m^2, about ten times the
    rounding a kd-tree's running box bounds can gather (a few dozen roundings of values up to
    ``3 extent^2``)."""
    return 1e-12 * max(1.0, extent * extent)


@_jit
def _find(parent: np.ndarray, v: int) -> int:
    while parent[v] != v:
        parent[v] = parent[parent[v]]  # path halving
        v = parent[v]
    return v


@_jit
def _components(centres: np.ndarray, eps: float, band: float, max_cells: int):
    n = centres.shape[0]
    labels = np.empty(n, np.int32)
    if n == 0:
        return True, labels
    edge = eps * _WIDEN
    low = np.empty(3)
    span = np.empty(3, np.int64)
    for a in range(3):
        lo = hi = centres[0, a]
        for i in range(n):
            lo = min(lo, centres[i, a])
            hi = max(hi, centres[i, a])
        low[a] = lo
        span[a] = np.int64(math.floor((hi - lo) / edge)) + 1
    cells = 1
    for a in range(3):  # each span is below 2^22 (the caller's check): no overflow
        cells *= span[a]
        if cells > max_cells:
            return False, labels
    cell = np.empty(n, np.int64)
    start = np.zeros(cells + 1, np.int64)
    for i in range(n):
        k0 = np.int64(math.floor((centres[i, 0] - low[0]) / edge))
        k1 = np.int64(math.floor((centres[i, 1] - low[1]) / edge))
        k2 = np.int64(math.floor((centres[i, 2] - low[2]) / edge))
        cell[i] = (k0 * span[1] + k1) * span[2] + k2
        start[cell[i] + 1] += 1
    for c in range(1, cells + 1):
        start[c] += start[c - 1]
    fill = start[:-1].copy()
    vertex = np.empty(n, np.int64)  # the vertices cell by cell, and their coordinates
    xyz = np.empty((n, 3))
    for i in range(n):
        t = fill[cell[i]]
        fill[cell[i]] += 1
        vertex[t] = i
        xyz[t, 0], xyz[t, 1], xyz[t, 2] = centres[i, 0], centres[i, 1], centres[i, 2]
    parent = np.arange(n)
    near, far = eps * eps - band, eps * eps + band
    unsure_pairs = np.empty((_MAX_UNSURE, 2), np.int64)
    unsure = 0
    s1, s2 = span[1] * span[2], span[2]
    for c in range(cells):
        if start[c] == start[c + 1]:
            continue
        k0, k1, k2 = c // s1, (c // s2) % span[1], c % s2
        # offsets (d0, d1, d2) in {-1, 0, 1}^3 numbered q = 9 (d0 + 1) + 3 (d1 + 1) + d2 + 1:
        # q = 13 is this cell, q > 13 one of each pair of opposite neighbours (-d is 26 - q)
        for q in range(13, 27):
            n0, n1, n2 = k0 + q // 9 - 1, k1 + (q // 3) % 3 - 1, k2 + q % 3 - 1
            if not (0 <= n0 < span[0] and 0 <= n1 < span[1] and 0 <= n2 < span[2]):
                continue
            other = (n0 * span[1] + n1) * span[2] + n2
            for s in range(start[c], start[c + 1]):
                x, y, z = xyz[s, 0], xyz[s, 1], xyz[s, 2]
                for t in range(s + 1 if other == c else start[other], start[other + 1]):
                    dx, dy, dz = xyz[t, 0] - x, xyz[t, 1] - y, xyz[t, 2] - z
                    d2sq = dx * dx + dy * dy + dz * dz
                    if d2sq < near:
                        ri, rj = _find(parent, vertex[s]), _find(parent, vertex[t])
                        if ri != rj:
                            parent[max(ri, rj)] = min(ri, rj)
                    elif d2sq <= far:  # too close to eps to say which side it is on
                        if unsure == unsure_pairs.shape[0]:
                            return False, labels
                        unsure_pairs[unsure, 0], unsure_pairs[unsure, 1] = vertex[s], vertex[t]
                        unsure += 1
    for u in range(unsure):  # such a pair matters only if it would join two components
        if _find(parent, unsure_pairs[u, 0]) != _find(parent, unsure_pairs[u, 1]):
            return False, labels
    root_label = np.full(n, -1, np.int32)
    count = 0
    for v in range(n):  # numbered by smallest member, as scipy's traversal numbers them
        r = _find(parent, v)
        if root_label[r] < 0:
            root_label[r] = count
            count += 1
        labels[v] = root_label[r]
    return True, labels


def radius_components(centres: np.ndarray, eps: float) -> np.ndarray | None:
    """Labels (V,) int32 of the connected components of the graph joining the ``centres``
    (V, 3) (m) at most ``eps`` (m) apart, numbered by smallest member; None when a pair
    within :func:`margin` of ``eps`` would join two components, a coordinate is not finite,
    or the grid exceeds :data:`MAX_CELLS` (scipy's kd-tree decides those)."""
    centres = np.ascontiguousarray(centres, dtype=np.float64)
    if len(centres) == 0:
        return np.zeros(0, np.int32)
    extent = float(np.max(np.abs(centres)))
    band = margin(extent)
    # pairs in cells farther apart are over eps * _WIDEN: outside the band, as it must be
    if not (math.isfinite(extent) and eps * eps * (_WIDEN**2 - 1.0) > 2.0 * band):
        return None
    if extent / (eps * _WIDEN) > 2.0**20:  # the grid is too fine for the cloud's size
        return None
    ok, labels = _components(centres, float(eps), band, MAX_CELLS)
    return labels if ok else None
