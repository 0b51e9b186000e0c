"""The compiled point-cloud kernels give bit-identical results to the numpy chains they replace
(the voxel grid's is kept as its fallback, ``cloud._voxel_grid_by_sort``)."""

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
