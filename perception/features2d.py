"""2-D local features for the active-vision behaviours (thesis ch. 3 §3.3): detect, match.

The thesis compares SIFT, SURF and KAZE on the Nikon/PTU head (Table 3.3: SIFT 77 %, KAZE 83 %,
SURF 60 %). SURF is patented ("non-free") and is in no pip wheel of OpenCV (it needs a build of
opencv-contrib with ``OPENCV_ENABLE_NONFREE``), so it is not offered; AKAZE and ORB, the free
binary-descriptor detectors in the ``opencv-python-headless`` 4.x wheel, take its place as the
fast options.

Settings (OpenCV's defaults unless said; no value was tuned on any result):

- ``sift``: ``cv2.SIFT_create(nfeatures=max_features)``, 3 octave layers, contrast threshold
  0.04, edge threshold 10, sigma 1.6 (Lowe 2004); 128-D float descriptors, L2 norm.
- ``kaze``: ``cv2.KAZE_create()``, threshold 0.001, 4 octaves, 4 sublevels, PM-G2 diffusivity
  (Alcantarilla et al. 2012); 64-D float descriptors, L2 norm.
- ``akaze``: ``cv2.AKAZE_create()``, MLDB descriptor of 486 bits (61 bytes), threshold 0.001
  (Alcantarilla et al. 2013); Hamming norm.
- ``orb``: ``cv2.ORB_create(nfeatures=max_features)``, 8 levels, scale factor 1.2, FAST
  threshold 20, Harris score (Rublee et al. 2011); 256-bit (32-byte) BRIEF, Hamming norm.

KAZE and AKAZE have no feature budget of their own: :func:`detect` keeps the ``max_features``
strongest responses of every type (a stable sort, so equal inputs give equal outputs).

Matching: the two nearest neighbours by brute force (exact, hence deterministic;
``cv2.batchDistance``, the kernel of ``cv2.BFMatcher``), kept when
the nearest is closer than :data:`LOWE_RATIO` = 0.8 times the second (Lowe 2004, §7.1: this
"eliminates 90 % of the false matches while discarding less than 5 % of the correct" ones).

Keypoint ``angle`` is in degrees as OpenCV reports it, the same sense for all four types (a
test checks it): a patch turned by ``theta`` in the image plane, i.e. ``p -> R(theta) p`` with
``R = [[cos, -sin], [sin, cos]]`` in pixel coordinates (x right, y down), has its keypoint
angles increased by ``theta``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ipbench.perception.cloud import PerceptionError

__all__ = [
    "DEFAULT_MAX_FEATURES",
    "FEATURE_TYPES",
    "LOWE_RATIO",
    "ActiveVisionError",
    "Features",
    "detect",
    "make_detector",
    "match",
    "match_many",
    "norm_of",
    "to_gray",
]

FEATURE_TYPES = ("sift", "kaze", "akaze", "orb")
DEFAULT_MAX_FEATURES = 2000  # per image; a budget for the <= 0.5 s saccade cycle (issue 13)
LOWE_RATIO = 0.8  # Lowe 2004, §7.1
_NORMS = {
    "sift": cv2.NORM_L2,
    "kaze": cv2.NORM_L2,
    "akaze": cv2.NORM_HAMMING,
    "orb": cv2.NORM_HAMMING,
}


class ActiveVisionError(PerceptionError):
    """Root exception of the active-vision modules (features2d, object_database, recognition,
    vergence, stereo, saliency); messages say what was wrong and what is valid."""


def _check_type(feature_type: str) -> str:
    if feature_type not in FEATURE_TYPES:
        raise ActiveVisionError(
            f"unknown feature type {feature_type!r}; valid: {', '.join(FEATURE_TYPES)}"
            " (SURF is non-free and in no OpenCV pip wheel)"
        )
    return feature_type


def norm_of(feature_type: str) -> int:
    """The OpenCV norm of a type's descriptors: ``cv2.NORM_L2`` or ``cv2.NORM_HAMMING``."""
    return _NORMS[_check_type(feature_type)]


def make_detector(
    feature_type: str, max_features: int = DEFAULT_MAX_FEATURES
) -> tuple[cv2.Feature2D, int]:
    """A new OpenCV detector/descriptor of ``feature_type`` and its norm (module docstring)."""
    _check_type(feature_type)
    if feature_type == "sift":
        detector = cv2.SIFT_create(nfeatures=max_features)
    elif feature_type == "kaze":
        detector = cv2.KAZE_create()
    elif feature_type == "akaze":
        detector = cv2.AKAZE_create()
    else:
        detector = cv2.ORB_create(nfeatures=max_features)
    return detector, _NORMS[feature_type]


