"""Compiled kernel of the exact descriptor matcher (numba, single-threaded, no fast-math).

:func:`segment_two_nearest` does in one pass over a block of dot products what
:func:`ipbench.perception.matching.match_many` did with a chain of numpy operations per train
set (``d2 = |q|^2 + |t|^2 - 2 q.t``, then ``np.argmin`` and ``np.partition(d2, 1)[:, :2]`` over
each train set's columns): the nearest column (the first one on ties, as ``np.argmin``) and the
two smallest squared distances (the second equals the first on ties, as ``np.partition``).
The squared distances are sums of integers below 2**24 in float32 (the caller checks it), so
they are exact in any order of operations; the kernel takes them as int32 (exact), whose
minimum reductions LLVM vectorises without fast-math (float ones it may not reorder), and its
output is bit-identical to numpy's (``tests/test_features2d.py`` holds the matcher to OpenCV's
brute-force one and ``tests/test_match_kernels.py`` the kernel to the numpy chain).
:func:`hamming_two_nearest` does the same for binary descriptors (AKAZE, ORB) straight from
their bytes, taken as 64-bit words (zero-padded: a pad adds no differing bit): the Hamming
distance is the population count of the XOR (a SWAR count, which LLVM vectorises). Integer
distances are exact, so the result is bit-identical to ``cv2.batchDistance`` with
``NORM_HAMMING``, the brute-force matcher's kernel, which it replaces at 2x its speed.
Compiled on first use and cached next to this file (``cache=True``).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["hamming_two_nearest", "segment_two_nearest"]

_jit = numba.njit(cache=True, nogil=True, error_model="numpy")


@_jit
def _two_smallest(d: np.ndarray, n: int) -> tuple[int, np.int32, np.int32]:
    """The first index of the minimum of ``d[:n]`` (int32, n >= 2), the minimum and the
    smallest of the others: short passes that LLVM vectorises (integer minima need no
    fast-math)."""
    m1 = d[0]
    for j in range(1, n):
        m1 = min(m1, d[j])
    j1 = 0
    while d[j1] != m1:
        j1 += 1
    m2 = np.int32(2**31 - 1)
    for j in range(j1):
        m2 = min(m2, d[j])
    for j in range(j1 + 1, n):
        m2 = min(m2, d[j])
    return j1, m1, m2


@_jit
def segment_two_nearest(
    dots: np.ndarray, q_sq: np.ndarray, t_sq: np.ndarray, bounds: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest column and two smallest squared distances per row and segment.

    ``dots`` (Q, B) float32 are the dot products of Q query and B train descriptors,
    ``q_sq`` (Q,) and ``t_sq`` (B,) float32 their squared norms, ``bounds`` (S + 1,) int64 the
    segments' column bounds (increasing, ``bounds[0] = 0``, ``bounds[S] = B``; each segment has
    at least two columns). Returns ``nearest`` (Q, S) int64 (column index within its segment),
    ``first`` and ``second`` (Q, S) float32 squared distances.
    """
    n_q = dots.shape[0]
    n_s = bounds.shape[0] - 1
    nearest = np.empty((n_q, n_s), np.int64)
    first = np.empty((n_q, n_s), np.float32)
    second = np.empty((n_q, n_s), np.float32)
    two = np.float32(2.0)
    width = 0
    for s in range(n_s):
        width = max(width, bounds[s + 1] - bounds[s])
    d = np.empty(width, np.int32)
    for i in range(n_q):
        row = dots[i]
        qi = q_sq[i]
        for s in range(n_s):
            lo = bounds[s]
            n = bounds[s + 1] - lo
            # the distances (exact integers), then the two smallest
            for j in range(n):
                d[j] = np.int32((qi + t_sq[lo + j]) - two * row[lo + j])
            j1, m1, m2 = _two_smallest(d, n)
            nearest[i, s] = j1
            first[i, s] = np.float32(m1)  # exact: below 2**24
            second[i, s] = np.float32(m2)
    return nearest, first, second


_M1 = np.uint64(0x5555555555555555)
_M2 = np.uint64(0x3333333333333333)
_M4 = np.uint64(0x0F0F0F0F0F0F0F0F)
_H01 = np.uint64(0x0101010101010101)


@_jit
def _popcount(x: np.uint64) -> np.uint64:
    """Set bits of a 64-bit word (the SWAR count of Hacker's Delight, §5-1)."""
    x = x - ((x >> np.uint64(1)) & _M1)
    x = (x & _M2) + ((x >> np.uint64(2)) & _M2)
    x = (x + (x >> np.uint64(4))) & _M4
    return (x * _H01) >> np.uint64(56)


@_jit
def hamming_two_nearest(
    query: np.ndarray, train: np.ndarray, bounds: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest column and two smallest Hamming distances per query and train segment.

    ``query`` (Q, W) and ``train`` (B, W) uint64 are binary descriptors as 64-bit words,
    ``bounds`` (S + 1,) int64 as in :func:`segment_two_nearest`. Returns ``nearest`` (Q, S)
    int64 (index within the segment; the first one on ties), ``first`` and ``second`` (Q, S)
    int32 distances in bits (the second equals the first on ties).
    """
    n_q, n_w = query.shape
    n_s = bounds.shape[0] - 1
    nearest = np.empty((n_q, n_s), np.int64)
    first = np.empty((n_q, n_s), np.int32)
    second = np.empty((n_q, n_s), np.int32)
    width = 0
    for s in range(n_s):
        width = max(width, bounds[s + 1] - bounds[s])
    d = np.empty(width, np.int32)
    for i in range(n_q):
        for s in range(n_s):
            lo = bounds[s]
            n = bounds[s + 1] - lo
            for j in range(n):
                bits = np.uint64(0)
                for k in range(n_w):
                    bits += _popcount(query[i, k] ^ train[lo + j, k])
                d[j] = np.int32(bits)
            j1, m1, m2 = _two_smallest(d, n)
            nearest[i, s] = j1
            first[i, s] = m1
            second[i, s] = m2
    return nearest, first, second
