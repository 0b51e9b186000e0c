"""Dynamic extrinsics of the head after a pan-tilt move (thesis ch. 4 §4.4.4).

Before the move both cameras are calibrated (intrinsics, distortion, world-from-camera poses).
Their images' features are matched (:func:`~ipbench.perception.matching.match`, Lowe's ratio
test) and the matches that satisfy the calibrated epipolar geometry within ``epipolar_px`` and
triangulate in front of both cameras (:class:`~ipbench.perception.stereo.StereoRig`) are the
*stable* features: world points seen by the left camera. After the move those left features are
matched to the new left image, gross mismatches are removed with a RANSAC homography, and
``cv2.solvePnPRansac`` (then ``cv2.solvePnPRefineLM`` on its inliers) gives the new left pose.
The right camera follows from the kinematic chain (:func:`right_from_chain`).

Why a homography and not a fundamental matrix: a PTU move is nearly a pure rotation about
the camera (the optical centre sits 0.134 m ahead of and 0.092 m above the tilt axis,
``assets/head/ptu_d46.xml``), so the translation is a few cm at most. For a
pure rotation the before/after views are related by the homography ``K R K^-1`` whatever the
depths, whereas the fundamental matrix ``K^-T [t]x R K^-1`` vanishes as ``t -> 0``: its
estimate is degenerate and RANSAC would accept mismatches. The small translation leaves
parallax ``f |t| (1/z_near - 1/z_far)``: 4 px for a 3 deg pan and 2 deg tilt (the camera
moves 9.6 mm) at f = 1519 px over 0.9-1.2 m, 13 px for 10 deg and 5 deg. The homography
threshold (:data:`HOMOGRAPHY_PX` = 10 px) is therefore a gross filter only (raise it for large
moves close to the scene); the pose's precision comes from PnP's own RANSAC threshold
(:data:`PNP_PX` = 2 px, four times a 0.5 px feature noise) and the
refinement.

Settings chosen from the geometry above, not tuned on any result: :data:`EPIPOLAR_PX` = 2 px
(the before-move extrinsics are calibrated: the thesis' stereo residuals are below 0.3 mm,
Table 4.2; the encoder-only ±5 px of Mohamed et al. 2018 does not apply), at least
:data:`MIN_INLIERS` = 12 points at every stage (6 pose unknowns, 2 equations a point: 4-fold
redundancy), RANSAC confidence 0.999.

Conventions as :mod:`ipbench.perception.stereo`: OpenCV camera axes (x right, y down, z
forward), poses are 4x4 world-from-camera transforms in m, ``T_a_b`` maps frame ``b``'s
coordinates to frame ``a``'s (``b_to_a`` in :mod:`~ipbench.perception.calibration.poses`).
Pixels are as observed (distorted); they are undistorted for the triangulation and the
homography, and PnP models the distortion itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ipbench.perception.calibration.errors import CalibrationError
from ipbench.perception.calibration.poses import as_transform, from_rvec_tvec, invert
from ipbench.perception.features2d import DEFAULT_MAX_FEATURES, ActiveVisionError, Features, detect
from ipbench.perception.matching import LOWE_RATIO, match
from ipbench.perception.stereo import StereoRig

__all__ = [
    "EPIPOLAR_PX",
    "HOMOGRAPHY_PX",
    "MIN_INLIERS",
    "PNP_PX",
    "DynamicUpdate",
    "right_from_chain",
    "update_left_pose",
    "update_left_pose_from_features",
]

EPIPOLAR_PX = 2.0
HOMOGRAPHY_PX = 10.0
PNP_PX = 2.0
MIN_INLIERS = 12
_CONFIDENCE = 0.999
_ITERATIONS = 2000
_DIST_LENGTHS = (4, 5, 8, 12, 14)  # the distortion models OpenCV accepts


@dataclass(frozen=True, eq=False)
class DynamicUpdate:
    """The left camera's pose after a PTU move, from features it saw before the move.

    Attributes
    ----------
    T_world_left : (4, 4) float array
        New world-from-left-camera pose, m.
    n_inliers : int
        PnP inliers (the points the refined pose uses).
    rms_px : float
        Reprojection RMS of the inliers under the refined pose (with distortion), px.
    n_matches : int
        Stable before-left features matched in the after-left image (ratio test).
    n_stereo : int
        Stable features: before-move left/right matches within the epipolar tolerance,
        triangulated in front of both cameras.
    n_homography : int
        Matches kept by the RANSAC homography filter.
    points_world : (n_inliers, 3) float array
        The inliers' triangulated world points, m.
    xy_after : (n_inliers, 2) float array
        Their observed (distorted) pixels in the after-left image, px.
    """

    T_world_left: np.ndarray
    n_inliers: int
    rms_px: float
    n_matches: int
    n_stereo: int
    n_homography: int
    points_world: np.ndarray
    xy_after: np.ndarray


def _matrix(name: str, value, shape: tuple[int, int]) -> np.ndarray:
    try:
        array = np.asarray(value, np.float64)
    except (TypeError, ValueError) as error:
        raise CalibrationError(
            f"{name} is not numeric ({error}); valid: a finite {shape} matrix"
        ) from None
    if array.shape != shape:
        raise CalibrationError(f"{name} has shape {array.shape}; valid: a finite {shape} matrix")
    if not np.all(np.isfinite(array)):
        raise CalibrationError(f"{name} has non-finite values; valid: a finite {shape} matrix")
    return array


def _intrinsics(name: str, value) -> np.ndarray:
    K = _matrix(name, value, (3, 3))
    if not (K[0, 0] > 0 and K[1, 1] > 0 and np.array_equal(K[2], [0.0, 0.0, 1.0])):
        raise CalibrationError(
            f"{name} = {K.tolist()} is not a camera matrix; valid: [[fx, s, cx], [0, fy, cy],"
            " [0, 0, 1]] with fx, fy > 0 px"
        )
    return K


def _distortion(name: str, value) -> np.ndarray | None:
    if value is None:
        return None
    try:
        array = np.asarray(value, np.float64).ravel()
    except (TypeError, ValueError) as error:
        raise CalibrationError(f"{name} is not numeric ({error}); valid: None or a list") from None
    problem = (
        f"has {len(array)} coefficients" if len(array) not in _DIST_LENGTHS
        else "has non-finite values" if not np.all(np.isfinite(array)) else ""
    )  # fmt: skip
    if problem:
        raise CalibrationError(
            f"{name} {problem}; valid: None or {', '.join(map(str, _DIST_LENGTHS))} finite"
            " OpenCV coefficients (k1, k2, p1, p2[, k3, ...])"
        )
    return array


def _undistort(xy: np.ndarray, K: np.ndarray, dist: np.ndarray | None) -> np.ndarray:
    """Ideal (undistorted) pixels of observed ones, in the same camera matrix ``K``."""
    if dist is None or len(xy) == 0:
        return np.asarray(xy, np.float64).reshape(-1, 2)
    out = cv2.undistortPoints(np.asarray(xy, np.float64).reshape(-1, 1, 2), K, dist, P=K)
    return out.reshape(-1, 2)


def _enough(count: int, need: int, what: str, fix: str) -> None:
    if count < need:
        raise CalibrationError(f"only {count} {what}; need at least {need}: {fix}")


def update_left_pose_from_features(
    before_left: Features,
    before_right: Features,
    K_l: np.ndarray,
    K_r: np.ndarray,
    dist_l: np.ndarray | None,
    dist_r: np.ndarray | None,
    T_world_left_before: np.ndarray,
    T_world_right_before: np.ndarray,
    after_left: Features,
    *,
    ratio: float = LOWE_RATIO,
    epipolar_px: float = EPIPOLAR_PX,
    homography_px: float = HOMOGRAPHY_PX,
    pnp_px: float = PNP_PX,
    min_inliers: int = MIN_INLIERS,
) -> DynamicUpdate:
    """:func:`update_left_pose` on features already detected (one type, observed pixels)."""
    K_l, K_r = _intrinsics("K_l", K_l), _intrinsics("K_r", K_r)
    dist_l, dist_r = _distortion("dist_l", dist_l), _distortion("dist_r", dist_r)
    T_wl = as_transform(T_world_left_before, "T_world_left_before")
    T_wr = as_transform(T_world_right_before, "T_world_right_before")
    for name, value in (("epipolar_px", epipolar_px), ("homography_px", homography_px),
                        ("pnp_px", pnp_px)):  # fmt: skip
        number = isinstance(value, (int, float, np.integer, np.floating))
        if not (number and np.isfinite(value) and value > 0):
            raise CalibrationError(f"{name} is {value!r}; valid: a positive number of pixels")
    if not (isinstance(min_inliers, (int, np.integer)) and min_inliers >= 6):
        raise CalibrationError(
            f"min_inliers is {min_inliers!r}; valid: an int >= 6 (a pose from fewer is not"
            f" overdetermined; default {MIN_INLIERS})"
        )
    types = {f.feature_type for f in (before_left, before_right, after_left)}
    if len(types) != 1:
        raise CalibrationError(
            f"features of types {sorted(types)}; valid: the three images' features of one type"
        )
    if not 0.0 < ratio <= 1.0:
        raise CalibrationError(f"ratio is {ratio!r}; valid: 0 < ratio <= 1 (Lowe: 0.8)")
    kind = types.pop()
    texture = "point the head at a textured, well-lit part of the scene"
    for name, feats in (("before-left", before_left), ("before-right", before_right),
                        ("after-left", after_left)):  # fmt: skip
        _enough(len(feats), min_inliers, f"{kind} features in the {name} image", texture)

    # stable features: left/right matches consistent with the calibrated stereo geometry
    pairs = match(before_left, before_right, ratio)
    xl = _undistort(before_left.xy[pairs[:, 0]], K_l, dist_l)
    xr = _undistort(before_right.xy[pairs[:, 1]], K_r, dist_r)
    rig = StereoRig(K_l, T_wl, K_r, T_wr)
    keep = rig.epipolar_distance(xl, xr) <= epipolar_px if len(pairs) else np.zeros(0, bool)
    points = rig.triangulate(xl[keep], xr[keep])
    front = np.all(rig.depths(points) > 0, axis=1) & np.all(np.isfinite(points), axis=1)
    stable_index, points = pairs[keep, 0][front], points[front]
    _enough(
        len(points), min_inliers,
        f"stable features (before-move left/right matches within {epipolar_px} px of the"
        " epipolar line, in front of both cameras)",
        "the cameras must overlap on a textured scene and their poses before the move must be"
        " calibrated",
    )  # fmt: skip

    # the stable left features in the after-move left image
    stable = before_left.subset(stable_index)
    moved = match(stable, after_left, ratio)
    _enough(
        len(moved), min_inliers, "stable features matched after the move",
        "the move must keep part of the before-move view in sight (smaller pan/tilt steps)",
    )  # fmt: skip
    obj = points[moved[:, 0]]
    img = after_left.xy[moved[:, 1]].astype(np.float64)
    src = _undistort(stable.xy[moved[:, 0]], K_l, dist_l)
    dst = _undistort(img, K_l, dist_l)
    H, mask = cv2.findHomography(
        src, dst, cv2.RANSAC, float(homography_px), maxIters=_ITERATIONS, confidence=_CONFIDENCE
    )
    if H is None or mask is None:
        raise CalibrationError(
            f"no homography between the {len(moved)} before/after matches: the matches are"
            " degenerate (collinear or repeated); point the head at a textured scene"
        )
    hom = mask.ravel().astype(bool)
    _enough(
        int(hom.sum()), min_inliers,
        f"matches within {homography_px} px of the before/after homography",
        "most matches are wrong or the move translated the camera far; raise homography_px"
        " or make smaller moves",
    )  # fmt: skip
    obj, img = obj[hom], img[hom]

    ok, rvec, tvec, inliers = cv2.solvePnPRansac(
        obj, img, K_l, dist_l, iterationsCount=_ITERATIONS, reprojectionError=float(pnp_px),
        confidence=_CONFIDENCE, flags=cv2.SOLVEPNP_ITERATIVE,
    )  # fmt: skip
    n = 0 if not ok or inliers is None else len(inliers)
    _enough(
        n, min_inliers, f"PnP inliers within {pnp_px} px",
        "the stable points do not agree on one pose: check the before-move calibration and"
        " the intrinsics, or raise pnp_px",
    )  # fmt: skip
    index = inliers.ravel()
    obj, img = obj[index], img[index]
    rvec, tvec = cv2.solvePnPRefineLM(obj, img, K_l, dist_l, rvec, tvec)
    projected, _ = cv2.projectPoints(obj, rvec, tvec, K_l, dist_l)
    rms = float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - img) ** 2, axis=1))))
    T_world_left = invert(from_rvec_tvec(rvec, tvec))  # solvePnP gives world-to-camera
    return DynamicUpdate(
        T_world_left=T_world_left,
        n_inliers=len(index),
        rms_px=rms,
        n_matches=len(moved),
        n_stereo=len(points),
        n_homography=int(hom.sum()),
        points_world=obj,
        xy_after=img,
    )


def _detect(name: str, image: np.ndarray, feature_type: str, max_features: int) -> Features:
    try:
        return detect(image, feature_type, max_features=max_features)
    except ActiveVisionError as error:
        raise CalibrationError(f"{name}: {error}") from error


def update_left_pose(
    before_left_img: np.ndarray,
    before_right_img: np.ndarray,
    K_l: np.ndarray,
    K_r: np.ndarray,
    dist_l: np.ndarray | None,
    dist_r: np.ndarray | None,
    T_world_left_before: np.ndarray,
    T_world_right_before: np.ndarray,
    after_left_img: np.ndarray,
    feature_type: str = "sift",
    *,
    max_features: int = DEFAULT_MAX_FEATURES,
    ratio: float = LOWE_RATIO,
    epipolar_px: float = EPIPOLAR_PX,
    homography_px: float = HOMOGRAPHY_PX,
    pnp_px: float = PNP_PX,
    min_inliers: int = MIN_INLIERS,
) -> DynamicUpdate:
    """The left camera's world pose after a PTU move, from what both cameras saw before it.

    Images are uint8 grey (H, W) or RGB (H, W, 3) as captured (distorted); ``K_*`` (3, 3) px and
    ``dist_*`` (OpenCV coefficients or None) are the cameras' calibrated intrinsics;
    ``T_world_*_before`` (4, 4) m their calibrated poses before the move. Features of
    ``feature_type`` (:data:`~ipbench.perception.features2d.FEATURE_TYPES`, at most
    ``max_features`` per image) are detected in the three images and the pose follows the
    module docstring. Raises :class:`CalibrationError` when any stage keeps fewer than
    ``min_inliers`` features, saying which stage and what to change.
    """
    args = (feature_type, max_features)
    before_left = _detect("before_left_img", before_left_img, *args)
    before_right = _detect("before_right_img", before_right_img, *args)
    after_left = _detect("after_left_img", after_left_img, *args)
    return update_left_pose_from_features(
        before_left, before_right, K_l, K_r, dist_l, dist_r, T_world_left_before,
        T_world_right_before, after_left, ratio=ratio, epipolar_px=epipolar_px,
        homography_px=homography_px, pnp_px=pnp_px, min_inliers=min_inliers,
    )  # fmt: skip


def right_from_chain(T_world_left_new: np.ndarray, T_left_right: np.ndarray) -> np.ndarray:
    """(4, 4) world-from-right-camera pose: ``T_world_left_new @ T_left_right``, m.

    ``T_left_right`` is the right camera's pose in the left camera's frame at the new PTU
    angles, from the calibrated kinematic chain (left camera -> its PTU's tilt and pan at the
    encoder angles -> the PTU bases -> the right PTU's pan and tilt -> right camera).
    """
    return as_transform(T_world_left_new, "T_world_left_new") @ as_transform(
        T_left_right, "T_left_right"
    )
