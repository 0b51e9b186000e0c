"""The compiled Euclidean clustering gives scipy's components (kd-tree pairs, csgraph labels)
whenever it answers, and leaves to scipy exactly the graphs it cannot certify."""

import numpy as np
import pytest

from ipbench.perception import _cluster_kernels
from ipbench.perception._cluster_kernels import radius_components
from ipbench.perception.segmentation import _components_by_tree


def _blobs(n: int, seed: int) -> np.ndarray:
    """Voxel-like centres (m): a few dense blobs and sparse strays, around x = 1 m, z = 0.8 m."""
    rng = np.random.default_rng(seed)
    centres = rng.uniform([0.6, -0.5, 0.75], [1.3, 0.3, 0.95], (6, 3))
    blobs = [c + rng.normal(0.0, 0.02, (n // 8, 3)) for c in centres]
    strays = rng.uniform([0.5, -0.6, 0.7], [1.4, 0.4, 1.0], (n - 6 * (n // 8), 3))
    points = np.concatenate([*blobs, strays])
    return points[rng.permutation(len(points))]


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("eps", [0.007, 0.015, 0.025])
def test_components_are_scipys(seed, eps):
    centres = _blobs(4000, seed)
    labels = radius_components(centres, eps)
    expected = _components_by_tree(centres, eps)
    assert labels is not None and labels.dtype == expected.dtype == np.int32
    assert 1 < expected.max() + 1 < len(centres)  # several components, some merged
    np.testing.assert_array_equal(labels, expected)


def test_negative_coordinates_and_tiny_inputs():
    centres = _blobs(1000, 7) - [2.0, 1.0, 3.0]
    np.testing.assert_array_equal(
        radius_components(centres, 0.015), _components_by_tree(centres, 0.015)
    )
    assert radius_components(np.zeros((0, 3)), 0.015).shape == (0,)
    np.testing.assert_array_equal(radius_components(np.ones((1, 3)), 0.015), [0])
    np.testing.assert_array_equal(radius_components(np.ones((3, 3)), 0.015), [0, 0, 0])


def test_a_pair_at_eps_joining_two_components_is_left_to_scipy():
    eps = 0.015
    pair = np.array([[0.5, 0.2, 0.8], [0.5 + eps, 0.2, 0.8]])  # distance eps up to rounding
    assert radius_components(pair, eps) is None
    # the same pair inside one component (also joined through a third centre) is decided
    bridged = np.concatenate([pair, [[0.5 + eps / 2, 0.2, 0.8]]])
    np.testing.assert_array_equal(radius_components(bridged, eps), [0, 0, 0])
    np.testing.assert_array_equal(
        radius_components(bridged, eps), _components_by_tree(bridged, eps)
    )


def test_the_segmentation_clusters_as_scipy_when_the_kernel_gives_up():
    from ipbench.perception.cloud import Cloud
    from ipbench.perception.segmentation import SegmentationConfig, _cluster

    config = SegmentationConfig(min_points=1, min_extent=0.0)
    eps = config.cluster_eps
    points = np.array([[0.5 + eps * i, 0.2, 0.8] for i in range(4)])  # one voxel each, eps apart
    assert radius_components(points, eps) is None
    cloud = Cloud(points, np.arange(4), (1, 4), np.zeros(3))
    sizes = sorted(len(s.points) for s in _cluster(cloud, config, np.array([0, 0, 1.0]), None))
    assert sizes == sorted(np.bincount(_components_by_tree(points, eps)).tolist())


def test_non_finite_or_too_fine_grids_are_left_to_scipy(monkeypatch):
    centres = _blobs(500, 3)
    broken = centres.copy()
    broken[10, 2] = np.nan
    assert radius_components(broken, 0.015) is None
    assert radius_components(centres, 1e-9) is None  # eps below the rounding band
    monkeypatch.setattr(_cluster_kernels, "MAX_CELLS", 8)
    assert radius_components(centres, 0.015) is None
