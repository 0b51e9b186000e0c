"""Depth image to world point cloud: synthetic planes with known geometry, a real observation."""

import numpy as np
import pytest

from ipbench.perception.cloud import Cloud, PerceptionError, crop_box, depth_to_points

H, W = 48, 64
K = np.array([[60.0, 0.0, 31.0], [0.0, 55.0, 24.5], [0.0, 0.0, 1.0]])


def _rot(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def _looking_down(tilt: float = 0.0, yaw: float = 0.0, origin=(0.9, -0.1, 1.5)) -> np.ndarray:
    """World-from-camera pose, OpenCV convention, optical axis down, tilted about camera x."""
    down = np.column_stack([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
    pose = np.eye(4)
    pose[:3, :3] = _rot("z", yaw) @ down @ _rot("x", tilt)
    pose[:3, 3] = origin
    return pose


def _plane_depth(pose: np.ndarray, plane_z: float) -> np.ndarray:
    """Exact z-depth image of the horizontal plane z = plane_z seen from ``pose``."""
    v, u = np.mgrid[0:H, 0:W]
    rays = np.stack([u, v, np.ones_like(u)], -1).reshape(-1, 3) @ np.linalg.inv(K).T
    world_dz = rays @ pose[:3, :3].T
    depth = (plane_z - pose[2, 3]) / world_dz[:, 2]  # ray parameter = camera z (ray z = 1)
    return depth.reshape(H, W)


@pytest.mark.parametrize("tilt,yaw", [(0.0, 0.0), (0.5, 0.3), (-0.3, 2.0)])
def test_plane_back_projects_to_its_height(tilt, yaw):
    pose = _looking_down(tilt, yaw)
    depth = _plane_depth(pose, 0.70)
    assert np.all(depth > 0)
    cloud = depth_to_points(depth.astype(np.float32), K, pose)
    assert cloud.points.shape == (H * W, 3) and cloud.points.dtype == np.float64
    assert np.max(np.abs(cloud.points[:, 2] - 0.70)) < 1e-3
    np.testing.assert_allclose(cloud.origin, pose[:3, 3])


def test_pixels_map_back_to_their_image_position():
    pose = _looking_down(0.4, 1.0)
    cloud = depth_to_points(_plane_depth(pose, 0.70), K, pose)
    camera = (cloud.points - pose[:3, 3]) @ pose[:3, :3]  # world -> camera frame
    uvw = camera @ K.T
    u, v = uvw[:, 0] / uvw[:, 2], uvw[:, 1] / uvw[:, 2]
    row, col = np.divmod(cloud.pixels, W)
    np.testing.assert_allclose(u, col, atol=1e-6)
    np.testing.assert_allclose(v, row, atol=1e-6)
    assert cloud.shape == (H, W)


def test_holes_are_dropped():
    pose = _looking_down()
    depth = _plane_depth(pose, 0.70)
    depth[5, 7] = 0.0
    depth[10, :] = np.nan
    depth[20, 30] = np.inf
    cloud = depth_to_points(depth, K, pose)
    assert len(cloud) == H * W - 1 - W - 1
    holes = {5 * W + 7, 20 * W + 30} | set(range(10 * W, 11 * W))
    assert not holes & set(cloud.pixels.tolist())
    assert np.all(np.diff(cloud.pixels) > 0)  # row-major order


def test_subset_and_crop_box():
    pose = _looking_down()
    cloud = depth_to_points(_plane_depth(pose, 0.70), K, pose)
    part = crop_box(cloud, (0.9, -0.1, 0.7), (0.1, 0.05, 0.01))
    assert 0 < len(part) < len(cloud)
    assert np.all(np.abs(part.points[:, :2] - [0.9, -0.1]) <= [0.1, 0.05])
    assert isinstance(part, Cloud) and part.shape == cloud.shape
    with pytest.raises(PerceptionError, match="half sizes > 0"):
        crop_box(cloud, (0, 0, 0), (0.1, -0.1, 0.1))


DIST = np.array([0.12, -0.3, 0.004, -0.003, 0.05])  # stronger than any lens of the envs


def test_distorted_pixels_back_project_along_their_true_rays():
    """A distorted camera's depth pixels go back to the points that project onto them
    (``cv2.projectPoints`` with the same lens), and a pinhole back-projection does not."""
    import cv2

    rng = np.random.default_rng(3)
    pose = _looking_down(0.3, 0.7)
    camera = np.column_stack(
        [rng.uniform(-0.35, 0.35, 200), rng.uniform(-0.3, 0.3, 200), rng.uniform(0.6, 1.2, 200)]
    )
    uv = cv2.projectPoints(camera, np.zeros(3), np.zeros(3), K, DIST)[0].reshape(-1, 2)
    # the pixel each point falls in (one point per pixel, inside the image)
    col, row = np.rint(uv[:, 0]).astype(int), np.rint(uv[:, 1]).astype(int)
    keep = (col >= 0) & (col < W) & (row >= 0) & (row < H)
    camera, uv, col, row = camera[keep], uv[keep], col[keep], row[keep]
    flat, first = np.unique(row * W + col, return_index=True)
    camera, uv = camera[first], uv[first]
    # move each point along its own ray so that it projects exactly onto the pixel centre
    ideal = cv2.undistortPointsIter(
        np.column_stack([col[first], row[first]]).astype(float).reshape(-1, 1, 2),
        K,
        DIST,
        None,
        None,
        (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12),
    ).reshape(-1, 2)
    exact = np.column_stack([ideal * camera[:, 2:], camera[:, 2]])
    depth = np.zeros((H, W))
    depth.reshape(-1)[flat] = exact[:, 2]
    cloud = depth_to_points(depth, K, pose, DIST)
    np.testing.assert_array_equal(cloud.pixels, flat)
    world = exact @ pose[:3, :3].T + pose[:3, 3]
    assert np.abs(cloud.points - world).max() < 1e-6
    pinhole = depth_to_points(depth, K, pose)
    assert np.abs(pinhole.points - world).max() > 1e-3  # the lens matters at these sizes
    # zeros are a pinhole; a bad lens is refused with the valid form
    zero = depth_to_points(depth, K, pose, np.zeros(5))
    np.testing.assert_array_equal(zero.points, pinhole.points)
    with pytest.raises(PerceptionError, match="5 finite OpenCV coefficients"):
        depth_to_points(depth, K, pose, np.zeros(4))


@pytest.mark.parametrize(
    "depth,k,pose,match",
    [
        (np.zeros((4, 4, 1)), K, np.eye(4), "depth has shape"),
        (np.ones((4, 4)), np.eye(2), np.eye(4), "valid: a finite 3x3"),
        (np.ones((4, 4)), -K, np.eye(4), "fx, fy > 0"),
        (np.ones((4, 4)), K, np.diag([2.0, 1, 1, 1]), "rigid transform"),
    ],
)
def test_invalid_inputs_raise(depth, k, pose, match):
    with pytest.raises(PerceptionError, match=match):
        depth_to_points(depth, k, pose)
    assert issubclass(PerceptionError, ValueError)


def test_real_observation_table_at_its_height():
    import gymnasium as gym

    import ipbench.envs  # noqa: F401

    env = gym.make("ipbench/SortingUncluttered-v0")
    try:
        obs, info = env.reset(seed=0)
    finally:
        env.close()
    cloud = depth_to_points(obs["wrist_depth"], obs["wrist_K"], obs["wrist_pose"])
    assert len(cloud) == int((obs["wrist_depth"] > 0).sum())
    p = cloud.points
    on_table = (p[:, 0] > 0.6) & (p[:, 0] < 1.3) & (p[:, 1] > -0.55) & (p[:, 1] < 0.35)
    table = on_table & (info["wrist_mask"].reshape(-1)[cloud.pixels] < 0)
    z = p[table, 2]
    assert table.sum() > 50_000
    assert abs(np.median(z) - 0.70) < 0.002
    assert np.mean(np.abs(z - 0.70) < 0.01) > 0.95