@dataclass(frozen=True, eq=False)
class Features:
    """Keypoints and descriptors of one image.

    Attributes
    ----------
    feature_type : str
        One of :data:`FEATURE_TYPES`.
    xy : (N, 2) float32 array
        Keypoint positions ``(u, v) = (column, row)``, px.
    size : (N,) float32 array
        Keypoint diameters, px.
    angle : (N,) float32 array
        Keypoint orientations as OpenCV reports them, deg, image-plane sense (module docstring).
    response : (N,) float32 array
        Detector responses (larger is stronger).
    descriptors : (N, D) array
        float32 (SIFT D = 128, KAZE D = 64) or uint8 bytes (AKAZE D = 61, ORB D = 32).
    """

    feature_type: str
    xy: np.ndarray
    size: np.ndarray
    angle: np.ndarray
    response: np.ndarray
    descriptors: np.ndarray

    def __len__(self) -> int:
        return len(self.xy)

    def subset(self, index: np.ndarray) -> Features:
        """The features at ``index`` (integer indices or a boolean mask (N,))."""
        return Features(
            self.feature_type,
            self.xy[index],
            self.size[index],
            self.angle[index],
            self.response[index],
            self.descriptors[index],
        )


def to_gray(image: np.ndarray) -> np.ndarray:
    """(H, W) uint8 grey image from an (H, W) or (H, W, 3) RGB uint8 image."""
    array = np.asarray(image)
    if (
        array.dtype != np.uint8
        or array.ndim not in (2, 3)
        or (array.ndim == 3 and array.shape[2] != 3)
    ):
        raise ActiveVisionError(
            f"image has dtype {array.dtype} and shape {array.shape}; valid: uint8 (H, W) grey"
            " or (H, W, 3) RGB"
        )
    if array.ndim == 3:
        array = cv2.cvtColor(array, cv2.COLOR_RGB2GRAY)
    return np.ascontiguousarray(array)


def _empty(feature_type: str) -> Features:
    width = {"sift": 128, "kaze": 64, "akaze": 61, "orb": 32}[feature_type]
    dtype = np.float32 if _NORMS[feature_type] == cv2.NORM_L2 else np.uint8
    z = np.zeros(0, np.float32)
    return Features(
        feature_type, np.zeros((0, 2), np.float32), z, z, z, np.zeros((0, width), dtype)
    )


def detect(
    image: np.ndarray,
    feature_type: str,
    mask: np.ndarray | None = None,
    max_features: int = DEFAULT_MAX_FEATURES,
) -> Features:
    """Detect and describe the ``max_features`` strongest keypoints of ``image``.

    ``image`` is uint8 grey (H, W) or RGB (H, W, 3); ``mask`` (H, W), if given, keeps the
    keypoints where it is non-zero. Deterministic: the same input gives the same output.
    """
    _check_type(feature_type)
    if not (isinstance(max_features, (int, np.integer)) and max_features > 0):
        raise ActiveVisionError(f"max_features is {max_features!r}; valid: a positive int")
    gray = to_gray(image)
    if mask is not None:
        mask = np.asarray(mask)
        if mask.shape != gray.shape:
            raise ActiveVisionError(
                f"mask has shape {mask.shape}, the image {gray.shape}; valid: the image's (H, W)"
            )
        mask = (mask != 0).astype(np.uint8)
    detector, _ = make_detector(feature_type, int(max_features))
    keypoints, descriptors = detector.detectAndCompute(gray, mask)
    if not keypoints or descriptors is None:
        return _empty(feature_type)
    xy = np.array([k.pt for k in keypoints], np.float32).reshape(-1, 2)
    size = np.array([k.size for k in keypoints], np.float32)
    angle = np.array([k.angle for k in keypoints], np.float32)
    response = np.array([k.response for k in keypoints], np.float32)
    # strongest first; ties by position, so the order does not depend on the detector's
    order = np.lexsort((xy[:, 0], xy[:, 1], -response))[: int(max_features)]
    return Features(
        feature_type, xy[order], size[order], angle[order], response[order], descriptors[order]
    )


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
    if not 0.0 < ratio <= 1.0:
        raise ActiveVisionError(f"ratio is {ratio!r}; valid: 0 < ratio <= 1 (Lowe: 0.8)")
    if len(query) == 0 or len(train) < 2:
        return np.zeros((0, 2), np.int64)
    norm = norm_of(query.feature_type)
    # cv2.batchDistance with K = 2 is the exact 2-NN search that cv2.BFMatcher.knnMatch runs
    # (same distance kernels, same order, same distances: Hamming as int32, L2 as float32),
    # minus the per-match DMatch objects, which made Python the bottleneck (issue 13)
    dtype = cv2.CV_32S if norm == cv2.NORM_HAMMING else cv2.CV_32F  # as BFMatcher
    dist, nidx = cv2.batchDistance(query.descriptors, train.descriptors, dtype, normType=norm, K=2)
    dist = dist.astype(np.float64)  # DMatch.distance is a float32, compared as a Python float
    keep = (nidx[:, 1] >= 0) & (dist[:, 0] < ratio * dist[:, 1])
    rows = np.flatnonzero(keep)
    return np.stack([rows, nidx[rows, 0]], axis=1).astype(np.int64).reshape(-1, 2)


