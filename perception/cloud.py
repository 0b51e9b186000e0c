"""Depth image to world-frame point cloud, and the root exception of the perception modules.

A :class:`Cloud` keeps, for every point, the flat index (``row * W + col``) of the pixel it
came from, so that segments found in 3-D map back to the image (for evaluation against a
ground-truth mask, or for colour). Pixels without depth (0, NaN or inf) are dropped.

Camera convention (as the environment's ``wrist_K`` / ``wrist_pose``): OpenCV, x right,
y down, z forward; a pixel ``(u, v) = (col, row)`` has its centre at integer coordinates, so
a camera-frame point is ``z * K^-1 (u, v, 1)``; ``pose`` is the 4x4 world-from-camera
transform. A camera with lens distortion (``dist``: OpenCV ``(k1, k2, p1, p2, k3)``, the
observation's ``*_dist`` under ``extrinsics="nominal"|"calibrated"``) back-projects each pixel
along its undistorted ray (``cv2.undistortPoints``), so the image itself is never resampled
and every point keeps its pixel.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from ipbench.perception._cloud_kernels import box_members, voxel_assign

__all__ = ["Cloud", "PerceptionError", "crop_box", "depth_to_points", "voxel_grid"]


class PerceptionError(ValueError):
    """Root exception of the perception modules; messages say what was wrong and what is valid."""


@dataclass(frozen=True, eq=False)
class Cloud:
    """A point cloud in the world frame with its pixel origins.

    Attributes
    ----------
    points : (N, 3) float64 array
        World coordinates, m.
    pixels : (N,) int64 array
        Flat pixel index ``row * W + col`` of each point in the source image.
    shape : tuple of int
        ``(H, W)`` of the source image, px.
    origin : (3,) float64 array
        Camera centre in the world frame, m (the viewpoint, e.g. to orient normals).
    """

    points: np.ndarray
    pixels: np.ndarray
    shape: tuple[int, int]
    origin: np.ndarray

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, index: np.ndarray) -> Cloud:
        """The cloud restricted to ``index`` (a boolean mask (N,) or integer indices)."""
        return Cloud(self.points[index], self.pixels[index], self.shape, self.origin)


def _check_matrix(name: str, value, shape: tuple[int, int]) -> np.ndarray:
    array = np.asarray(value, dtype=np.float64)
    if array.shape != shape or not np.all(np.isfinite(array)):
        raise PerceptionError(
            f"{name} has shape {array.shape} (finite: {bool(np.all(np.isfinite(array)))}); "
            f"valid: a finite {shape[0]}x{shape[1]} matrix"
        )
    return array


@lru_cache(maxsize=4)
def _ray_grid(key: bytes, height: int, width: int) -> np.ndarray:
    """(H * W, 2) undistorted normalised coordinates ``(x/z, y/z)`` of every pixel centre of a
    camera whose ``K`` (9) and ``dist`` (5) float64 values are packed in ``key``."""
    values = np.frombuffer(key, dtype=np.float64)
    K, dist = values[:9].reshape(3, 3), values[9:]  # noqa: N806
    v, u = np.divmod(np.arange(height * width, dtype=np.float64), width)
    pixels = np.column_stack([u, v]).reshape(-1, 1, 2)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-10)
    rays = cv2.undistortPointsIter(pixels, K, dist, None, None, criteria).reshape(-1, 2)
    rays.setflags(write=False)
    return rays


def depth_to_points(
    depth: np.ndarray, K: np.ndarray, pose: np.ndarray, dist: np.ndarray | None = None
) -> Cloud:
    """Back-project the valid pixels of a depth image to the world frame.

    Parameters
    ----------
    depth : (H, W) float array
        z-depth along the optical axis, m; 0 (or NaN/inf) = no depth (dropped).
    K : (3, 3) array
        Intrinsics ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``, px (skew is honoured).
    pose : (4, 4) array
        World-from-camera transform, OpenCV camera convention, m.
    dist : (5,) array or None
        The lens' OpenCV distortion ``(k1, k2, p1, p2, k3)`` (the depth image is as the lens
        sees: distorted); None or all zeros: a pinhole, as before.

    Returns
    -------
    Cloud
        One point per valid pixel, in row-major pixel order.
    """
    depth = np.asarray(depth)
    if depth.ndim != 2 or depth.size == 0 or not np.issubdtype(depth.dtype, np.number):
        raise PerceptionError(
            f"depth has shape {depth.shape} and dtype {depth.dtype}; "
            "valid: a non-empty (H, W) numeric image in metres"
        )
    K = _check_matrix("K", K, (3, 3))
    pose = _check_matrix("pose", pose, (4, 4))
    if K[0, 0] <= 0 or K[1, 1] <= 0 or K[1, 0] != 0 or K[2, 0] != 0 or K[2, 1] != 0:
        raise PerceptionError(f"K={K.tolist()} is not an intrinsics matrix; valid: fx, fy > 0")
    rotation = pose[:3, :3]
    if not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-6) or abs(pose[3, 3] - 1) > 1e-9:
        raise PerceptionError("pose is not a rigid transform; valid: [[R, t], [0, 0, 0, 1]]")

    if dist is not None:
        dist = np.asarray(dist, dtype=np.float64)
        if dist.shape != (5,) or not np.all(np.isfinite(dist)):
            raise PerceptionError(
                f"dist has shape {dist.shape}; valid: 5 finite OpenCV coefficients "
                "(k1, k2, p1, p2, k3), or None for a pinhole"
            )
        if not np.any(dist):
            dist = None

    height, width = depth.shape
    flat = depth.reshape(-1)
    with np.errstate(invalid="ignore"):
        pixels = np.flatnonzero(np.isfinite(flat) & (flat > 0))
    z = flat[pixels].astype(np.float64)
    if dist is None:
        v, u = np.divmod(pixels, width)
        fx, skew, cx, fy, cy = K[0, 0], K[0, 1], K[0, 2], K[1, 1], K[1, 2]
        y_over_z = (v - cy) / fy
        x_over_z = (u - cx - skew * y_over_z) / fx
    else:
        rays = _ray_grid(np.concatenate([K.reshape(-1), dist]).tobytes(), height, width)
        x_over_z, y_over_z = rays[pixels, 0], rays[pixels, 1]
    camera = np.column_stack([x_over_z * z, y_over_z * z, z])
    points = camera @ rotation.T + pose[:3, 3]
    return Cloud(points, pixels.astype(np.int64), (height, width), pose[:3, 3].copy())


def crop_box(cloud: Cloud, center, half) -> Cloud:
    """The points of ``cloud`` inside an axis-aligned world box.

    Parameters
    ----------
    cloud : Cloud
    center, half : (3,) array-like
        Box centre and half sizes, m (world frame); e.g. the inspection area with a height
        limit: ``center=(0.72, 0.26, 0.85), half=(0.1, 0.1, 0.15)``.
    """
    center = np.asarray(center, dtype=np.float64).reshape(-1)
    half = np.asarray(half, dtype=np.float64).reshape(-1)
    if center.shape != (3,) or half.shape != (3,) or not np.all(half > 0):
        raise PerceptionError(
            f"box center {center.tolist()}, half {half.tolist()}; "
            "valid: two 3-vectors in metres, half sizes > 0"
        )
    points = np.ascontiguousarray(cloud.points, dtype=np.float64)
    return cloud.subset(box_members(points, center, half))


def voxel_grid(points: np.ndarray, size: float) -> tuple[np.ndarray, np.ndarray]:
    """Voxel-grid downsampling that remembers which voxel each point went to.

    Parameters
    ----------
    points : (N, 3) array
        m.
    size : float
        Voxel edge, m (grid anchored at the world origin).

    Returns
    -------
    centroids : (V, 3) float64 array
        Mean of the points in each occupied voxel, m.
    voxel_of : (N,) int64 array
        Index into ``centroids`` of each point (so labels go back from voxels to points).
    """
    if not size > 0:
        raise PerceptionError(f"voxel size {size!r}; valid: > 0 m")
    points = np.asarray(points, dtype=np.float64)
    if len(points) == 0:
        return np.zeros((0, 3)), np.zeros(0, np.int64)
    points = np.ascontiguousarray(points)
    ranked = voxel_assign(points, float(size))
    if ranked is None:  # a grid too large for the rank table: the same numbering by a sort
        return _voxel_grid_by_sort(points, size)
    voxel_of, counts, sums = ranked
    return sums / counts[:, None], voxel_of


def _voxel_grid_by_sort(points: np.ndarray, size: float) -> tuple[np.ndarray, np.ndarray]:
    """:func:`voxel_grid` by numpy alone (voxels numbered by ``np.unique``'s sort): what the
    kernel replaced, and what it is tested against."""
    keys = np.floor(points / size).astype(np.int64)
    keys -= keys.min(axis=0)
    span = keys.max(axis=0) + 1
    flat = (keys[:, 0] * span[1] + keys[:, 1]) * span[2] + keys[:, 2]
    _, voxel_of, counts = np.unique(flat, return_inverse=True, return_counts=True)
    sums = np.stack([np.bincount(voxel_of, points[:, i], len(counts)) for i in range(3)], 1)
    return sums / counts[:, None], voxel_of.astype(np.int64)
