"""Statistics and switches of the structured-light depth noise model (no rendering)."""

import math

import numpy as np
import pytest

from ipbench.envs.sensors.depth_noise import (
    DepthNoiseConfig,
    DepthNoiseModel,
    SensorError,
    axial_sigma,
    cos_incidence,
    lateral_sigma_px,
)

H, W, F = 480, 640, 570.0  # Xtion depth image at VGA: fx = fy ~ 570 px
U = ((np.arange(W) - (W - 1) / 2) / F)[None, :]  # ray direction (u, v, 1), OpenCV frame
V = ((np.arange(H) - (H - 1) / 2) / F)[:, None]


def plane(z: float) -> np.ndarray:
    return np.full((H, W), z, np.float32)


def tilted_plane(tilt_deg: float, z0: float, axis: str = "y"):
    """z-depth and true incidence angle (rad) of a plane through (0, 0, z0), tilted about axis."""
    b = math.radians(tilt_deg)
    n = (math.sin(b), 0.0, math.cos(b)) if axis == "y" else (0.0, math.sin(b), math.cos(b))
    dot = n[0] * U + n[1] * V + n[2]  # n . ray
    z = (z0 * n[2] / dot).astype(np.float32)
    theta = np.arccos(np.abs(dot) / np.sqrt(1 + U**2 + V**2))
    return np.broadcast_to(z, (H, W)).copy(), np.broadcast_to(theta, (H, W))


def test_documented_numbers():
    assert axial_sigma(1.0) == pytest.approx(0.0012 + 0.0019 * 0.6**2)
    assert axial_sigma(2.0) == pytest.approx(0.0012 + 0.0019 * 1.6**2)
    # angle term 0.0001 / sqrt(z) * theta^2 / (pi/2 - theta)^2: theta = 60 deg gives 4x
    assert axial_sigma(1.0, math.pi / 3) - axial_sigma(1.0) == pytest.approx(0.0004)
    assert lateral_sigma_px(math.pi / 3) == pytest.approx(0.8 + 0.035 * 2)
    model = DepthNoiseModel()
    for z in (1.0, 2.0):  # axial noise (+) disparity quantisation dz = z^2 / (f b) / 8
        dz = z**2 / (F * 0.075) / 8
        approx = math.hypot(axial_sigma(z), dz / math.sqrt(12))
        assert model.expected_std(z, F) == pytest.approx(approx, rel=0.05)


@pytest.mark.parametrize(("z", "mean_tol"), [(1.0, 0.002), (2.0, 0.005), (1.37, 0.002)])
def test_plane_statistics_match_model(z, mean_tol):
    model = DepthNoiseModel()
    out = model.apply(plane(z), F, F, np.random.default_rng(1))
    valid = out[out > 0]
    assert valid.size == H * W  # a smooth plane in range loses nothing
    assert abs(valid.mean() - z) < mean_tol
    assert valid.std() == pytest.approx(model.expected_std(z, F), rel=0.15)


def test_disparity_is_quantised():
    depth, _ = tilted_plane(40, 1.5)
    out = DepthNoiseModel().apply(depth, F, F, np.random.default_rng(1))
    levels = F * 0.075 * 8 / out[out > 0]  # disparity in 1/8 px
    assert np.abs(levels - np.rint(levels)).max() < 0.01
    assert np.unique(np.rint(levels)).size > 20


