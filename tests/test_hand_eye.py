"""Hand-eye calibration (thesis ch. 4, Fig. 4.4) on synthetic poses, and the pose helpers.

The data are exact: a random true X (and target pose), random gripper poses with diverse rotations,
and target-to-camera poses derived from them, so every OpenCV method must recover X to 1e-8 as in
OpenCV's own regression test (``test_calibration_hand_eye.cpp``). The noise levels of that test
(gripper 0.001 rad / 1 mm, target 0.002 rad / 5 mm) are used where noise is needed.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ipbench.perception.calibration.errors import CalibrationError
from ipbench.perception.calibration.hand_eye import (
    HAND_EYE_METHODS,
    MIN_ROTATION_DEG,
    ROBOT_WORLD_METHODS,
    TSAI_ROTATION_RANGE_DEG,
    calibrate_hand_eye,
    calibrate_robot_world_hand_eye,
    check_motions,
)
from ipbench.perception.calibration.poses import (
    as_transform,
    compose,
    from_rvec_tvec,
    invert,
    rotation_angle_deg,
    to_rvec_tvec,
    translation_error_mm,
)

N_POSES = 10  # as OpenCV's regression test and the thesis (ch. 4)
GRIPPER_NOISE = (0.001, 0.001)  # rad, m (OpenCV test_calibration_hand_eye.cpp)
TARGET_NOISE = (0.002, 0.005)  # rad, m


def _transform(rotation: Rotation, translation) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = rotation.as_matrix()
    T[:3, 3] = translation
    return T


def _random_transform(rng: np.random.Generator, scale: float) -> np.ndarray:
    return _transform(Rotation.random(random_state=rng), rng.normal(0.0, scale, 3))


def _gripper_poses(rng: np.random.Generator, n: int = N_POSES) -> list[np.ndarray]:
    # uniformly random orientations around a point in the arm's workspace, m
    return [
        _transform(Rotation.random(random_state=rng), [0.8, 0.0, 1.0] + rng.normal(0, 0.2, 3))
        for _ in range(n)
    ]


def _eye_in_hand(seed: int, gripper=None):
    """True camera-to-gripper X, target-to-base Z and exact (gripper_to_base,
    target_to_camera): gripper_to_base X target_to_camera = Z."""
    rng = np.random.default_rng(seed)
    X, Z = _random_transform(rng, 0.1), _random_transform(rng, 1.0)
    gripper = _gripper_poses(rng) if gripper is None else gripper
    camera = [invert(X) @ invert(g) @ Z for g in gripper]
    return X, Z, gripper, camera


def _eye_to_hand(seed: int):
    """True camera-to-base X, target-to-gripper Z: base_to_gripper X target_to_camera = Z."""
    rng = np.random.default_rng(seed)
    X, Z = _random_transform(rng, 1.0), _random_transform(rng, 0.1)
    gripper = _gripper_poses(rng)
    camera = [invert(X) @ g @ Z for g in gripper]
    return X, Z, gripper, camera


def _noisy(poses, rng, noise):
    rotation, translation = noise
    return [
        _transform(
            Rotation.from_rotvec(rng.normal(0, rotation, 3)) * Rotation.from_matrix(T[:3, :3]),
            T[:3, 3] + rng.normal(0, translation, 3),
        )
        for T in poses
    ]


def _split(poses):
    return [T[:3, :3] for T in poses], [T[:3, 3] for T in poses]


# ---- exact recovery --------------------------------------------------------------------------


@pytest.mark.parametrize("method", HAND_EYE_METHODS)
def test_every_method_recovers_camera_to_gripper_without_noise(method):
    X, _, gripper, camera = _eye_in_hand(seed=1)
    result = calibrate_hand_eye(gripper, camera, method=method)
    assert np.abs(result.X - X).max() < 1e-8
    assert (result.method, result.setup, result.n_poses) == (method, "eye_in_hand", N_POSES)
    assert result.rotation_residuals_deg.shape == (N_POSES * (N_POSES - 1) // 2,)
    assert result.rotation_residuals_deg.max() < 1e-8
    assert result.translation_residuals_mm.max() < 1e-8


@pytest.mark.parametrize("method", HAND_EYE_METHODS)
def test_every_method_recovers_camera_to_base_eye_to_hand(method):
    X, _, gripper, camera = _eye_to_hand(seed=2)
    result = calibrate_hand_eye(gripper, camera, method=method, setup="eye_to_hand")
    assert np.abs(result.X - X).max() < 1e-8
    assert result.setup == "eye_to_hand"
    # the same data taken for eye-in-hand do not fit: the setup is not a label only
    assert calibrate_hand_eye(gripper, camera, method="park").translation_rms_mm > 1.0


@pytest.mark.parametrize("setup", ["eye_in_hand", "eye_to_hand"])
@pytest.mark.parametrize("method", ROBOT_WORLD_METHODS)
def test_robot_world_recovers_X_and_Z(method, setup):
    data = _eye_in_hand(seed=3) if setup == "eye_in_hand" else _eye_to_hand(seed=3)
    X, Z, gripper, camera = data
    result = calibrate_robot_world_hand_eye(gripper, camera, method=method, setup=setup)
    assert np.abs(result.X - X).max() < 1e-8
    assert np.abs(result.Z - Z).max() < 1e-8
    assert result.rotation_residuals_deg.shape == (N_POSES,)
    assert result.translation_residuals_mm.max() < 1e-8


# ---- the method really reaches OpenCV ----------------------------------------------------------


def test_method_is_passed_by_keyword_and_changes_the_result_under_noise():
    rng = np.random.default_rng(4)
    X, _, gripper, camera = _eye_in_hand(seed=4)
    gripper, camera = _noisy(gripper, rng, GRIPPER_NOISE), _noisy(camera, rng, TARGET_NOISE)
    results = {m: calibrate_hand_eye(gripper, camera, method=m).X for m in HAND_EYE_METHODS}
    for a in HAND_EYE_METHODS:
        for b in HAND_EYE_METHODS:
            if a < b:
                assert np.abs(results[a] - results[b]).max() > 1e-6, (a, b)
    flags = {
        "tsai": cv2.CALIB_HAND_EYE_TSAI,
        "park": cv2.CALIB_HAND_EYE_PARK,
        "horaud": cv2.CALIB_HAND_EYE_HORAUD,
        "andreff": cv2.CALIB_HAND_EYE_ANDREFF,
        "daniilidis": cv2.CALIB_HAND_EYE_DANIILIDIS,
    }
    args = (*_split(gripper), *_split(camera))
    for method, flag in flags.items():
        R, t = cv2.calibrateHandEye(*args, method=flag)
        assert np.allclose(results[method][:3, :3], R, atol=1e-12)
        assert np.allclose(results[method][:3, 3], t.ravel(), atol=1e-12)
    # the pitfall guarded against: positionally, OpenCV silently runs Tsai
    R_positional, _ = cv2.calibrateHandEye(*args, cv2.CALIB_HAND_EYE_PARK)
    assert np.allclose(R_positional, results["tsai"][:3, :3], atol=1e-12)
    assert not np.allclose(R_positional, results["park"][:3, :3], atol=1e-6)
    # and every method stays within OpenCV's own pass thresholds at this noise
    for method, estimate in results.items():
        limit = 0.01 if method in ("andreff", "daniilidis") else 0.02
        assert np.radians(rotation_angle_deg(estimate, X)) < limit, method
        assert translation_error_mm(estimate, X) < 50.0, method


def test_residuals_reflect_the_noise():
    rng = np.random.default_rng(5)
    _, _, gripper, camera = _eye_in_hand(seed=5)
    result = calibrate_hand_eye(
        _noisy(gripper, rng, GRIPPER_NOISE), _noisy(camera, rng, TARGET_NOISE), method="park"
    )
    # 5 mm of target noise per pose: mm-level, not zero and not metres
    assert 1.0 < result.translation_rms_mm < 50.0
    assert 0.01 < result.rotation_rms_deg < 1.0


# ---- degenerate motions and bad input ----------------------------------------------------------


def _camera_for(gripper, seed=6):
    return _eye_in_hand(seed, gripper=gripper)[3]


def test_two_poses_are_refused():
    _, _, gripper, camera = _eye_in_hand(seed=6)
    with pytest.raises(CalibrationError, match=r"got 2 pose\(s\).*at least 3"):
        calibrate_hand_eye(gripper[:2], camera[:2], method="park")


def test_pure_translations_are_refused():
    rng = np.random.default_rng(7)
    gripper = [_transform(Rotation.identity(), rng.normal(0, 0.3, 3)) for _ in range(6)]
    with pytest.raises(CalibrationError, match=r"smaller than 2° \(largest 0\.00°\).*Rotate"):
        calibrate_hand_eye(gripper, _camera_for(gripper), method="horaud")


def test_rotations_of_one_degree_about_one_axis_are_refused():
    rng = np.random.default_rng(8)
    gripper = [
        _transform(Rotation.from_euler("z", i % 2, degrees=True), rng.normal(0, 0.3, 3))
        for i in range(6)
    ]
    with pytest.raises(CalibrationError) as error:
        calibrate_hand_eye(gripper, _camera_for(gripper), method="daniilidis")
    message = str(error.value)
    assert f"smaller than {MIN_ROTATION_DEG:g}°" in message
    assert "(0, 1) 1.00°" in message  # names the pairs that rotate too little
    assert "15 relative rotations between the 6 robot poses" in message


def test_large_rotations_about_parallel_axes_are_refused():
    rng = np.random.default_rng(9)
    gripper = [
        _transform(Rotation.from_euler("z", 40 * i, degrees=True), rng.normal(0, 0.3, 3))
        for i in range(5)
    ]
    with pytest.raises(CalibrationError, match=r"within 0\.00° of one direction.*non-parallel"):
        calibrate_hand_eye(gripper, _camera_for(gripper), method="andreff")


def test_tsai_refuses_what_opencv_would_silently_answer_with_the_identity():
    # 5° steps about two axes: informative for the others, outside Tsai's 17.3°-116.4° window
    rng = np.random.default_rng(10)
    gripper = [
        _transform(
            Rotation.from_rotvec(np.radians(5) * np.array([i % 2, 0, i])), rng.normal(0, 0.3, 3)
        )
        for i in range(4)
    ]
    X, _, _, camera = _eye_in_hand(seed=6, gripper=gripper)
    summary = check_motions(gripper, camera, method="park")
    assert summary.robot_rotation_deg.max() < TSAI_ROTATION_RANGE_DEG[0]
    assert np.abs(calibrate_hand_eye(gripper, camera, method="park").X - X).max() < 1e-8
    # what OpenCV itself does with these poses: the identity, with only a log line
    R, t = cv2.calibrateHandEye(*_split(gripper), *_split(camera), method=cv2.CALIB_HAND_EYE_TSAI)
    assert np.allclose(R, np.eye(3)) and np.allclose(t, 0.0)
    with pytest.raises(CalibrationError, match=r"'tsai'.*17\.3°-116\.4°.*park, horaud"):
        calibrate_hand_eye(gripper, camera, method="tsai")


def test_check_motions_summarises_the_pairs():
    _, _, gripper, camera = _eye_in_hand(seed=11)
    summary = check_motions(gripper, camera, method="park")
    assert summary.pairs.shape == (45, 2)
    assert np.all(summary.pairs[:, 0] < summary.pairs[:, 1])
    # A = X B X^-1: robot and camera motions rotate by the same angle
    assert np.allclose(summary.robot_rotation_deg, summary.camera_rotation_deg, atol=1e-9)
    assert summary.informative.all()
    assert summary.axis_spread_deg > 45.0  # random rotations: axes all over the sphere


def test_unknown_methods_and_setups_list_the_valid_ones():
    _, _, gripper, camera = _eye_in_hand(seed=12)
    with pytest.raises(CalibrationError, match="'surf'; valid: tsai, park, horaud, andreff"):
        calibrate_hand_eye(gripper, camera, method="surf")
    with pytest.raises(CalibrationError, match="'tsai'; valid: shah, li"):
        calibrate_robot_world_hand_eye(gripper, camera, method="tsai")
    with pytest.raises(CalibrationError, match="'eye_on_base'; valid: eye_in_hand, eye_to_hand"):
        calibrate_hand_eye(gripper, camera, setup="eye_on_base")


def test_bad_pose_lists_are_refused():
    _, _, gripper, camera = _eye_in_hand(seed=13)
    with pytest.raises(CalibrationError, match="10 gripper_to_base and 9 target_to_camera"):
        calibrate_hand_eye(gripper, camera[:9])
    scaled = [g.copy() for g in gripper]
    scaled[3][:3, :3] *= 2.0
    with pytest.raises(CalibrationError, match=r"gripper_to_base\[3\].*not a proper rotation"):
        calibrate_hand_eye(scaled, camera)
    with pytest.raises(CalibrationError, match=r"target_to_camera\[0\] has shape \(3, 4\)"):
        calibrate_hand_eye(gripper, [c[:3] for c in camera])


# ---- pose helpers ----------------------------------------------------------------------------


def test_pose_helpers():
    rng = np.random.default_rng(14)
    a, b = _random_transform(rng, 1.0), _random_transform(rng, 1.0)
    assert np.allclose(compose(a, invert(a)), np.eye(4), atol=1e-12)
    assert np.allclose(compose(a, b) @ [1, 2, 3, 1], a @ (b @ [1, 2, 3, 1]))
    rvec, tvec = to_rvec_tvec(a)
    assert np.allclose(from_rvec_tvec(rvec, tvec), a, atol=1e-12)
    turn = _transform(Rotation.from_euler("x", 30, degrees=True), [0.003, 0.004, 0.0])
    assert rotation_angle_deg(np.eye(4), turn) == pytest.approx(30.0, abs=1e-12)
    assert rotation_angle_deg(turn, np.eye(4)) == pytest.approx(30.0, abs=1e-12)
    assert translation_error_mm(np.eye(4), turn) == pytest.approx(5.0, abs=1e-12)
    # accurate for tiny angles, where arccos((trace - 1) / 2) returns 0
    tiny = Rotation.from_euler("y", 1e-7, degrees=True).as_matrix()
    assert rotation_angle_deg(np.eye(3), tiny) == pytest.approx(1e-7, rel=1e-6)
    near_half_turn = Rotation.from_euler("z", 179.9999, degrees=True).as_matrix()
    assert rotation_angle_deg(np.eye(3), near_half_turn) == pytest.approx(179.9999, abs=1e-9)
    batch = rotation_angle_deg(np.eye(3), np.stack([np.eye(3), tiny]))
    assert batch.shape == (2,)


def test_pose_helpers_reject_non_rigid_input():
    with pytest.raises(CalibrationError, match=r"last row .*valid: \[0, 0, 0, 1\]"):
        as_transform(np.ones((4, 4)))
    mirror = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(CalibrationError, match="det R = -1"):
        invert(mirror)
    with pytest.raises(CalibrationError, match="NaN"):
        as_transform(np.full((4, 4), np.nan))
    with pytest.raises(CalibrationError, match="3 each"):
        from_rvec_tvec([0.0, 0.0], [0.0, 0.0, 1.0])