_EXACT_SQ = 2.0**22  # float32 sums of integers below 2**24 are exact; |a|^2 + |b|^2 stays below
_BLOCK = 4096  # train descriptors per matrix product: (Q, 4096) float32 blocks, <= 33 MB


def _integer_valued(descriptors: np.ndarray) -> bool:
    """True when float descriptors are small non-negative integers (OpenCV's SIFT stores its
    bytes as floats), so that a float32 matrix product gives their squared distances exactly."""
    d = descriptors
    return bool(
        d.dtype == np.float32
        and len(d)
        and d.min() >= 0
        and np.array_equal(d, np.rint(d))
        and float(np.max(np.einsum("ij,ij->i", d, d, dtype=np.float64))) < _EXACT_SQ
    )


def match_many(
    query: Features, trains: list[Features] | tuple[Features, ...], ratio: float = LOWE_RATIO
) -> list[np.ndarray]:
    """:func:`match` of ``query`` to each of ``trains``: the same (M_i, 2) arrays, exactly.

    Integer-valued float descriptors (SIFT's) take their squared L2 distances from one float32
    matrix product per block of train descriptors (exact for integers: every partial sum is an
    integer below 2**24), then the same float32 square root and ratio test as the brute-force
    matcher; other descriptors go through :func:`match` one train set at a time.
    """
    trains = list(trains)
    if any(t.feature_type != query.feature_type for t in trains):
        raise ActiveVisionError(
            f"cannot match {query.feature_type} features to"
            f" {sorted({t.feature_type for t in trains})} features; valid: features of the"
            " same type"
        )
    if not 0.0 < ratio <= 1.0:
        raise ActiveVisionError(f"ratio is {ratio!r}; valid: 0 < ratio <= 1 (Lowe: 0.8)")
    empty = np.zeros((0, 2), np.int64)
    out = [empty] * len(trains)
    use = [i for i, t in enumerate(trains) if len(t) >= 2]
    if len(query) == 0 or not use:
        return out
    fast = _integer_valued(query.descriptors) and all(
        _integer_valued(trains[i].descriptors) for i in use
    )
    if not fast:
        return [match(query, t, ratio) for t in trains]
    q = query.descriptors
    q_sq = np.einsum("ij,ij->i", q, q)
    k = 0
    while k < len(use):  # blocks of whole train sets, about _BLOCK descriptors each
        block, size = [], 0
        while k < len(use) and (not block or size + len(trains[use[k]]) <= _BLOCK):
            block.append(use[k])
            size += len(trains[use[k]])
            k += 1
        t = np.concatenate([trains[i].descriptors for i in block])
        d2 = q_sq[:, None] + np.einsum("ij,ij->i", t, t)[None, :] - 2.0 * (q @ t.T)
        start = 0
        for i in block:
            part = d2[:, start : start + len(trains[i])]
            start += len(trains[i])
            nearest = np.argmin(part, axis=1)
            two = np.partition(part, 1, axis=1)[:, :2]
            dist = np.sqrt(two).astype(np.float64)  # float32 sqrt, as the matcher's
            rows = np.flatnonzero(dist[:, 0] < ratio * dist[:, 1])
            out[i] = np.stack([rows, nearest[rows]], axis=1).astype(np.int64).reshape(-1, 2)
    return out
