"""Stereo extrinsics of the head: eq. 4.7 averaged over views, then bundle adjustment.

A synthetic rig after the CloPeMa head (gerac83/ug_bluerobot ``clopema_description``): the
right camera's centre sits (0.285, -0.004, 0.041) m from the left one in the left camera frame,
the calibrated UG offset (``calibration_UG``, right PTU base relative to the left: x 0.041
forward, y -0.285 left, z 0.004 up, mapped to camera axes x right, y down, z forward; baseline
0.288 m), with the calibrated relative rpy (-2.7°, 0.3°, -1.7°) on top of verging at a point
1.3 m ahead; both Nikon D5100s in preview mode (1232 x 816 px, a quarter of 4928 x 3264) with
the 18 mm kit lens, f = 3759 / 4 px (4928 px over 23.6 mm), and the lens distortion measured on
the cell's xtion1 (``calibration_UG/xtion1_rgb_camera.yaml``) as a realistic plumb-bob model;
the thesis' board of 24 mm squares (9 x 6 inner corners) at 1.0-1.6 m; corner noise 0.2 px
[EST].
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ipbench.perception.calibration.errors import CalibrationError
from ipbench.perception.calibration.poses import (
    from_rvec_tvec,
    invert,
    rotation_angle_deg,
    to_rvec_tvec,
    translation_error_mm,
)
from ipbench.perception.calibration.stereo_extrinsics import (
    refine_stereo,
    stereo_from_target_poses,
)

SIZE = (1232, 816)  # px
F = 3759.0 / 4.0  # px
K = np.array([[F, 0.0, (SIZE[0] - 1) / 2], [0.0, F, (SIZE[1] - 1) / 2], [0.0, 0.0, 1.0]])
DIST = np.array([0.0206, -0.0987, -0.00166, 0.00059, 0.0])
RIGHT_CENTRE = np.array([0.285, -0.004, 0.041])  # m, in the left camera frame
FIXATION = np.array([RIGHT_CENTRE[0] / 2, 0.0, 1.3])  # m
SQUARE = 0.024  # m
CORNER_NOISE = 0.2  # px
N_VIEWS = 12

_grid = np.mgrid[0:9, 0:6].T.reshape(-1, 2) * SQUARE
BOARD = np.hstack([_grid - _grid.mean(axis=0), np.zeros((len(_grid), 1))])


def _left_to_right() -> np.ndarray:
    z = (FIXATION - RIGHT_CENTRE) / np.linalg.norm(FIXATION - RIGHT_CENTRE)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    verge = np.stack([x, np.cross(z, x), z], axis=1)
    right_to_left = np.eye(4)
    right_to_left[:3, :3] = verge @ Rotation.from_euler("xyz", [-2.7, 0.3, -1.7], True).as_matrix()
    right_to_left[:3, 3] = RIGHT_CENTRE
    return invert(right_to_left)


LEFT_TO_RIGHT = _left_to_right()


def _project(pose: np.ndarray) -> np.ndarray:
    rvec, tvec = to_rvec_tvec(pose)
    return cv2.projectPoints(BOARD, rvec, tvec, K, DIST)[0].reshape(-1, 2)


def _board_poses(seed: int, n: int = N_VIEWS) -> list[np.ndarray]:
    """Target-to-left poses, tilted up to 30°, whose corners all fall inside both images."""
    rng = np.random.default_rng(seed)
    poses = []
    while len(poses) < n:
        pose = np.eye(4)
        pose[:3, :3] = Rotation.from_euler("xyz", rng.uniform(-30, 30, 3), True).as_matrix()
        pose[:3, 3] = FIXATION + rng.uniform([-0.2, -0.15, -0.3], [0.2, 0.15, 0.3])
        inside = [
            np.all((p > 0) & (p < SIZE)) for p in (_project(pose), _project(LEFT_TO_RIGHT @ pose))
        ]
        if all(inside):
            poses.append(pose)
    return poses


def _corners(poses, rng=None):
    left, right = [], []
    for pose in poses:
        for image, camera_pose in ((left, pose), (right, LEFT_TO_RIGHT @ pose)):
            corners = _project(camera_pose)
            if rng is not None:
                corners = corners + rng.normal(0.0, CORNER_NOISE, corners.shape)
            image.append(corners)
    return left, right


def _pnp(corners) -> np.ndarray:
    ok, rvec, tvec = cv2.solvePnP(BOARD, corners, K, DIST)
    assert ok
    return from_rvec_tvec(rvec, tvec)


def _errors(estimate: np.ndarray) -> tuple[float, float]:
    return rotation_angle_deg(estimate, LEFT_TO_RIGHT), translation_error_mm(
        estimate, LEFT_TO_RIGHT
    )


# ---- eq. 4.7 ---------------------------------------------------------------------------------


def test_eq_4_7_is_exact_without_noise():
    left = _board_poses(seed=1)
    right = [LEFT_TO_RIGHT @ pose for pose in left]
    result = stereo_from_target_poses(left, right)
    assert np.abs(result.left_to_right - LEFT_TO_RIGHT).max() < 1e-9
    assert result.n_views == N_VIEWS
    assert result.rotation_deviation_deg.max() < 1e-9
    assert result.translation_deviation_mm.max() < 1e-9
    assert result.baseline_m == pytest.approx(np.linalg.norm(RIGHT_CENTRE), abs=1e-9)


def test_eq_4_7_averages_rotations_as_rotations():
    # two views that err by ±10° about one axis: their mean rotation is the truth, while an
    # element-wise mean of the two matrices would not even be a rotation
    left = _board_poses(seed=2, n=2)
    error = Rotation.from_rotvec(np.radians(10.0) * np.array([0.6, 0.0, 0.8])).as_matrix()
    wrong = [LEFT_TO_RIGHT.copy(), LEFT_TO_RIGHT.copy()]
    wrong[0][:3, :3] = error @ LEFT_TO_RIGHT[:3, :3]
    wrong[1][:3, :3] = error.T @ LEFT_TO_RIGHT[:3, :3]
    right = [w @ pose for w, pose in zip(wrong, left, strict=True)]
    result = stereo_from_target_poses(left, right)
    assert rotation_angle_deg(result.left_to_right, LEFT_TO_RIGHT) < 1e-9
    assert np.allclose(result.rotation_deviation_deg, 10.0, atol=1e-9)
    naive = (wrong[0][:3, :3] + wrong[1][:3, :3]) / 2
    assert abs(np.linalg.det(naive) - 1.0) > 1e-3


# ---- bundle adjustment -----------------------------------------------------------------------


def test_bundle_adjustment_is_exact_without_noise():
    poses = _board_poses(seed=3)
    left, right = _corners(poses)
    start = from_rvec_tvec([0.01, -0.02, 0.015], [0.01, 0.005, -0.01]) @ LEFT_TO_RIGHT
    result = refine_stereo(BOARD, left, right, K, DIST, K, DIST, start)
    assert result.converged
    assert result.initial_rms_px > 1.0
    assert result.rms_px < 1e-6
    assert np.abs(result.left_to_right - LEFT_TO_RIGHT).max() < 1e-8
    assert np.abs(result.target_to_left - np.stack(poses)).max() < 1e-8


def test_bundle_adjustment_beats_eq_4_7_and_agrees_with_opencv():
    rng = np.random.default_rng(4)
    left, right = _corners(_board_poses(seed=4), rng)
    eq_4_7 = stereo_from_target_poses([_pnp(c) for c in left], [_pnp(c) for c in right])
    refined = refine_stereo(BOARD, left, right, K, DIST, K, DIST, eq_4_7.left_to_right)

    rotation_47, translation_47 = _errors(eq_4_7.left_to_right)
    rotation_ba, translation_ba = _errors(refined.left_to_right)
    assert rotation_ba < rotation_47
    assert translation_ba < translation_47
    # a per-corner RMS near the noise's sqrt(2) * 0.2 px, not a per-coordinate one
    assert refined.rms_px == pytest.approx(np.sqrt(2) * CORNER_NOISE, abs=0.03)
    assert refined.rms_px < refined.initial_rms_px

    criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-10)
    rms, *_, R, T, _, _ = cv2.stereoCalibrate(
        [BOARD.astype(np.float32)] * len(left),
        [c.astype(np.float32) for c in left],
        [c.astype(np.float32) for c in right],
        K,
        DIST,
        K,
        DIST,
        SIZE,
        flags=cv2.CALIB_FIX_INTRINSIC,
        criteria=criteria,
    )
    opencv = np.eye(4)
    opencv[:3, :3], opencv[:3, 3] = R, T.ravel()
    assert rotation_angle_deg(refined.left_to_right, opencv) < 1e-4  # deg
    assert translation_error_mm(refined.left_to_right, opencv) < 1e-3  # mm
    assert refined.rms_px == pytest.approx(rms, abs=1e-6)


def test_bundle_adjustment_accepts_per_view_points_and_initial_poses():
    poses = _board_poses(seed=5, n=3)
    left, right = _corners(poses)
    result = refine_stereo(
        [BOARD] * 3,
        [c.reshape(-1, 1, 2) for c in left],
        right,
        K,
        DIST,
        K,
        DIST,
        LEFT_TO_RIGHT,
        target_to_left=poses,
    )
    assert result.rms_px < 1e-6
    assert result.target_to_left.shape == (3, 4, 4)


# ---- bad input -------------------------------------------------------------------------------


def test_bad_input_is_refused():
    poses = _board_poses(seed=6, n=2)
    left, right = _corners(poses)
    with pytest.raises(CalibrationError, match="2 left and 1 right views"):
        refine_stereo(BOARD, left, right[:1], K, DIST, K, DIST, LEFT_TO_RIGHT)
    with pytest.raises(CalibrationError, match="view 1 has 54 object points, 54 left and 3"):
        refine_stereo(BOARD, left, [right[0], right[1][:3]], K, DIST, K, DIST, LEFT_TO_RIGHT)
    with pytest.raises(CalibrationError, match="K_right is not a camera matrix"):
        refine_stereo(BOARD, left, right, K, DIST, np.eye(2), DIST, LEFT_TO_RIGHT)
    with pytest.raises(CalibrationError, match="d_left has 3 coefficients"):
        refine_stereo(BOARD, left, right, K, DIST[:3], K, DIST, LEFT_TO_RIGHT)
    with pytest.raises(CalibrationError, match="1 target_to_left poses for 2 views"):
        refine_stereo(BOARD, left, right, K, DIST, K, DIST, LEFT_TO_RIGHT, poses[:1])
    with pytest.raises(CalibrationError, match="2 left and 1 right target poses"):
        stereo_from_target_poses(poses, poses[:1])
