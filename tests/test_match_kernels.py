"""The compiled matcher kernel equals the numpy chain it replaced (``np.argmin`` and
``np.partition(d2, 1)`` per train set), ties included."""

import cv2
import numpy as np
import pytest

from ipbench.perception._match_kernels import hamming_two_nearest, segment_two_nearest


def _numpy_chain(q: np.ndarray, t: np.ndarray, bounds: np.ndarray):
    q_sq = np.einsum("ij,ij->i", q, q)
    d2 = q_sq[:, None] + np.einsum("ij,ij->i", t, t)[None, :] - 2.0 * (q @ t.T)
    nearest, first, second = [], [], []
    for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
        part = d2[:, lo:hi]
        two = np.partition(part, 1, axis=1)[:, :2]
        nearest.append(np.argmin(part, axis=1))
        first.append(two[:, 0])
        second.append(two[:, 1])
    return np.stack(nearest, 1), np.stack(first, 1), np.stack(second, 1)


@pytest.mark.parametrize("seed", range(4))
def test_the_kernel_equals_argmin_and_partition_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    # SIFT-like byte descriptors; few distinct values, so that ties are frequent
    levels = 3 if seed % 2 else 256
    q = rng.integers(0, levels, (57, 128)).astype(np.float32)
    t = rng.integers(0, levels, (300, 128)).astype(np.float32)
    t[5] = t[7] = q[0]  # a repeated nearest: the first column wins, the second equals it
    sizes = rng.integers(2, 40, 20)
    sizes[0] = 10  # columns 5 and 7 in the first segment
    bounds = np.r_[0, np.cumsum(sizes)]
    bounds = bounds[bounds <= len(t)]
    bounds[-1] = len(t)
    q_sq = np.einsum("ij,ij->i", q, q)
    got = segment_two_nearest(q @ t.T, q_sq, np.einsum("ij,ij->i", t, t), bounds)
    want = _numpy_chain(q, t, bounds)
    for g, w in zip(got, want, strict=True):
        assert g.shape == w.shape
        np.testing.assert_array_equal(g, w)
    assert got[0][0, 0] == 5 and got[1][0, 0] == got[2][0, 0] == 0.0
    if levels == 3:
        assert np.any(got[1] == got[2])  # the tie case is exercised


@pytest.mark.parametrize("n_bytes", [32, 61])  # ORB, AKAZE (padded to 64)
def test_the_hamming_kernel_equals_opencvs_batch_distance(n_bytes):
    rng = np.random.default_rng(n_bytes)
    q = rng.integers(0, 256, (40, n_bytes), dtype=np.uint8)
    t = rng.integers(0, 256, (200, n_bytes), dtype=np.uint8)
    t[3] = t[9] = q[0]  # a repeated nearest at distance 0
    bounds = np.array([0, 12, 14, 90, 200], np.int64)
    width = -(-n_bytes // 8) * 8

    def words(a):
        return np.ascontiguousarray(np.pad(a, ((0, 0), (0, width - n_bytes)))).view(np.uint64)

    nearest, first, second = hamming_two_nearest(words(q), words(t), bounds)
    assert nearest[0, 0] == 3 and first[0, 0] == second[0, 0] == 0
    for s, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
        dist, nidx = cv2.batchDistance(q, t[lo:hi], cv2.CV_32S, normType=cv2.NORM_HAMMING, K=2)
        np.testing.assert_array_equal(first[:, s], dist[:, 0])
        np.testing.assert_array_equal(second[:, s], dist[:, 1])
        unique = dist[:, 0] < dist[:, 1]  # where the nearest is unique, the same index
        np.testing.assert_array_equal(nearest[unique, s], nidx[unique, 0])
