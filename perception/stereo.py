"""Stereo geometry of the head: triangulation, epipolar checks, left/right hypothesis pairing.

Camera convention (as :func:`ipbench.envs.sensors.camera_pose` and ``intrinsics``, and
:mod:`~ipbench.perception.cloud`): OpenCV, x right, y down, z forward; pixel ``(u, v)`` =
``(column, row)`` with centres at integer coordinates; ``K = [[fx, 0, cx], [0, fy, cy], [0, 0,
1]]``; a pose is the 4x4 world-from-camera transform, m. The projection matrix of a camera is
``P = K [R^T | -R^T t]`` for the pose ``[[R, t], [0, 1]]``.

Left and right hypotheses of one object have the same class and centres that satisfy the
epipolar constraint: the right centre lies within :data:`EPIPOLAR_TOLERANCE_PX` of the left
centre's epipolar line, and the triangulated centre lies in front of both cameras. Instances
of one class side by side lie on nearly the same epipolar line; an ``expected_disparity``
(from vergence) separates them.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment

from ipbench.perception.features2d import ActiveVisionError, Features
from ipbench.perception.matching import match
from ipbench.perception.recognition import Hypothesis

__all__ = [
    "EPIPOLAR_TOLERANCE_PX",
    "StereoRig",
    "hypothesis_position",
    "match_hypotheses",
    "projection_matrix",
]

# the encoder-only pan-tilt stereo update leaves up to ±5 px of epipolar error
# (Mohamed et al. 2018, doi 10.1186/s13640-018-0292-8); twice that
EPIPOLAR_TOLERANCE_PX = 10.0
DISPARITY_TOLERANCE_PX = 20.0  # as vergence.FIXATION_TOLERANCE_PX
MIN_POSITION_MATCHES = 5


def _matrix(name: str, value, shape: tuple[int, int]) -> np.ndarray:
    array = np.asarray(value, np.float64)
    if array.shape != shape or not np.all(np.isfinite(array)):
        raise ActiveVisionError(f"{name} has shape {array.shape}; valid: a finite {shape} matrix")
    return array


def projection_matrix(K: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """(3, 4) ``K [R^T | -R^T t]`` of a camera with intrinsics ``K`` and world-from-camera
    ``pose``."""
    K, pose = _matrix("K", K, (3, 3)), _matrix("pose", pose, (4, 4))
    R, t = pose[:3, :3], pose[:3, 3]
    return K @ np.hstack([R.T, (-R.T @ t)[:, None]])


@dataclass(frozen=True, eq=False)
class StereoRig:
    """The two cameras of the head at one moment: intrinsics (3, 3) px and world-from-camera
    poses (4, 4) m (OpenCV convention, module docstring), and optionally each lens' OpenCV
    distortion ``dist_*`` (5,) ``(k1, k2, p1, p2, k3)`` (the observation's ``head_*_dist``):
    pixels given to the rig are then as the lens sees them, and are undistorted to the ideal
    pinhole's (:meth:`ideal`) before any geometry. None (or zeros): pinhole cameras."""

    K_left: np.ndarray
    pose_left: np.ndarray
    K_right: np.ndarray
    pose_right: np.ndarray
    dist_left: np.ndarray | None = None
    dist_right: np.ndarray | None = None

    def __post_init__(self) -> None:
        for name, shape in (("K_left", (3, 3)), ("pose_left", (4, 4)),
                            ("K_right", (3, 3)), ("pose_right", (4, 4))):  # fmt: skip
            object.__setattr__(self, name, _matrix(name, getattr(self, name), shape))
        for name in ("dist_left", "dist_right"):
            dist = getattr(self, name)
            if dist is not None:
                dist = _matrix(name, np.reshape(dist, (1, -1)), (1, 5))[0]
                object.__setattr__(self, name, dist if np.any(dist) else None)

    def ideal(self, xy: np.ndarray, side: str) -> np.ndarray:
        """(N, 2) pixels of camera ``side`` ("left" or "right") as its ideal pinhole would see
        them (``cv2.undistortPointsIter`` with ``P = K``); unchanged without a lens."""
        if side not in ("left", "right"):
            raise ActiveVisionError(f"side {side!r}; valid: 'left', 'right'")
        xy, dist = _points(xy), getattr(self, f"dist_{side}")
        if dist is None or len(xy) == 0:
            return xy
        K = getattr(self, f"K_{side}")  # noqa: N806
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-10)
        out = cv2.undistortPointsIter(xy.reshape(-1, 1, 2), K, dist, None, K, criteria)
        return out.reshape(-1, 2)

    @property
    def baseline(self) -> float:
        """Distance between the camera centres, m."""
        return float(np.linalg.norm(self.pose_right[:3, 3] - self.pose_left[:3, 3]))

    def fundamental(self) -> np.ndarray:
        """(3, 3) F with ``x_right^T F x_left = 0`` for homogeneous pixels."""
        right_from_left = np.linalg.inv(self.pose_right) @ self.pose_left
        R, t = right_from_left[:3, :3], right_from_left[:3, 3]
        tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
        return np.linalg.inv(self.K_right).T @ tx @ R @ np.linalg.inv(self.K_left)

    def epipolar_distance(self, xy_left: np.ndarray, xy_right: np.ndarray) -> np.ndarray:
        """(N,) px: distance of each right point to its left point's epipolar line."""
        xl, xr = self.ideal(xy_left, "left"), self.ideal(xy_right, "right")
        if len(xl) != len(xr):
            raise ActiveVisionError(f"{len(xl)} left and {len(xr)} right points; valid: equal")
        lines = np.hstack([xl, np.ones((len(xl), 1))]) @ self.fundamental().T
        num = np.abs(np.sum(lines[:, :2] * xr, 1) + lines[:, 2])
        return num / np.maximum(np.linalg.norm(lines[:, :2], axis=1), 1e-12)

    def triangulate(self, xy_left: np.ndarray, xy_right: np.ndarray) -> np.ndarray:
        """(N, 3) world points of matched pixels (``cv2.triangulatePoints``, linear DLT), m."""
        xl, xr = self.ideal(xy_left, "left"), self.ideal(xy_right, "right")
        if len(xl) != len(xr):
            raise ActiveVisionError(f"{len(xl)} left and {len(xr)} right points; valid: equal")
        if len(xl) == 0:
            return np.zeros((0, 3))
        X = cv2.triangulatePoints(
            projection_matrix(self.K_left, self.pose_left),
            projection_matrix(self.K_right, self.pose_right),
            xl.T.copy(), xr.T.copy(),
        )  # fmt: skip
        with np.errstate(divide="ignore", invalid="ignore"):
            return (X[:3] / X[3]).T

    def depths(self, points: np.ndarray) -> np.ndarray:
        """(N, 2) z of world points in the left and right camera frames, m."""
        points = np.asarray(points, float).reshape(-1, 3)
        out = []
        for pose in (self.pose_left, self.pose_right):
            out.append((points - pose[:3, 3]) @ pose[:3, 2])
        return np.stack(out, 1)


