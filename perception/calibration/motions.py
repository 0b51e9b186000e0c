"""Which hand-eye pose sets can determine ``X``, and the shared vocabulary (methods, set-ups).

Degenerate motions (Tsai & Lenz 1989; OpenCV docs: "a minimum of 2 motions with non parallel
rotation axes"): at least :data:`MIN_POSES` poses; relative rotations of at least
:data:`MIN_ROTATION_DEG`; rotation axes that are not all parallel (spread at least
:data:`MIN_AXIS_SPREAD_DEG`). The 2° thresholds are fixed from the noise levels of OpenCV's
own regression test (gripper 0.001 rad, target 0.002 rad), not from any calibration result:
the axis of a relative rotation of angle θ is uncertain by about ``σ √2 / θ``, which at θ = 2°
and σ = 0.002 rad is already ≈ 4.6°, so smaller motions carry no usable axis; and when all
axes lie within 2° of one line, ``X``'s translation along that line is fixed only through
``sin(2°) ≈ 0.035``, amplifying the translation noise by ≈ 29 times.

OpenCV's Tsai (since opencv PR #24897, in the 4.14 wheel) keeps only pose pairs whose relative
rotation has ``2 sin(θ/2)`` in [0.3, 1.7], i.e. θ in 17.3°-116.4°, on both the robot and the
camera side, and with fewer than two such pairs it only logs an error and returns the identity;
:func:`check_motions` refuses such inputs before OpenCV sees them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ipbench.perception.calibration.errors import CalibrationError
from ipbench.perception.calibration.poses import as_transforms, rotation_angle_deg

__all__ = [
    "HAND_EYE_METHODS",
    "MIN_AXIS_SPREAD_DEG",
    "MIN_POSES",
    "MIN_ROTATION_DEG",
    "ROBOT_WORLD_METHODS",
    "SETUPS",
    "TSAI_ROTATION_RANGE_DEG",
    "MotionSummary",
    "check_motions",
]

HAND_EYE_METHODS = ("tsai", "park", "horaud", "andreff", "daniilidis")
ROBOT_WORLD_METHODS = ("shah", "li")
SETUPS = ("eye_in_hand", "eye_to_hand")

# two relative motions need three poses (OpenCV docs of calibrateHandEye)
MIN_POSES = 3
# see the module docstring for both thresholds
MIN_ROTATION_DEG = 2.0
MIN_AXIS_SPREAD_DEG = 2.0
# OpenCV's Tsai keeps pairs with 0.3 <= 2 sin(θ/2) <= 1.7 (opencv PR #24897)
TSAI_ROTATION_RANGE_DEG = (
    float(np.degrees(2.0 * np.arcsin(0.3 / 2.0))),
    float(np.degrees(2.0 * np.arcsin(1.7 / 2.0))),
)
_MIN_TSAI_PAIRS = 2
_LISTED_PAIRS = 8


@dataclass(frozen=True, eq=False)
class MotionSummary:
    """The relative motions of a set of hand-eye poses, as :func:`check_motions` judged them.

    Attributes
    ----------
    pairs : (P, 2) int64 array
        Pose index pairs ``(i, j)``, ``i < j``, ``P = n (n - 1) / 2``.
    robot_rotation_deg, camera_rotation_deg : (P,) float64 arrays
        Rotation angle of each pair's robot motion ``A`` and camera motion ``B``, deg
        (equal without noise).
    informative : (P,) bool array
        Pairs the method can use: robot rotation at least :data:`MIN_ROTATION_DEG` (and, for
        Tsai, both rotations inside :data:`TSAI_ROTATION_RANGE_DEG`).
    axis_spread_deg : float
        Largest angle between an informative pair's robot rotation axis and the principal
        direction of all of them, deg (0 when they are parallel; NaN when none is
        informative).
    """

    pairs: np.ndarray
    robot_rotation_deg: np.ndarray
    camera_rotation_deg: np.ndarray
    informative: np.ndarray
    axis_spread_deg: float


def _choice(value, name: str, valid: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in valid:
        raise CalibrationError(f"unknown {name} {value!r}; valid: {', '.join(valid)}")
    return value


def _inverse_all(transforms: np.ndarray) -> np.ndarray:
    R_T = np.swapaxes(transforms[:, :3, :3], 1, 2)
    result = np.zeros_like(transforms)
    result[:, :3, :3] = R_T
    result[:, :3, 3] = -np.einsum("nij,nj->ni", R_T, transforms[:, :3, 3])
    result[:, 3, 3] = 1.0
    return result


def _poses(gripper_to_base, target_to_camera, setup: str) -> tuple[np.ndarray, np.ndarray]:
    """``robot[i]`` (gripper-to-base, or base-to-gripper for eye-to-hand) and
    ``target_to_camera[i]`` as (n, 4, 4) arrays of equal length."""
    setup = _choice(setup, "setup", SETUPS)
    robot = as_transforms(gripper_to_base, "gripper_to_base")
    camera = as_transforms(target_to_camera, "target_to_camera")
    if len(robot) != len(camera):
        raise CalibrationError(
            f"got {len(robot)} gripper_to_base and {len(camera)} target_to_camera poses; "
            "valid: one target_to_camera per robot pose, in the same order"
        )
    if setup == "eye_to_hand":
        robot = _inverse_all(robot)
    return robot, camera


def _motions(robot: np.ndarray, camera: np.ndarray):
    """Pairs ``(i, j)``, ``i < j``, with their motions ``A`` (P, 4, 4) and ``B`` (P, 4, 4)."""
    i, j = np.triu_indices(len(robot), k=1)
    A = _inverse_all(robot[j]) @ robot[i]
    B = camera[j] @ _inverse_all(camera[i])
    return np.stack([i, j], axis=1).astype(np.int64), A, B


def _axis_spread_deg(rotations: np.ndarray) -> float:
    if len(rotations) == 0:
        return float("nan")
    axes = Rotation.from_matrix(rotations).as_rotvec()
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    principal = np.linalg.eigh(axes.T @ axes)[1][:, -1]
    return float(np.degrees(np.arccos(np.clip(np.abs(axes @ principal).min(), 0.0, 1.0))))


def _list_pairs(pairs: np.ndarray, angles: np.ndarray) -> str:
    order = np.argsort(angles, kind="stable")
    shown = ", ".join(
        f"({pairs[k, 0]}, {pairs[k, 1]}) {angles[k]:.2f}°" for k in order[:_LISTED_PAIRS]
    )
    more = len(order) - _LISTED_PAIRS
    return shown + (f" and {more} more" if more > 0 else "")


def check_motions(
    gripper_to_base: Sequence,
    target_to_camera: Sequence,
    method: str = "tsai",
    setup: str = "eye_in_hand",
) -> MotionSummary:
    """Refuse pose sets from which ``method`` cannot determine ``X``.

    Raises :class:`CalibrationError` (saying how many poses there are, which relative
    rotations are too small and what to record instead) when there are fewer than
    :data:`MIN_POSES` poses, when no pair of poses differs by at least
    :data:`MIN_ROTATION_DEG`, when the rotation axes of the informative pairs are all within
    :data:`MIN_AXIS_SPREAD_DEG` of one direction, or, for Tsai, when fewer than two pairs lie
    in :data:`TSAI_ROTATION_RANGE_DEG` (OpenCV would return the identity). ``method`` is one
    of :data:`HAND_EYE_METHODS` or :data:`ROBOT_WORLD_METHODS`.
    """
    method = _choice(method, "method", HAND_EYE_METHODS + ROBOT_WORLD_METHODS)
    robot, camera = _poses(gripper_to_base, target_to_camera, setup)
    n = len(robot)
    if n < MIN_POSES:
        raise CalibrationError(
            f"hand-eye calibration got {n} pose(s); it needs at least {MIN_POSES} (two "
            "relative motions with non-parallel rotation axes), and more are better: OpenCV's "
            "regression test and the thesis (ch. 4) use 10. Record more robot poses."
        )
    pairs, A, B = _motions(robot, camera)
    robot_deg = np.asarray(rotation_angle_deg(np.eye(3), A), dtype=np.float64).reshape(-1)
    camera_deg = np.asarray(rotation_angle_deg(np.eye(3), B), dtype=np.float64).reshape(-1)
    informative = robot_deg >= MIN_ROTATION_DEG
    tiny = ~informative
    tiny_text = (
        f" Pairs (i, j) rotating less than {MIN_ROTATION_DEG:g}°: "
        f"{_list_pairs(pairs[tiny], robot_deg[tiny])}."
        if tiny.any()
        else ""
    )
    if not informative.any():
        raise CalibrationError(
            f"all {len(pairs)} relative rotations between the {n} robot poses are smaller "
            f"than {MIN_ROTATION_DEG:g}° (largest {robot_deg.max():.2f}°): such motions do "
            f"not determine X (pure translations never do).{tiny_text} Rotate the gripper by "
            "tens of degrees (20°-90°) about at least two different axes between poses."
        )
    spread = _axis_spread_deg(A[informative, :3, :3])
    if spread < MIN_AXIS_SPREAD_DEG:
        raise CalibrationError(
            f"the rotation axes of all {int(informative.sum())} informative relative motions "
            f"of the {n} robot poses lie within {spread:.2f}° of one direction (at least "
            f"{MIN_AXIS_SPREAD_DEG:g}° needed): X's translation along that axis is not "
            f"determined.{tiny_text} Rotate the gripper about at least two non-parallel axes "
            "(e.g. tilt the wrist as well as turning it)."
        )
    if method == "tsai":
        low, high = TSAI_ROTATION_RANGE_DEG
        in_range = (
            (robot_deg >= low) & (robot_deg <= high) & (camera_deg >= low) & (camera_deg <= high)
        )
        informative = informative & in_range
        spread = _axis_spread_deg(A[informative, :3, :3])
        count = int(informative.sum())
        if count < _MIN_TSAI_PAIRS or spread < MIN_AXIS_SPREAD_DEG:
            axes_text = f", their axes within {spread:.2f}° of one direction" if count else ""
            raise CalibrationError(
                f"method 'tsai': OpenCV's Tsai uses only pose pairs whose relative rotation "
                f"lies in {low:.1f}°-{high:.1f}° and silently returns the identity with fewer "
                f"than {_MIN_TSAI_PAIRS} of them (opencv PR #24897); of the {len(pairs)} "
                f"pairs of the {n} poses, {count} {'qualifies' if count == 1 else 'qualify'}"
                f"{axes_text}. Record poses that differ by 20°-110° about at least two axes, "
                f"or choose another method ({', '.join(HAND_EYE_METHODS[1:])})."
            )
    return MotionSummary(
        pairs=pairs,
        robot_rotation_deg=robot_deg,
        camera_rotation_deg=camera_deg,
        informative=informative,
        axis_spread_deg=spread,
    )
