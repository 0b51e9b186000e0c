"""The compiled point-cloud kernels give bit-identical results to the numpy chains they replace
(the voxel grid's is kept as its fallback, ``cloud._voxel_grid_by_sort``) and to the voxel
grid's point-by-point definition; the hull test answers as numpy's expression or leaves the
point to it."""

import numpy as np
import pytest

from ipbench.perception import _cloud_kernels
from ipbench.perception.cloud import Cloud, _voxel_grid_by_sort, crop_box, voxel_grid


def _table_scene(n: int, seed: int) -> np.ndarray:
    """A table top at z = 0.75 m with noise and a few boxes on it, world metres."""
    rng = np.random.default_rng(seed)
    table = np.column_stack(
        [rng.uniform(0.55, 1.35, n), rng.uniform(-0.6, 0.4, n), 0.75 + rng.normal(0, 2e-3, n)]
    )
    objects = [
        c + rng.uniform(-0.04, 0.04, (n // 10, 3)) * [1, 1, 2]
        for c in rng.uniform([0.7, -0.4, 0.8], [1.2, 0.2, 0.85], (4, 3))
    ]
    return np.concatenate([table, *objects])


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("size", [0.005, 0.013, 0.05])
def test_voxel_grid_matches_the_numpy_chain_bit_for_bit(seed, size):
    points = _table_scene(20_000, seed)
    points = points[np.random.default_rng(seed).permutation(len(points))]
    centres, voxel_of = voxel_grid(points, size)
    ref_centres, ref_voxel_of = _voxel_grid_by_sort(points, size)
    assert voxel_of.dtype == np.int64
    np.testing.assert_array_equal(voxel_of, ref_voxel_of)
    assert centres.tobytes() == ref_centres.tobytes()


def test_a_grid_too_large_for_the_rank_table_takes_the_sort_with_the_same_result(monkeypatch):
    points = _table_scene(5_000, 7)
    by_table = voxel_grid(points, 0.005)
    monkeypatch.setattr(_cloud_kernels, "MAX_GRID_CELLS", 10)
    assert _cloud_kernels.voxel_assign(points, 0.005) is None
    by_sort = voxel_grid(points, 0.005)
    np.testing.assert_array_equal(by_sort[1], by_table[1])
    assert by_sort[0].tobytes() == by_table[0].tobytes()


def test_voxel_grid_of_negative_coordinates_and_one_point():
    points = np.array([[-0.0126, -1.0, 3.0], [-0.0124, -1.0, 3.0], [0.0, 0.0, 0.0]])
    centres, voxel_of = voxel_grid(points, 0.005)
    ref_centres, ref_voxel_of = _voxel_grid_by_sort(points, 0.005)
    np.testing.assert_array_equal(voxel_of, ref_voxel_of)
    assert centres.tobytes() == ref_centres.tobytes()
    one, index = voxel_grid(points[:1], 0.005)
    np.testing.assert_array_equal(one, points[:1])
    np.testing.assert_array_equal(index, [0])


def test_crop_box_matches_the_numpy_mask_and_keeps_the_order():
    points = _table_scene(20_000, 3)
    cloud = Cloud(points, np.arange(len(points)) * 3, (480, 640), np.zeros(3))
    center, half = np.array([0.9, -0.1, 0.8]), np.array([0.2, 0.15, 0.05])
    part = crop_box(cloud, center, half)
    inside = np.all(np.abs(points - center) <= half, axis=1)
    assert 0 < len(part) < len(cloud)
    assert part.points.tobytes() == points[inside].tobytes()
    np.testing.assert_array_equal(part.pixels, cloud.pixels[inside])
    # a point exactly on the box face is inside, as with the numpy mask
    edge = Cloud(np.array([[1.1, -0.1, 0.8]]), np.zeros(1, np.int64), (1, 1), np.zeros(3))
    assert len(crop_box(edge, center, half)) == int(np.all(np.abs(edge.points - center) <= half))


@pytest.mark.parametrize("opening", [0.0, 0.035, 0.09])
def test_the_in_hand_mask_matches_the_numpy_chain_bit_for_bit(opening):
    from ipbench.perception.segmentation import GripperGeometry, SegmentationConfig

    gripper, config = GripperGeometry(), SegmentationConfig()
    rng = np.random.default_rng(int(opening * 1000))
    # points around the gripper (TCP frame, m), some exactly on a sphere of the hand radius
    local = rng.uniform(-0.35, 0.35, (200_000, 3))
    local[:1000] *= config.hand_radius / np.linalg.norm(local[:1000], axis=1)[:, None]
    palm_front = gripper.palm_center[2] + gripper.palm_half[2] - gripper.tcp_offset
    reference = (np.linalg.norm(local, axis=1) <= config.hand_radius) & (local[:, 2] > palm_front)
    boxes = gripper.boxes(opening)
    for centre, half in boxes:
        reference &= ~np.all(np.abs(local - centre) <= half + config.gripper_margin, axis=1)
    keep = _cloud_kernels.hand_keep(
        local,
        config.hand_radius,
        palm_front,
        np.array([c for c, _ in boxes]),
        np.array([h + config.gripper_margin for _, h in boxes]),
    )
    assert 0 < keep.sum() < len(keep)
    np.testing.assert_array_equal(keep, reference)


def _voxel_grid_by_dict(points: np.ndarray, size: float) -> tuple[np.ndarray, np.ndarray]:
    """The voxel grid written out point by point: key ``floor(p / size)`` per axis, voxels
    numbered in increasing key order (row-major over the grid), each centroid the sum of its
    points in their order divided by their count."""
    keys = [tuple(int(np.floor(v / size)) for v in p) for p in points]
    number = {key: i for i, key in enumerate(sorted(set(keys)))}
    sums, counts = np.zeros((len(number), 3)), np.zeros(len(number), np.int64)
    for p, key in zip(points, keys, strict=True):
        for a in range(3):
            sums[number[key], a] += p[a]
        counts[number[key]] += 1
    return sums / counts[:, None], np.array([number[k] for k in keys], np.int64)


def _assert_same_grid(points: np.ndarray, size: float) -> None:
    centres, voxel_of = voxel_grid(points, size)
    ref_centres, ref_voxel_of = _voxel_grid_by_dict(points, size)
    assert voxel_of.dtype == np.int64 and centres.shape == ref_centres.shape
    np.testing.assert_array_equal(voxel_of, ref_voxel_of)
    assert centres.tobytes() == ref_centres.tobytes()


@pytest.mark.parametrize("seed", range(4))
def test_voxel_grid_equals_the_point_by_point_definition(seed):
    rng = np.random.default_rng(seed)
    size = [0.005, 0.02, 0.1, 1.0][seed]
    # a spread cloud (grids of many bit-set words) around negative and positive coordinates
    points = rng.normal(0.0, 30 * size, (3000, 3)) + rng.uniform(-2.0, 2.0, 3)
    _assert_same_grid(points, size)


def test_voxel_grid_on_voxel_boundaries_negative_zero_and_one_voxel():
    size = 0.25  # exact in binary: k * size lies exactly on a voxel face
    k = np.arange(-8, 9) * size
    on_faces = np.stack(np.meshgrid(k, k[::-1], k[:5]), -1).reshape(-1, 3)
    _assert_same_grid(on_faces, size)
    just_below = np.nextafter(on_faces, -np.inf)  # one ulp into the voxel before
    _assert_same_grid(np.concatenate([on_faces, just_below]), size)
    _assert_same_grid(np.array([[-0.0, 0.0, -0.0], [0.0, -0.0, 0.0], [-1e-300, 0.0, 0.0]]), 0.005)
    same = np.tile([[0.3, -0.7, 0.01]], (5, 1))  # all in one voxel: its centroid is the point
    _assert_same_grid(same, 0.005)


def test_empty_cloud_gives_no_voxels():
    centres, voxel_of = voxel_grid(np.zeros((0, 3)), 0.005)
    assert centres.shape == (0, 3) and voxel_of.shape == (0,) and voxel_of.dtype == np.int64


def test_non_finite_points_take_the_numpy_chain():
    points = _table_scene(100, 1)
    for bad in (np.nan, np.inf, -np.inf):
        broken = points.copy()
        broken[50, 1] = bad
        assert _cloud_kernels.voxel_assign(broken, 0.005) is None
    far = points.copy()
    far[0, 0] = 1e300  # a key beyond int64
    assert _cloud_kernels.voxel_assign(far, 0.005) is None


def _hull_by_numpy(points, index, e1, e2, equations) -> np.ndarray:
    flat = np.column_stack([points[index] @ e1, points[index] @ e2])
    limit = _cloud_kernels.HULL_LIMIT
    return np.all(flat @ equations[:, :2].T + equations[:, 2] <= limit, axis=1)


def _table_hull(seed: int):
    from scipy.spatial import ConvexHull

    from ipbench.perception.segmentation import plane_basis

    rng = np.random.default_rng(seed)
    normal = np.array([0.05, -0.03, 1.0]) / np.linalg.norm([0.05, -0.03, 1.0])
    e1, e2 = plane_basis(normal)
    support = rng.uniform([0.6, -0.5, 0.7], [1.3, 0.3, 0.75], (400, 3))
    hull = ConvexHull(np.column_stack([support @ e1, support @ e2]))
    return support, e1, e2, np.ascontiguousarray(hull.equations)


@pytest.mark.parametrize("seed", range(3))
def test_hull_members_decides_as_the_numpy_expression(seed):
    support, e1, e2, equations = _table_hull(seed)
    rng = np.random.default_rng(seed + 10)
    points = np.concatenate([rng.uniform([0.4, -0.7, 0.7], [1.5, 0.5, 1.0], (20_000, 3)), support])
    index = np.flatnonzero(rng.random(len(points)) < 0.8)
    decided, inside = _cloud_kernels.hull_members(points, index, e1, e2, equations)
    expected = _hull_by_numpy(points, index, e1, e2, equations)
    assert decided and 0 < expected.sum() < len(expected)
    np.testing.assert_array_equal(inside, expected)  # the hull's own vertices included


def test_a_point_at_the_hull_limit_is_left_to_numpy():
    from ipbench.perception.segmentation import _over_hull

    support, e1, e2, equations = _table_hull(0)
    a, b, c = equations[0]
    # a point HULL_LIMIT outside facet 0, next to the middle of that facet
    vertex = support[np.argmin(np.abs(support @ e1 * a + support @ e2 * b + c))]
    shift = _cloud_kernels.HULL_LIMIT - (vertex @ e1 * a + vertex @ e2 * b + c)
    edge = vertex + shift * (a * e1 + b * e2) / (a * a + b * b)
    points = np.concatenate([support, edge[None]])
    index = np.arange(len(points))
    decided, _ = _cloud_kernels.hull_members(points, index, e1, e2, equations)
    assert not decided
    expected = _hull_by_numpy(points, index, e1, e2, equations)
    np.testing.assert_array_equal(_over_hull(points, index, e1, e2, equations), expected)


def test_a_non_finite_point_is_left_to_numpy():
    from ipbench.perception.segmentation import _over_hull

    support, e1, e2, equations = _table_hull(1)
    points = support.copy()
    points[3] = np.nan
    index = np.arange(len(points))
    assert not _cloud_kernels.hull_members(points, index, e1, e2, equations)[0]
    expected = _hull_by_numpy(points, index, e1, e2, equations)
    assert not expected[3]
    np.testing.assert_array_equal(_over_hull(points, index, e1, e2, equations), expected)