def _points(xy) -> np.ndarray:
    array = np.asarray(xy, np.float64)
    if array.ndim == 1 and array.shape == (2,):
        array = array[None]
    if array.ndim != 2 or array.shape[1] != 2 or not np.all(np.isfinite(array)):
        raise ActiveVisionError(f"points have shape {array.shape}; valid: finite (N, 2) pixels")
    return array


def match_hypotheses(
    left: list[Hypothesis] | tuple[Hypothesis, ...],
    right: list[Hypothesis] | tuple[Hypothesis, ...],
    rig: StereoRig,
    epipolar_px: float = EPIPOLAR_TOLERANCE_PX,
    expected_disparity: float | None = None,
    disparity_px: float = DISPARITY_TOLERANCE_PX,
) -> list[tuple[int, int]]:
    """One-to-one ``(left index, right index)`` pairs of hypotheses of the same object.

    A pair qualifies with the same class, the right centre within ``epipolar_px`` of the left
    centre's epipolar line, the triangulated centre in front of both cameras, and, when
    ``expected_disparity`` (``x_right - x_left``, px) is given, a centre disparity within
    ``disparity_px`` of it. Among the qualifying pairs, the assignment minimising the summed
    epipolar distance (plus disparity error) is returned, sorted by left index.
    """
    if not left or not right:
        return []
    cl = np.array([h.centre for h in left], float)
    cr = np.array([h.centre for h in right], float)
    nl, nr = len(left), len(right)
    il, ir = np.repeat(np.arange(nl), nr), np.tile(np.arange(nr), nl)
    epi = rig.epipolar_distance(cl[il], cr[ir])
    cost = epi.copy()
    ok = epi <= epipolar_px
    ok &= np.array([left[i].class_name == right[j].class_name for i, j in zip(il, ir, strict=True)])
    ok &= np.all(rig.depths(rig.triangulate(cl[il], cr[ir])) > 0, axis=1)
    if expected_disparity is not None:
        error = np.abs(cr[ir, 0] - cl[il, 0] - expected_disparity)
        ok &= error <= disparity_px
        cost += error
    big = 1e9
    matrix = np.where(ok, cost, big).reshape(nl, nr)
    rows, cols = linear_sum_assignment(matrix)
    return sorted((int(i), int(j)) for i, j in zip(rows, cols, strict=True) if matrix[i, j] < big)


def hypothesis_position(
    left: Hypothesis,
    right: Hypothesis,
    rig: StereoRig,
    left_features: Features | None = None,
    right_features: Features | None = None,
    epipolar_px: float = EPIPOLAR_TOLERANCE_PX,
) -> np.ndarray:
    """(3,) world position of an object seen by both cameras, m.

    With both images' features: the median of the triangulated matches between the two
    hypotheses' inlier keypoints (ratio test, epipolar distance within ``epipolar_px``, in
    front of both cameras), when at least 5 remain; otherwise the triangulated centres.
    """
    if left_features is not None and right_features is not None:
        fl = left_features.subset(left.inlier_indices)
        fr = right_features.subset(right.inlier_indices)
        pairs = match(fl, fr)
        if len(pairs) >= MIN_POSITION_MATCHES:
            xl, xr = fl.xy[pairs[:, 0]], fr.xy[pairs[:, 1]]
            good = rig.epipolar_distance(xl, xr) <= epipolar_px
            points = rig.triangulate(xl[good], xr[good])
            good_points = points[np.all(rig.depths(points) > 0, axis=1)]
            if len(good_points) >= MIN_POSITION_MATCHES:
                return np.median(good_points, axis=0)
    return rig.triangulate(left.centre, right.centre)[0]
