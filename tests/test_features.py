"""FPFH bag of words: descriptor shape, codebook determinism, encoding, shape discrimination."""

import types

import numpy as np
import pytest

from ipbench.perception import cloud as cloud_module
from ipbench.perception import features as features_module
from ipbench.perception import segment_eval as segment_eval_module
from ipbench.perception import segmentation as segmentation_module
from ipbench.perception.cloud import PerceptionError
from ipbench.perception.features import FPFH_DIM, Codebook, FeatureConfig, describe, fpfh

CAM_A, CAM_B = np.array([0.5, -0.6, 0.6]), np.array([-0.4, -0.6, 0.55])  # viewpoints, m
NOISE = 0.0015  # m


def _grid(a: float, b: float, step: float) -> np.ndarray:
    u, v = np.meshgrid(np.arange(-a, a + 1e-9, step), np.arange(-b, b + 1e-9, step))
    return np.column_stack([u.ravel(), v.ravel()])


def _visible(points: np.ndarray, normals: np.ndarray, camera: np.ndarray) -> np.ndarray:
    return points[np.einsum("ij,ij->i", normals, camera - points) > 0]


def box_view(size, camera, step: float = 0.002) -> np.ndarray:
    """Faces of a box (full ``size``, centred at the origin) that face ``camera``."""
    half, points, normals = np.asarray(size) / 2, [], []
    for axis in range(3):
        others = [i for i in range(3) if i != axis]
        uv = _grid(half[others[0]], half[others[1]], step)
        for sign in (1.0, -1.0):
            face = np.zeros((len(uv), 3))
            face[:, others], face[:, axis] = uv, sign * half[axis]
            normal = np.zeros(3)
            normal[axis] = sign
            points.append(face)
            normals.append(np.tile(normal, (len(face), 1)))
    return _visible(np.concatenate(points), np.concatenate(normals), camera)


def cylinder_view(radius: float, height: float, camera, step: float = 0.002) -> np.ndarray:
    """Side and top of an upright cylinder centred at the origin, as seen from ``camera``."""
    a, z = np.meshgrid(
        np.arange(0, 2 * np.pi, step / radius), np.arange(-height / 2, height / 2, step)
    )
    ring = np.column_stack([np.cos(a.ravel()), np.sin(a.ravel()), np.zeros(a.size)])
    side = ring * [radius, radius, 0] + np.column_stack([np.zeros((a.size, 2)), z.ravel()])
    disk = _grid(radius, radius, step)
    disk = disk[np.hypot(disk[:, 0], disk[:, 1]) <= radius]
    top = np.column_stack([disk, np.full(len(disk), height / 2)])
    normals = np.concatenate([ring, np.tile([0.0, 0.0, 1.0], (len(top), 1))])
    return _visible(np.concatenate([side, top]), normals, camera)


def _noisy(points: np.ndarray, seed: int) -> np.ndarray:
    return points + np.random.default_rng(seed).normal(0, NOISE, points.shape)


SHAPES = {
    "box": lambda cam: box_view((0.09, 0.06, 0.20), cam),
    "cylinder": lambda cam: cylinder_view(0.035, 0.20, cam),
    "bowl": lambda cam: cylinder_view(0.08, 0.06, cam),
}


@pytest.fixture(scope="module")
def training():
    """FPFH of each shape from both viewpoints (one noise draw each)."""
    views = [(f(cam), cam) for f in SHAPES.values() for cam in (CAM_A, CAM_B)]
    return np.vstack([fpfh(_noisy(p, i), viewpoint=cam) for i, (p, cam) in enumerate(views)])


