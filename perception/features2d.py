"""2-D local features for the active-vision behaviours (thesis ch. 3 §3.3): detect, describe.

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

Matching the features is :mod:`ipbench.perception.matching`'s.

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
    "ActiveVisionError",
    "Features",
    "detect",
    "make_detector",
    "norm_of",
    "to_gray",
]

FEATURE_TYPES = ("sift", "kaze", "akaze", "orb")
DEFAULT_MAX_FEATURES = 2000  # per image; a budget for the <= 0.5 s saccade cycle
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
