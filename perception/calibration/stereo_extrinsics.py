"""Stereo extrinsics of the head from target views (thesis ch. 4, eq. 4.7), refined jointly.

Both cameras see the same calibration target in each view; with ``target_to_left[i]`` and
``target_to_right[i]`` their target poses (``cv2.solvePnP``), eq. 4.7 gives one estimate per
view of the left-to-right transform (``T_right_left``, OpenCV's stereo ``(R, T)``: a point
``p_l`` in the left camera frame is ``R p_l + T`` in the right camera frame)::

    T_right_left = T_right_target · T_left_target⁻¹ = target_to_right[i] · target_to_left[i]⁻¹

:func:`stereo_from_target_poses` averages the views: the rotations by their chordal L2 mean
(the unit-quaternion eigenvector mean of scipy's ``Rotation.mean``, Markley et al. 2007, a
proper rotation unlike an element-wise mean of matrices), the translations arithmetically.

Each view's PnP pose errs on its own, so :func:`refine_stereo` then minimises the
reprojection error of all corners in both images jointly over ``T_right_left`` and every
view's target-to-left pose (bundle adjustment with ``scipy.optimize.least_squares``; the
intrinsics stay fixed, as ``cv2.stereoCalibrate`` with ``CALIB_FIX_INTRINSIC``). The RMS is
OpenCV's: ``sqrt(sum of squared corner distances / corners in both images)``, px.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation
from threadpoolctl import threadpool_limits

from ipbench.perception.calibration.errors import CalibrationError
from ipbench.perception.calibration.poses import (
    as_transform,
    as_transforms,
    from_rvec_tvec,
    invert,
    rotation_angle_deg,
    to_rvec_tvec,
    translation_error_mm,
)

__all__ = [
    "StereoExtrinsics",
    "StereoRefinement",
    "refine_stereo",
    "stereo_from_target_poses",
]

# PnP (hence a view's target pose) needs four points
MIN_POINTS_PER_VIEW = 4
# the lengths OpenCV accepts for distortion coefficients
_DIST_SIZES = (0, 4, 5, 8, 12, 14)


@dataclass(frozen=True, eq=False)
class StereoExtrinsics:
    """The head's stereo extrinsics averaged over views (eq. 4.7).

    Attributes
    ----------
    left_to_right : (4, 4) float64 array
        ``T_right_left``, m: left-camera coordinates to right-camera coordinates.
    rotation_deviation_deg : (n_views,) float64 array
        Angle between each view's eq. 4.7 rotation and the mean, deg.
    translation_deviation_mm : (n_views,) float64 array
        Distance between each view's eq. 4.7 translation and the mean, mm.
    """

    left_to_right: np.ndarray
    rotation_deviation_deg: np.ndarray
    translation_deviation_mm: np.ndarray

    @property
    def n_views(self) -> int:
        """Views averaged."""
        return len(self.rotation_deviation_deg)

    @property
    def baseline_m(self) -> float:
        """Distance between the two optical centres, m."""
        return float(np.linalg.norm(self.left_to_right[:3, 3]))


@dataclass(frozen=True, eq=False)
class StereoRefinement:
    """Stereo extrinsics after joint bundle adjustment.

    Attributes
    ----------
    left_to_right : (4, 4) float64 array
        Refined ``T_right_left``, m.
    target_to_left : (n_views, 4, 4) float64 array
        Refined target pose of every view in the left camera frame, m.
    rms_px : float
        RMS reprojection error per corner over both images after refinement, px.
    initial_rms_px : float
        The same before refinement, px.
    n_evaluations : int
        Residual evaluations of the solver.
    converged : bool
        Whether ``least_squares`` met a convergence tolerance.
    """

    left_to_right: np.ndarray
    target_to_left: np.ndarray
    rms_px: float
    initial_rms_px: float
    n_evaluations: int
    converged: bool


def stereo_from_target_poses(
    target_to_left: Sequence, target_to_right: Sequence
) -> StereoExtrinsics:
    """Eq. 4.7 averaged over views.

    ``target_to_left[i]`` and ``target_to_right[i]`` are (4, 4) poses of the target seen by
    the left and right camera in view ``i``, m.
    """
    left = as_transforms(target_to_left, "target_to_left")
    right = as_transforms(target_to_right, "target_to_right")
    if len(left) != len(right) or len(left) == 0:
        raise CalibrationError(
            f"got {len(left)} left and {len(right)} right target poses; valid: one or more "
            "views, each with the target's pose in both cameras, in the same order"
        )
    per_view = np.stack([r @ invert(lt) for lt, r in zip(left, right, strict=True)])
    mean = np.eye(4)
    mean[:3, :3] = Rotation.from_matrix(per_view[:, :3, :3]).mean().as_matrix()
    mean[:3, 3] = per_view[:, :3, 3].mean(axis=0)
    return StereoExtrinsics(
        left_to_right=mean,
        rotation_deviation_deg=np.atleast_1d(rotation_angle_deg(per_view, mean)),
        translation_deviation_mm=np.atleast_1d(translation_error_mm(per_view, mean)),
    )


def _camera(K, dist, side: str) -> tuple[np.ndarray, np.ndarray]:
    K = np.asarray(K, dtype=np.float64)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
        raise CalibrationError(
            f"K_{side} is not a camera matrix (shape {K.shape}); valid: a finite (3, 3) "
            "[[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0, px"
        )
    dist = np.zeros(0) if dist is None else np.asarray(dist, dtype=np.float64).reshape(-1)
    if dist.size not in _DIST_SIZES or not np.all(np.isfinite(dist)):
        raise CalibrationError(
            f"d_{side} has {dist.size} coefficients; valid: None or {_DIST_SIZES[1:]} finite "
            "OpenCV distortion coefficients (k1, k2, p1, p2[, k3, ...])"
        )
    return K, dist


def _views(object_points, left_points, right_points) -> list[tuple[np.ndarray, ...]]:
    left_list, right_list = list(left_points), list(right_points)
    if len(left_list) != len(right_list) or not left_list:
        raise CalibrationError(
            f"got {len(left_list)} left and {len(right_list)} right views of corners; valid: "
            "one or more views, each with the corners in both images"
        )
    shared = isinstance(object_points, np.ndarray) and object_points.ndim == 2
    objects = [object_points] * len(left_list) if shared else list(object_points)
    if len(objects) != len(left_list):
        raise CalibrationError(
            f"got {len(objects)} views of object points for {len(left_list)} views of "
            "corners; valid: one (N, 3) array shared by all views, or one per view"
        )
    views = []
    for i, (obj, lp, rp) in enumerate(zip(objects, left_list, right_list, strict=True)):
        obj = np.asarray(obj, dtype=np.float64).reshape(-1, 3)
        lp = np.asarray(lp, dtype=np.float64).reshape(-1, 2)
        rp = np.asarray(rp, dtype=np.float64).reshape(-1, 2)
        if not len(obj) == len(lp) == len(rp) or len(obj) < MIN_POINTS_PER_VIEW:
            raise CalibrationError(
                f"view {i} has {len(obj)} object points, {len(lp)} left and {len(rp)} right "
                f"corners; valid: the same number, at least {MIN_POINTS_PER_VIEW}, in the "
                "same order (object points in m, corners in px)"
            )
        if not (np.all(np.isfinite(obj)) and np.all(np.isfinite(lp)) and np.all(np.isfinite(rp))):
            raise CalibrationError(f"view {i} has NaN or infinite points; valid: finite numbers")
        views.append((obj, lp, rp))
    return views


def _initial_poses(views, K, dist, target_to_left) -> np.ndarray:
    if target_to_left is not None:
        poses = as_transforms(target_to_left, "target_to_left")
        if len(poses) != len(views):
            raise CalibrationError(
                f"got {len(poses)} target_to_left poses for {len(views)} views; valid: one "
                "per view, or None to estimate them with cv2.solvePnP on the left corners"
            )
        return poses
    poses = []
    for i, (obj, left, _) in enumerate(views):
        ok, rvec, tvec = cv2.solvePnP(obj, left, K, dist)
        if not ok:
            raise CalibrationError(
                f"cv2.solvePnP found no target pose for view {i}; check the corners and "
                "their order against the object points"
            )
        poses.append(from_rvec_tvec(rvec, tvec))
    return np.stack(poses)


def refine_stereo(
    object_points,
    left_points: Sequence,
    right_points: Sequence,
    K_left,
    d_left,
    K_right,
    d_right,
    initial,
    target_to_left: Sequence | None = None,
) -> StereoRefinement:
    """Bundle-adjust ``T_right_left`` and the views' target poses, intrinsics fixed.

    Parameters
    ----------
    object_points : (N, 3) array, or list of (N_i, 3) arrays
        Target corners in the target frame, m: one array for all views, or one per view.
    left_points, right_points : list of (N_i, 2) arrays
        The corners detected in each view's left and right image, px (OpenCV's
        ``(N, 1, 2)`` layout is accepted).
    K_left, d_left, K_right, d_right : arrays
        Each camera's (3, 3) matrix, px, and OpenCV distortion coefficients (or None).
    initial : (4, 4) array
        Starting ``T_right_left``, m (e.g. :func:`stereo_from_target_poses`).
    target_to_left : list of (4, 4) arrays, optional
        Starting target poses in the left camera; by default ``cv2.solvePnP`` on the left
        corners.
    """
    K_l, d_l = _camera(K_left, d_left, "left")
    K_r, d_r = _camera(K_right, d_right, "right")
    views = _views(object_points, left_points, right_points)
    stereo = as_transform(initial, "initial")
    poses = _initial_poses(views, K_l, d_l, target_to_left)

    sizes = [4 * len(obj) for obj, _, _ in views]
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    n_params = 6 + 6 * len(views)

    def evaluate(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residuals (projected - detected, px) and their exact Jacobian, from the derivatives
        OpenCV's ``projectPoints`` and ``composeRT`` return."""
        out = np.empty(offsets[-1])
        jac = np.zeros((offsets[-1], n_params))
        r_s, t_s = x[0:3], x[3:6]
        for k, (obj, left, right) in enumerate(views):
            view = slice(6 + 6 * k, 12 + 6 * k)
            r_k, t_k = x[6 + 6 * k : 9 + 6 * k], x[9 + 6 * k : 12 + 6 * k]
            r_r, t_r, dr_dr1, _, dr_dr2, _, dt_dr1, dt_dt1, dt_dr2, dt_dt2 = cv2.composeRT(
                r_k, t_k, r_s, t_s
            )
            projected_l, J_l = cv2.projectPoints(obj, r_k, t_k, K_l, d_l)
            projected_r, J_r = cv2.projectPoints(obj, r_r, t_r, K_r, d_r)
            n = len(obj)
            rows_l = slice(offsets[k], offsets[k] + 2 * n)
            rows_r = slice(offsets[k] + 2 * n, offsets[k + 1])
            out[rows_l] = (projected_l.reshape(-1, 2) - left).reshape(-1)
            out[rows_r] = (projected_r.reshape(-1, 2) - right).reshape(-1)
            jac[rows_l, view] = J_l[:, :6]
            J_rot, J_trans = J_r[:, :3], J_r[:, 3:6]
            jac[rows_r, view] = np.hstack([J_rot @ dr_dr1 + J_trans @ dt_dr1, J_trans @ dt_dt1])
            jac[rows_r, 0:6] = np.hstack([J_rot @ dr_dr2 + J_trans @ dt_dr2, J_trans @ dt_dt2])
        return out, jac

    cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def cached(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = evaluate(x)
        return cache[key]

    n_corners = sum(2 * len(obj) for obj, _, _ in views)
    x0 = np.concatenate([np.concatenate(to_rvec_tvec(T)) for T in (stereo, *poses)])
    initial_rms = float(np.sqrt(np.sum(cached(x0)[0] ** 2) / n_corners))
    # one BLAS thread: the problem is small, and threads spinning against busy cores made each
    # SVD of the (4N, 6 + 6n) Jacobian ~200 times slower on the 2-core test machine
    with threadpool_limits(limits=1, user_api="blas"):
        solution = least_squares(
            lambda x: cached(x)[0], x0, jac=lambda x: cached(x)[1], method="trf", x_scale="jac"
        )
    x = solution.x
    return StereoRefinement(
        left_to_right=from_rvec_tvec(x[0:3], x[3:6]),
        target_to_left=np.stack(
            [
                from_rvec_tvec(x[6 + 6 * k : 9 + 6 * k], x[9 + 6 * k : 12 + 6 * k])
                for k in range(len(views))
            ]
        ),
        rms_px=float(np.sqrt(np.sum(solution.fun**2) / n_corners)),
        initial_rms_px=initial_rms,
        n_evaluations=int(solution.nfev),
        converged=bool(solution.status > 0),
    )