def test_fpfh_shape_and_finite():
    points = _noisy(SHAPES["cylinder"](CAM_A), 0)
    config = FeatureConfig()
    d = fpfh(points, config, viewpoint=CAM_A)
    grid = np.floor((points - points.min(axis=0)) / config.voxel_size + 0.5)  # open3d's grid
    voxels = np.unique(grid, axis=0)
    assert d.shape == (len(voxels), FPFH_DIM) and d.dtype == np.float64
    assert np.isfinite(d).all() and (d >= 0).all()
    # 3 angle histograms of 11 bins; open3d normalises each (own 100 + neighbours' 100)
    np.testing.assert_allclose(d.reshape(-1, 3, 11).sum(axis=2), 200.0, rtol=1e-6)
    assert fpfh(points, config).shape == d.shape  # default orientation: +z
    assert fpfh(np.zeros((0, 3))).shape == (0, FPFH_DIM)
    with pytest.raises(PerceptionError, match=r"finite \(N, 3\)"):
        fpfh(np.zeros((5, 2)))
    with pytest.raises(PerceptionError, match="fpfh_radius"):
        FeatureConfig(fpfh_radius=0.0)


def test_codebook_is_deterministic_for_a_seed(training, tmp_path):
    a, b = Codebook.fit(training, 32, seed=7), Codebook.fit(training, 32, seed=7)
    np.testing.assert_array_equal(a.centers, b.centers)
    assert a.size == 32 and a.centers.shape == (32, FPFH_DIM)
    assert not np.array_equal(a.centers, Codebook.fit(training, 32, seed=8).centers)
    np.testing.assert_array_equal(Codebook.from_arrays(a.to_arrays()).centers, a.centers)
    a.save(tmp_path / "codebook.npz")
    np.testing.assert_array_equal(Codebook.load(tmp_path / "codebook.npz").centers, a.centers)
    with pytest.raises(PerceptionError, match="2 <= k <= M"):
        Codebook.fit(training[:10], 32)
    with pytest.raises(PerceptionError, match="'centers'"):
        Codebook.from_arrays({"words": a.centers})


def test_encode_is_max_pooled_and_l2_normalised(training):
    codebook = Codebook.fit(training, 64, seed=0)
    descriptors = training[:500]
    bow = codebook.encode(descriptors)
    assert bow.shape == (64,) and (bow >= 0).all()
    assert np.linalg.norm(bow) == pytest.approx(1.0)
    words = np.unique(codebook.assign(descriptors))
    np.testing.assert_allclose(bow[words], 1 / np.sqrt(len(words)))  # presence, not counts
    assert np.count_nonzero(bow) == len(words)
    doubled = codebook.encode(np.vstack([descriptors, descriptors[:50]]))
    np.testing.assert_array_equal(doubled, bow)  # max pooling: repeats change nothing
    assert not codebook.encode(np.zeros((0, FPFH_DIM))).any()


def test_box_and_cylinder_differ_views_of_one_cylinder_agree(training):
    codebook, config = Codebook.fit(training, 64, seed=0), FeatureConfig(codebook_size=64)
    cyl_a = describe(_noisy(SHAPES["cylinder"](CAM_A), 100), codebook, config, viewpoint=CAM_A)
    cyl_b = describe(_noisy(SHAPES["cylinder"](CAM_B), 101), codebook, config, viewpoint=CAM_B)
    box = describe(_noisy(SHAPES["box"](CAM_A), 102), codebook, config, viewpoint=CAM_A)
    cylinders, across = np.linalg.norm(cyl_a - cyl_b), np.linalg.norm(cyl_a - box)
    assert float(cyl_a @ box) < 0.8, "box and cylinder must be clearly different"
    assert cylinders < across and cylinders < np.linalg.norm(cyl_b - box)
    assert across - cylinders > 0.15


@pytest.mark.parametrize(
    "module", [cloud_module, segmentation_module, segment_eval_module, features_module]
)
def test_all_names(module):
    """``__all__`` lists exactly the public names each module defines (plus re-exports)."""
    public = {
        name
        for name, obj in vars(module).items()
        if not name.startswith("_")
        and not isinstance(obj, types.ModuleType)
        and getattr(obj, "__module__", module.__name__) == module.__name__
    }
    reexported = {"crop_box"} if module is segmentation_module else set()
    assert set(module.__all__) == public | reexported
    assert all(hasattr(module, name) for name in module.__all__)
