"""Small helpers on 4x4 homogeneous rigid transforms, m.

Naming as OpenCV's calib3d: ``a_to_b`` (written ``T_b_a`` in the thesis, eq. 4.7) maps a
point's coordinates in frame ``a`` to its coordinates in frame ``b``, ``p_b = T p_a``; so
``gripper_to_base`` is the robot's forward kinematics and ``target_to_camera`` is what
``cv2.solvePnP`` returns for a calibration target. Transforms compose right to left:
``compose(b_to_c, a_to_b) == a_to_c``.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from ipbench.perception.calibration.errors import CalibrationError

__all__ = [
    "as_transform",
    "as_transforms",
    "compose",
    "from_rvec_tvec",
    "invert",
    "rotation_angle_deg",
    "to_rvec_tvec",
    "translation_error_mm",
]

# |R^T R - I| and |det R - 1| allowed in an input rotation: float32 round-off is ~1e-7, so
# 1e-5 accepts single-precision poses and rejects scaled, sheared or mirrored matrices.
ORTHONORMAL_TOLERANCE = 1e-5


def as_transform(value, name: str = "transform") -> np.ndarray:
    """``value`` as a (4, 4) float64 rigid transform; :class:`CalibrationError` names ``name``
    and says what is wrong when it is not one (shape, non-finite entries, last row, a rotation
    part that is not a proper rotation)."""
    array = np.asarray(value, dtype=np.float64)
    if array.shape != (4, 4):
        raise CalibrationError(
            f"{name} has shape {array.shape}; valid: a (4, 4) homogeneous transform "
            "[[R, t], [0, 0, 0, 1]] with t in metres (build one with from_rvec_tvec)"
        )
    if not np.all(np.isfinite(array)):
        raise CalibrationError(f"{name} has NaN or infinite entries; valid: finite numbers")
    if not np.allclose(array[3], (0.0, 0.0, 0.0, 1.0), atol=ORTHONORMAL_TOLERANCE):
        raise CalibrationError(
            f"{name} has last row {array[3].tolist()}; valid: [0, 0, 0, 1] (a rigid transform)"
        )
    R = array[:3, :3]
    error = float(np.abs(R.T @ R - np.eye(3)).max())
    if error > ORTHONORMAL_TOLERANCE or abs(np.linalg.det(R) - 1.0) > ORTHONORMAL_TOLERANCE:
        raise CalibrationError(
            f"{name} has a rotation part that is not a proper rotation (|R^T R - I| = "
            f"{error:.2g}, det R = {np.linalg.det(R):.6g}); valid: an orthonormal R with "
            "det +1 (not scaled, sheared or mirrored)"
        )
    return array


def as_transforms(values: Sequence, name: str = "transforms") -> np.ndarray:
    """A sequence of rigid transforms as an (N, 4, 4) float64 array, each checked as
    :func:`as_transform` (the message names the bad element, ``name[i]``)."""
    if isinstance(values, np.ndarray) and values.ndim == 2:
        raise CalibrationError(
            f"{name} is a single {values.shape} array; valid: a list of (4, 4) transforms"
        )
    try:
        items = list(values)
    except TypeError as error:
        raise CalibrationError(
            f"{name} is a {type(values).__name__}; valid: a list of (4, 4) transforms"
        ) from error
    if not items:
        return np.zeros((0, 4, 4))
    return np.stack([as_transform(item, f"{name}[{i}]") for i, item in enumerate(items)])


def compose(*transforms) -> np.ndarray:
    """The product ``T_1 @ T_2 @ ... @ T_n`` (apply ``T_n`` first), (4, 4)."""
    if not transforms:
        raise CalibrationError("compose needs at least one (4, 4) transform; got none")
    result = np.eye(4)
    for i, transform in enumerate(transforms):
        result = result @ as_transform(transform, f"compose argument {i}")
    return result


def invert(transform) -> np.ndarray:
    """The inverse ``[[R^T, -R^T t], [0, 1]]`` of a rigid transform, (4, 4)."""
    T = as_transform(transform)
    result = np.eye(4)
    result[:3, :3] = T[:3, :3].T
    result[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return result


def from_rvec_tvec(rvec, tvec) -> np.ndarray:
    """(4, 4) transform from an OpenCV Rodrigues vector (3,) rad and a translation (3,) m."""
    rvec = np.asarray(rvec, dtype=np.float64).reshape(-1)
    tvec = np.asarray(tvec, dtype=np.float64).reshape(-1)
    if rvec.shape != (3,) or tvec.shape != (3,):
        raise CalibrationError(
            f"rvec has {rvec.size} and tvec {tvec.size} entries; valid: 3 each (a Rodrigues "
            "rotation vector in rad, a translation in m)"
        )
    if not (np.all(np.isfinite(rvec)) and np.all(np.isfinite(tvec))):
        raise CalibrationError("rvec or tvec has NaN or infinite entries; valid: finite numbers")
    result = np.eye(4)
    result[:3, :3] = cv2.Rodrigues(rvec)[0]
    result[:3, 3] = tvec
    return result


def to_rvec_tvec(transform) -> tuple[np.ndarray, np.ndarray]:
    """The OpenCV Rodrigues vector (3,) rad and translation (3,) m of a rigid transform."""
    T = as_transform(transform)
    return cv2.Rodrigues(T[:3, :3])[0].reshape(3), T[:3, 3].copy()


def rotation_angle_deg(a, b) -> float | np.ndarray:
    """Angle of the rotation ``R_a^T R_b`` between two rotations, deg in [0, 180].

    ``a`` and ``b`` are (..., 3, 3) rotations or (..., 4, 4) transforms (their rotation parts),
    broadcast against each other. The angle is ``atan2(sin, cos)`` of the relative rotation,
    accurate near 0° (where ``arccos`` of the trace loses half the digits) and near 180°.
    """
    Ra = np.asarray(a, dtype=np.float64)[..., :3, :3]
    Rb = np.asarray(b, dtype=np.float64)[..., :3, :3]
    R = np.swapaxes(Ra, -1, -2) @ Rb
    cos = (np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0
    vee = np.stack(
        [R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]],
        axis=-1,
    )
    angle = np.degrees(np.arctan2(np.linalg.norm(vee, axis=-1) / 2.0, cos))
    return float(angle) if np.ndim(angle) == 0 else angle


def translation_error_mm(a, b) -> float | np.ndarray:
    """Distance between the translations of two (..., 4, 4) transforms given in metres, mm."""
    ta = np.asarray(a, dtype=np.float64)[..., :3, 3]
    tb = np.asarray(b, dtype=np.float64)[..., :3, 3]
    distance = 1000.0 * np.linalg.norm(ta - tb, axis=-1)
    return float(distance) if np.ndim(distance) == 0 else distance
