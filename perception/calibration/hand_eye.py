"""Hand-eye calibration, AX = XB and AX = ZB, with OpenCV (thesis ch. 4, Fig. 4.4).

Two set-ups of the CloPeMa cell:

- ``"eye_in_hand"``: a camera on the robot (the wrist Xtion) looks at a target fixed in the
  cell. ``X`` is the camera-to-gripper transform.
- ``"eye_to_hand"``: a camera fixed to the robot's base (the stereo head) looks at a target
  held in the gripper. As OpenCV's documentation of ``calibrateHandEye`` explains, the robot
  poses are then passed inverted (base-to-gripper), and ``X`` is the camera-to-base transform.

Inputs are lists of 4x4 transforms in metres (:mod:`~ipbench.perception.calibration.poses`):
``gripper_to_base[i]`` from the robot's kinematics and ``target_to_camera[i]`` from
``cv2.solvePnP`` at the same moment. With ``robot[i]`` = ``gripper_to_base[i]`` (eye in hand)
or its inverse (eye to hand), every pose satisfies ``robot[i] X target_to_camera[i] = Z`` for
a constant ``Z`` (the target in the base frame, or in the gripper frame), and every pair of
poses ``i < j`` gives one motion ``A X = X B`` with ``A = robot[j]^-1 robot[i]`` and
``B = target_to_camera[j] target_to_camera[i]^-1`` (Tsai & Lenz 1989, eqs. 6-7).

OpenCV pitfalls handled here:

- the method must be passed as ``method=``: as the 5th positional argument it lands on an
  output array and Tsai runs silently (opencv PR #28074);
- OpenCV's Tsai (since opencv PR #24897, in the 4.14 wheel) keeps only pose pairs whose
  relative rotation has ``2 sin(θ/2)`` in [0.3, 1.7], i.e. θ in 17.3°-116.4°, on both the
  robot and the camera side, and with fewer than two such pairs it only logs an error and
  returns the identity; :func:`check_motions` refuses such inputs before OpenCV sees them.

Degenerate motions are refused by :func:`~.motions.check_motions` (:mod:`.motions`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from ipbench.perception.calibration.errors import CalibrationError
from ipbench.perception.calibration.motions import (
    HAND_EYE_METHODS,
    MIN_AXIS_SPREAD_DEG,
    MIN_POSES,
    MIN_ROTATION_DEG,
    ROBOT_WORLD_METHODS,
    SETUPS,
    TSAI_ROTATION_RANGE_DEG,
    MotionSummary,
    _choice,
    _inverse_all,
    _motions,
    _poses,
    check_motions,
)
from ipbench.perception.calibration.poses import (
    rotation_angle_deg,
    translation_error_mm,
)

__all__ = [  # with the vocabulary and the motion check of :mod:`.motions`, re-exported
    "HAND_EYE_METHODS",
    "MIN_AXIS_SPREAD_DEG",
    "MIN_POSES",
    "MIN_ROTATION_DEG",
    "ROBOT_WORLD_METHODS",
    "SETUPS",
    "TSAI_ROTATION_RANGE_DEG",
    "HandEyeResult",
    "MotionSummary",
    "RobotWorldHandEyeResult",
    "calibrate_hand_eye",
    "calibrate_robot_world_hand_eye",
    "check_motions",
]

_HAND_EYE_FLAGS = {
    "tsai": cv2.CALIB_HAND_EYE_TSAI,
    "park": cv2.CALIB_HAND_EYE_PARK,
    "horaud": cv2.CALIB_HAND_EYE_HORAUD,
    "andreff": cv2.CALIB_HAND_EYE_ANDREFF,
    "daniilidis": cv2.CALIB_HAND_EYE_DANIILIDIS,
}
_ROBOT_WORLD_FLAGS = {
    "shah": cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH,
    "li": cv2.CALIB_ROBOT_WORLD_HAND_EYE_LI,
}


@dataclass(frozen=True, eq=False)
class HandEyeResult:
    """A hand-eye calibration ``AX = XB``.

    Attributes
    ----------
    X : (4, 4) float64 array
        Camera-to-gripper (``"eye_in_hand"``) or camera-to-base (``"eye_to_hand"``), m.
    method : str
        One of :data:`HAND_EYE_METHODS`.
    setup : str
        One of :data:`SETUPS`.
    n_poses : int
        Poses used.
    rotation_residuals_deg : (P,) float64 array
        Angle between ``A X`` and ``X B`` for every pose pair ``i < j``, deg.
    translation_residuals_mm : (P,) float64 array
        Distance between the translations of ``A X`` and ``X B`` for every pair, mm.
    """

    X: np.ndarray
    method: str
    setup: str
    n_poses: int
    rotation_residuals_deg: np.ndarray
    translation_residuals_mm: np.ndarray

    @property
    def rotation_rms_deg(self) -> float:
        """RMS of :attr:`rotation_residuals_deg`, deg."""
        return float(np.sqrt(np.mean(self.rotation_residuals_deg**2)))

    @property
    def translation_rms_mm(self) -> float:
        """RMS of :attr:`translation_residuals_mm`, mm."""
        return float(np.sqrt(np.mean(self.translation_residuals_mm**2)))


@dataclass(frozen=True, eq=False)
class RobotWorldHandEyeResult:
    """A robot-world/hand-eye calibration ``robot[i] X target_to_camera[i] = Z``.

    Attributes
    ----------
    X : (4, 4) float64 array
        Camera-to-gripper (``"eye_in_hand"``) or camera-to-base (``"eye_to_hand"``), m.
    Z : (4, 4) float64 array
        Target-to-base (``"eye_in_hand"``: the fixed target in the robot's base frame) or
        target-to-gripper (``"eye_to_hand"``: the held target in the gripper frame), m.
    method : str
        One of :data:`ROBOT_WORLD_METHODS`.
    setup : str
        One of :data:`SETUPS`.
    n_poses : int
        Poses used.
    rotation_residuals_deg : (n_poses,) float64 array
        Angle between ``robot[i] X target_to_camera[i]`` and ``Z`` for every pose, deg.
    translation_residuals_mm : (n_poses,) float64 array
        Distance between their translations for every pose, mm.
    """

    X: np.ndarray
    Z: np.ndarray
    method: str
    setup: str
    n_poses: int
    rotation_residuals_deg: np.ndarray
    translation_residuals_mm: np.ndarray


def _transform(R, t) -> np.ndarray:
    result = np.eye(4)
    result[:3, :3] = np.asarray(R, dtype=np.float64)
    result[:3, 3] = np.asarray(t, dtype=np.float64).reshape(3)
    return result


def _split(transforms: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
    return [T[:3, :3].copy() for T in transforms], [T[:3, 3:].copy() for T in transforms]


def _finite(X: np.ndarray, method: str) -> np.ndarray:
    if not np.all(np.isfinite(X)):
        raise CalibrationError(
            f"OpenCV's {method!r} returned a non-finite transform: the poses are degenerate "
            "or inconsistent (check that both lists are in the same order and in metres)"
        )
    return X


def calibrate_hand_eye(
    gripper_to_base: Sequence,
    target_to_camera: Sequence,
    method: str = "tsai",
    setup: str = "eye_in_hand",
) -> HandEyeResult:
    """Solve ``AX = XB`` with ``cv2.calibrateHandEye``.

    Parameters
    ----------
    gripper_to_base : list of (4, 4) arrays
        The robot's gripper poses in its base frame, m (also for ``"eye_to_hand"``: they are
        inverted here).
    target_to_camera : list of (4, 4) arrays
        The target's pose in the camera frame at each robot pose (``cv2.solvePnP``), m.
    method : str
        One of :data:`HAND_EYE_METHODS`.
    setup : str
        ``"eye_in_hand"`` (X = camera-to-gripper) or ``"eye_to_hand"`` (X = camera-to-base).
    """
    method = _choice(method, "hand-eye method", HAND_EYE_METHODS)
    check_motions(gripper_to_base, target_to_camera, method=method, setup=setup)
    robot, camera = _poses(gripper_to_base, target_to_camera, setup)
    R_robot, t_robot = _split(robot)
    R_camera, t_camera = _split(camera)
    R, t = cv2.calibrateHandEye(
        R_robot, t_robot, R_camera, t_camera, method=_HAND_EYE_FLAGS[method]
    )
    X = _finite(_transform(R, t), method)
    _, A, B = _motions(robot, camera)
    AX, XB = A @ X, X @ B
    return HandEyeResult(
        X=X,
        method=method,
        setup=setup,
        n_poses=len(robot),
        rotation_residuals_deg=np.atleast_1d(rotation_angle_deg(AX, XB)),
        translation_residuals_mm=np.atleast_1d(translation_error_mm(AX, XB)),
    )


def calibrate_robot_world_hand_eye(
    gripper_to_base: Sequence,
    target_to_camera: Sequence,
    method: str = "shah",
    setup: str = "eye_in_hand",
) -> RobotWorldHandEyeResult:
    """Solve ``robot[i] X target_to_camera[i] = Z`` for ``X`` and ``Z`` together with
    ``cv2.calibrateRobotWorldHandEye`` (Shah 2013, Li et al. 2010).

    Arguments as :func:`calibrate_hand_eye`; ``method`` is one of
    :data:`ROBOT_WORLD_METHODS`. OpenCV's ``AX = ZB`` takes world(target)-to-camera and
    base-to-gripper poses and returns base-to-world and gripper-to-camera; here they are
    inverted into this module's ``X`` and ``Z`` (see :class:`RobotWorldHandEyeResult`).
    """
    method = _choice(method, "robot-world method", ROBOT_WORLD_METHODS)
    check_motions(gripper_to_base, target_to_camera, method=method, setup=setup)
    robot, camera = _poses(gripper_to_base, target_to_camera, setup)
    R_camera, t_camera = _split(camera)
    R_robot_inv, t_robot_inv = _split(_inverse_all(robot))
    R_bw, t_bw, R_gc, t_gc = cv2.calibrateRobotWorldHandEye(
        R_camera, t_camera, R_robot_inv, t_robot_inv, method=_ROBOT_WORLD_FLAGS[method]
    )
    X = _finite(_inverse_all(_transform(R_gc, t_gc)[None])[0], method)
    Z = _finite(_inverse_all(_transform(R_bw, t_bw)[None])[0], method)
    predicted = robot @ X @ camera
    return RobotWorldHandEyeResult(
        X=X,
        Z=Z,
        method=method,
        setup=setup,
        n_poses=len(robot),
        rotation_residuals_deg=np.atleast_1d(rotation_angle_deg(predicted, Z)),
        translation_residuals_mm=np.atleast_1d(translation_error_mm(predicted, Z)),
    )
