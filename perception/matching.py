"""Descriptor matching of the active-vision behaviours (thesis ch. 3 §3.3).

The two nearest neighbours by brute force (exact, hence deterministic; ``cv2.batchDistance``,
the kernel of ``cv2.BFMatcher``), kept when the nearest is closer than :data:`LOWE_RATIO` = 0.8
times the second (Lowe 2004, §7.1: this "eliminates 90 % of the false matches while discarding
less than 5 % of the correct" ones).

:func:`match_many` matches one query to many train sets (a database's views) at once, with the
ratio test per set. Integer-valued float descriptors (OpenCV's SIFT stores its bytes as floats)
take their squared L2 distances from one float32 matrix product per block of train descriptors
— exact for integers: every partial sum is an integer below 2**24 — and the compiled kernel
:func:`~ipbench.perception._match_kernels.segment_two_nearest`; the result equals the brute
force matcher's exactly (a test holds it to ``cv2.BFMatcher``). Binary descriptors (AKAZE,
ORB) take :func:`~ipbench.perception._match_kernels.hamming_two_nearest`, exact as well.
A :class:`TrainSet` keeps the stacked train descriptors, their norms and that check, so that a
database pays for them once; KAZE's real-valued descriptors go through ``cv2.batchDistance``
one set at a time (a float sum in another order would not be bit-identical).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ipbench.perception._match_kernels import hamming_two_nearest, segment_two_nearest
from ipbench.perception.features2d import ActiveVisionError, Features, norm_of

__all__ = ["LOWE_RATIO", "TrainSet", "match", "match_many"]

LOWE_RATIO = 0.8  # Lowe 2004, §7.1
_EXACT_SQ = 2.0**22  # float32 sums of integers below 2**24 are exact; |a|^2 + |b|^2 stays below
_BLOCK = 4096  # train descriptors per matrix product: (Q, 4096) float32 blocks, <= 33 MB


def _check_ratio(ratio: float) -> None:
    if not 0.0 < ratio <= 1.0:
        raise ActiveVisionError(f"ratio is {ratio!r}; valid: 0 < ratio <= 1 (Lowe: 0.8)")


def match(query: Features, train: Features, ratio: float = LOWE_RATIO) -> np.ndarray:
    """Lowe's ratio-test matches of ``query`` to ``train``: (M, 2) int64 ``(query, train)`` indices.

    A query feature is kept when its nearest train descriptor is closer than ``ratio`` times
    the second nearest; with fewer than two train features no ratio can be taken and nothing
    matches. Rows are in query order.
    """
    if query.feature_type != train.feature_type:
        raise ActiveVisionError(
            f"cannot match {query.feature_type} features to {train.feature_type} features;"
            " valid: features of the same type"
        )
    _check_ratio(ratio)
    if len(query) == 0 or len(train) < 2:
        return np.zeros((0, 2), np.int64)
    norm = norm_of(query.feature_type)
    # cv2.batchDistance with K = 2 is the exact 2-NN search that cv2.BFMatcher.knnMatch runs
    # (same distance kernels, same order, same distances: Hamming as int32, L2 as float32),
    # minus the per-match DMatch objects, which make Python the bottleneck
    dtype = cv2.CV_32S if norm == cv2.NORM_HAMMING else cv2.CV_32F  # as BFMatcher
    dist, nidx = cv2.batchDistance(query.descriptors, train.descriptors, dtype, normType=norm, K=2)
    dist = dist.astype(np.float64)  # DMatch.distance is a float32, compared as a Python float
    keep = (nidx[:, 1] >= 0) & (dist[:, 0] < ratio * dist[:, 1])
    rows = np.flatnonzero(keep)
    return np.stack([rows, nidx[rows, 0]], axis=1).astype(np.int64).reshape(-1, 2)


def _integer_valued(descriptors: np.ndarray, squared_norms: np.ndarray | None = None) -> bool:
    """True when float descriptors are small non-negative integers (OpenCV's SIFT stores its
    bytes as floats), so that a float32 matrix product gives their squared distances exactly."""
    d = descriptors
    if not (d.dtype == np.float32 and len(d) and d.min() >= 0 and np.array_equal(d, np.rint(d))):
        return False
    sq = np.einsum("ij,ij->i", d, d, dtype=np.float64) if squared_norms is None else squared_norms
    return bool(float(np.max(sq)) < _EXACT_SQ)


@dataclass(frozen=True, eq=False)
class TrainSet:
    """Train feature sets to match queries against, prepared once.

    Attributes
    ----------
    features : tuple of Features
        The sets, one feature type; a set with fewer than two features never matches.
    feature_type : str
        Their type (the first set's; all must share it).
    exact_product : bool
        True when the descriptors take the exact matrix-product path (module docstring).
    binary : bool
        True when they are bytes compared by Hamming distance (module docstring).
    """

    features: tuple[Features, ...]
    feature_type: str = field(init=False)
    exact_product: bool = field(init=False)
    binary: bool = field(init=False)
    _use: tuple[int, ...] = field(init=False, repr=False)  # sets with >= 2 features
    _stack: np.ndarray = field(init=False, repr=False)  # (M, D) their descriptors, stacked
    _sq: np.ndarray = field(init=False, repr=False)  # (M,) float32 squared norms
    _offset: np.ndarray = field(init=False, repr=False)  # (len(_use) + 1,) rows of each set

    def __post_init__(self) -> None:
        features = tuple(self.features)
        types = sorted({f.feature_type for f in features})
        if len(types) > 1:
            raise ActiveVisionError(
                f"train sets of types {types}; valid: features of one type in a train set"
            )
        use = tuple(i for i, f in enumerate(features) if len(f) >= 2)
        stack = (
            np.concatenate([features[i].descriptors for i in use])
            if use
            else np.zeros((0, 0), np.float32)
        )
        exact = bool(use) and stack.dtype == np.float32
        sq = np.einsum("ij,ij->i", stack, stack) if exact else np.zeros(0, np.float32)
        exact = exact and _integer_valued(stack, sq.astype(np.float64))
        put = object.__setattr__
        put(self, "features", features)
        put(self, "feature_type", types[0] if types else "")
        binary = bool(use) and stack.dtype == np.uint8
        if binary:  # 64-bit words, zero-padded
            width = -(-stack.shape[1] // 8) * 8
            stack = np.ascontiguousarray(np.pad(stack, ((0, 0), (0, width - stack.shape[1])))).view(
                np.uint64
            )
        put(self, "exact_product", exact)
        put(self, "binary", binary)
        put(self, "_use", use)
        put(self, "_stack", stack)
        put(self, "_sq", sq)
        put(self, "_offset", np.cumsum([0] + [len(features[i]) for i in use]))


def match_many(
    query: Features, trains: TrainSet | list[Features] | tuple[Features, ...],
    ratio: float = LOWE_RATIO,
) -> list[np.ndarray]:  # fmt: skip
    """:func:`match` of ``query`` to each train set: the same (M_i, 2) arrays, exactly.

    ``trains`` is a :class:`TrainSet` (prepared once, e.g. a database's) or a sequence of
    :class:`Features`. Integer-valued descriptors take the matrix-product path (module
    docstring); others go through :func:`match` one set at a time.
    """
    if not isinstance(trains, TrainSet):
        trains = TrainSet(tuple(trains))
    if trains.features and trains.feature_type != query.feature_type:
        raise ActiveVisionError(
            f"cannot match {query.feature_type} features to {trains.feature_type} features;"
            " valid: features of the same type"
        )
    _check_ratio(ratio)
    out = [np.zeros((0, 2), np.int64)] * len(trains.features)
    use, offset = trains._use, trains._offset
    if len(query) == 0 or not use:
        return out
    if trains.binary and query.descriptors.dtype == np.uint8:
        return _match_binary(query, trains, ratio, out)
    if not (trains.exact_product and _integer_valued(query.descriptors)):
        return [match(query, t, ratio) for t in trains.features]
    q = query.descriptors
    q_sq = np.einsum("ij,ij->i", q, q)
    k = 0
    while k < len(use):  # blocks of whole train sets, about _BLOCK descriptors each
        end = k + 1
        while end < len(use) and offset[end + 1] - offset[k] <= _BLOCK:
            end += 1
        lo, hi = offset[k], offset[end]
        nearest, first, second = segment_two_nearest(
            q @ trains._stack[lo:hi].T, q_sq, trains._sq[lo:hi],
            (offset[k : end + 1] - lo).astype(np.int64),
        )  # fmt: skip
        dist0 = np.sqrt(first).astype(np.float64)  # float32 sqrt, as the matcher's
        dist1 = np.sqrt(second).astype(np.float64)
        for col, i in enumerate(use[k:end]):
            rows = np.flatnonzero(dist0[:, col] < ratio * dist1[:, col])
            out[i] = np.stack([rows, nearest[rows, col]], axis=1).astype(np.int64).reshape(-1, 2)
        k = end
    return out


def _match_binary(
    query: Features, trains: TrainSet, ratio: float, out: list[np.ndarray]
) -> list[np.ndarray]:
    """The Hamming path of :func:`match_many` (``out`` holds the empty results)."""
    q = query.descriptors
    width = trains._stack.shape[1] * 8
    if q.shape[1] > width:
        raise ActiveVisionError(
            f"query descriptors have {q.shape[1]} bytes, the train sets {width} at most;"
            " valid: descriptors of one detector"
        )
    words = np.ascontiguousarray(np.pad(q, ((0, 0), (0, width - q.shape[1])))).view(np.uint64)
    nearest, first, second = hamming_two_nearest(
        words, trains._stack, trains._offset.astype(np.int64)
    )
    dist0, dist1 = first.astype(np.float64), second.astype(np.float64)  # as the matcher's
    for col, i in enumerate(trains._use):
        rows = np.flatnonzero(dist0[:, col] < ratio * dist1[:, col])
        out[i] = np.stack([rows, nearest[rows, col]], axis=1).astype(np.int64).reshape(-1, 2)
    return out