def test_lateral_noise_jags_edges():
    config = DepthNoiseConfig(edge_dropout=0.0)
    out = DepthNoiseModel(config).apply(step_image(), F, F, np.random.default_rng(3))
    far = out > 1.2  # samples from the far side of the step (columns >= 320)
    # Column 319 samples column >= 320 when round(0.8 g) >= 1, i.e. g > 0.625: 27 %.
    assert 0.2 < far[:, W // 2 - 1].mean() < 0.34
    assert 0 < far[:, W // 2 - 2].mean() < 0.08  # needs an offset >= 2 px: 3 %
    assert not far[:, : W // 2 - 4].any()


def test_noise_grows_with_distance():
    model = DepthNoiseModel()
    stds = [model.apply(plane(z), F, F, np.random.default_rng(2)).std() for z in (1.0, 2.0)]
    assert stds[1] > 2 * stds[0]


def test_deterministic_for_a_seed():
    model = DepthNoiseModel()
    depth, _ = tilted_plane(40, 1.2)
    depth[100:200, 100:300] = 0.9  # an object, for edges
    specular = np.zeros((H, W), bool)
    specular[300:400, 300:500] = True
    a, b, c = (model.apply(depth, F, F, np.random.default_rng(s), specular) for s in (7, 7, 8))
    np.testing.assert_array_equal(a, b)
    assert (a != c).mean() > 0.5


def test_disabled_is_ideal_depth_clipped_to_range():
    model = DepthNoiseModel(DepthNoiseConfig(enabled=False))
    depth = np.broadcast_to(np.linspace(0.2, 4.0, W, dtype=np.float32), (H, W))
    out = model.apply(depth, F, F, np.random.default_rng(0))
    inside = (depth >= 0.45) & (depth <= 3.5)
    np.testing.assert_array_equal(out[inside], depth[inside])
    assert (out[~inside] == 0).all()
    assert out.dtype == np.float32 and out is not depth


@pytest.mark.parametrize(("z", "valid"), [(0.40, False), (0.6, True), (3.2, True), (3.8, False)])
def test_range_limits(z, valid):
    out = DepthNoiseModel().apply(plane(z), F, F, np.random.default_rng(3))
    assert (out > 0).mean() == (1.0 if valid else 0.0)
    if valid:
        assert np.abs(out - z).max() < 0.15


def test_missing_input_stays_missing_and_input_untouched():
    depth = plane(1.0)
    depth[:, :100] = 0
    before = depth.copy()
    out = DepthNoiseModel(DepthNoiseConfig(lateral_sigma_px=0, lateral_angle_k_px=0)).apply(
        depth, F, F, np.random.default_rng(0)
    )
    assert (out[:, :100] == 0).all()
    np.testing.assert_array_equal(depth, before)


def step_image() -> np.ndarray:
    depth = plane(1.0)
    depth[:, W // 2 :] = 1.4  # a 40 cm step between columns 319 and 320
    return depth


def test_depth_edges_lose_pixels_smooth_planes_do_not():
    out = DepthNoiseModel().apply(step_image(), F, F, np.random.default_rng(4))
    missing = out == 0
    # the two columns at the step lose 70 %, spread over 6 by the lateral noise: ~23 %
    assert missing[:, W // 2 - 3 : W // 2 + 3].mean() > 0.15
    assert not missing[:, : W // 2 - 6].any()  # the planes beside it lose none
    assert not missing[:, W // 2 + 6 :].any()
    for tilt in (30, 50):  # smooth tilted planes (incidence < 73 deg) keep every pixel
        depth, _ = tilted_plane(tilt, 1.0, axis="x")
        assert (DepthNoiseModel().apply(depth, F, F, np.random.default_rng(5)) > 0).all()


def test_edge_dropout_rule():
    no_lateral = dict(lateral_sigma_px=0.0, lateral_angle_k_px=0.0)
    out = DepthNoiseModel(DepthNoiseConfig(edge_dropout=1.0, **no_lateral)).apply(
        step_image(), F, F, np.random.default_rng(0)
    )
    cols = np.flatnonzero((out == 0).any(axis=0))
    np.testing.assert_array_equal(cols, [W // 2 - 1, W // 2])  # the 3x3 span exceeds 3 cm
    assert (out[:, cols] == 0).all()
    out = DepthNoiseModel(DepthNoiseConfig(edge_dropout=0.0, **no_lateral)).apply(
        step_image(), F, F, np.random.default_rng(0)
    )
    assert (out > 0).all()


def test_grazing_incidence_is_missing():
    config = DepthNoiseConfig(edge_dropout=0.0, lateral_sigma_px=0.0, lateral_angle_k_px=0.0)
    depth, theta = tilted_plane(70, 1.0)  # incidence from ~41 deg to ~90 deg across the image
    out = DepthNoiseModel(config).apply(depth, F, F, np.random.default_rng(6))
    in_range = (depth > 0.5) & (depth < 3.3)
    grazing = in_range & (theta > np.radians(81))
    fine = in_range & (theta < np.radians(79))
    assert grazing.sum() > 1000 and fine.sum() > 1000
    assert (out[grazing] == 0).mean() > 0.95
    assert (out[fine] > 0).all()


def test_cos_incidence_matches_geometry():
    depth, theta = tilted_plane(50, 1.0)
    est = np.arccos(cos_incidence(depth, F, F))
    assert np.abs(np.degrees(est - theta)[2:-2, 2:-2]).max() < 0.5


def test_specular_holes_only_where_masked():
    specular = np.zeros((H, W), bool)
    specular[100:300, 200:400] = True
    inner = np.zeros_like(specular)
    inner[105:295, 205:395] = True  # away from the mask border (lateral shift: <= 3 px)
    outer = np.ones_like(specular)
    outer[95:305, 195:405] = False
    model = DepthNoiseModel()
    # Facing the camera (incidence < 25 deg): the IR highlight removes all of it.
    out = model.apply(plane(1.0), F, F, np.random.default_rng(8), specular)
    assert (out[inner] == 0).mean() > 0.99
    assert (out[outer] > 0).all()
    # Seen at 27-73 deg: random blobs remove ~30 % of it.
    depth, _ = tilted_plane(50, 1.0, axis="x")
    out = model.apply(depth, F, F, np.random.default_rng(9), specular)
    assert 0.15 < (out[inner] == 0).mean() < 0.5
    assert (out[outer] > 0).all()
    without = model.apply(depth, F, F, np.random.default_rng(9))
    assert (without > 0).all()


def test_invalid_input_and_config():
    model = DepthNoiseModel()
    rng = np.random.default_rng(0)
    with pytest.raises(SensorError, match="depth"):
        model.apply(np.ones((2, 3, 4), np.float32), F, F, rng)
    with pytest.raises(SensorError, match="depth"):
        model.apply(np.ones((4, 4), np.int32), F, F, rng)
    with pytest.raises(SensorError, match="specular"):
        model.apply(plane(1.0), F, F, rng, np.ones((3, 3), bool))
    with pytest.raises(SensorError, match=r"\[0, 1\]"):
        DepthNoiseConfig(edge_dropout=1.5)
    assert issubclass(SensorError, ValueError)


@pytest.mark.parametrize("bit_generator", [np.random.PCG64, np.random.SFC64, np.random.MT19937])
def test_random_words_are_the_generators_integers(bit_generator):
    from ipbench.envs.sensors.depth_noise import _random_words

    a, b = np.random.Generator(bit_generator(7)), np.random.Generator(bit_generator(7))
    words = _random_words(a, 999)
    expected = b.integers(0, 2**64 - 1, size=999, dtype=np.uint64, endpoint=True)
    np.testing.assert_array_equal(words, expected)
    assert a.random() == b.random()  # and the stream goes on alike
