"""Structured-light effects against published numbers (synthetic images and one MuJoCo render).

Numbers: Nguyen, Izadi & Lovell 2012 (axial sigma 1.9 mm at 1 m, 6.1 mm at 2 m); 1/8 px
disparity steps ``z^2 / (8 f b)`` (Khoshelham & Oude Elberink 2012); projector shadow
``f b (1 / z_fg - 1 / z_bg)`` px wide (geometry, BlenSor / render_kinect); unit error ranges of
the STRUCTURED_LIGHT preset (Boehm; depth_noise docstring).
"""

import dataclasses
import hashlib
import json
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from ipbench.envs.sensors import SensorRenderer, intrinsics
from ipbench.envs.sensors.depth_noise import (
    DEFAULT_CONFIG,
    SENSOR_EFFECTS,
    STRUCTURED_LIGHT,
    DepthNoiseConfig,
    DepthNoiseModel,
    SensorError,
    UnitError,
    without_effect,
)
from ipbench.envs.sensors.structured_light import projector_lit, projector_visible
from ipbench.eval.repro.digests import synthetic_depth_images

H, W, F, B = 480, 640, 570.0, 0.075
U = ((np.arange(W) - (W - 1) / 2) / F)[None, :]
V = ((np.arange(H) - (H - 1) / 2) / F)[:, None]
QUIET = dict(  # every per-pixel random effect off: geometry only
    axial_a=0.0, axial_b=0.0, axial_angle_k=0.0, lateral_sigma_px=0.0, lateral_angle_k_px=0.0,
    disparity_step_px=0.0, edge_dropout=0.0, grazing_angle_deg=90.0, specular_facing_deg=0.0,
    specular_dropout=0.0,
)  # fmt: skip


def plane(z: float) -> np.ndarray:
    return np.full((H, W), z, np.float32)


def preset(*off: str) -> DepthNoiseConfig:
    config = STRUCTURED_LIGHT
    for effect in off:
        config = without_effect(config, effect)
    return config


def matched(config=None, **changes) -> DepthNoiseModel:
    """Block matching without shadow, lateral noise or unit error (noise per ``changes``)."""
    config = config or preset("projector_shadow", "lateral_noise")
    return DepthNoiseModel(dataclasses.replace(config, **changes))


@pytest.mark.parametrize(("z", "nguyen_mm"), [(1.0, 1.9), (2.0, 6.1)])
def test_plane_sigma_matches_nguyen(z, nguyen_mm):
    model = DepthNoiseModel(preset("projector_shadow"))
    out = model.apply(plane(z), F, F, np.random.default_rng(1))
    valid = out[out > 0]
    assert valid.size > 0.99 * H * W  # a plane in range keeps (nearly) every pixel
    assert abs(valid.mean() - z) < 0.002 * z**2
    assert 1000 * valid.std() == pytest.approx(nguyen_mm, rel=0.2)


def test_depth_steps_are_one_eighth_pixel_of_disparity():
    b = math.radians(8)  # a slowly varying plane around 1 m
    z = np.broadcast_to((1.0 * math.cos(b) / (math.sin(b) * U + math.cos(b))), (H, W))
    out = matched().apply(z.astype(np.float32), F, F, np.random.default_rng(2))
    levels = np.unique(out[(out > 0.97) & (out < 1.03)])
    steps = np.diff(levels)
    expected = levels[1:] ** 2 / (8 * F * B)  # z^2 / (8 f b): 2.9 mm at 1 m
    np.testing.assert_allclose(steps, expected, rtol=0.01)
    assert len(levels) > 10


def shadow_scene(z_fg: float, z_bg: float) -> mujoco.MjModel:
    spec = mujoco.MjSpec()
    spec.visual.global_.offwidth, spec.visual.global_.offheight = W, H
    world = spec.worldbody
    world.add_light(pos=[0, 0, 1], dir=[0, 0, -1])
    world.add_camera(name="xtion", pos=[0, 0, 0], fovy=45.0)  # looks along world -z
    box = mujoco.mjtGeom.mjGEOM_BOX
    world.add_geom(type=box, size=[3, 3, 0.01], pos=[0, 0, -z_bg - 0.01])  # wall
    world.add_geom(type=box, size=[0.1, 0.12, 0.05], pos=[0, 0, -z_fg - 0.05])  # box
    return spec.compile()


@pytest.mark.parametrize(("z_fg", "z_bg"), [(1.0, 1.2), (0.6, 1.2), (0.8, 0.9)])
@pytest.mark.parametrize("method", ["shadow_map", "scanline"])
def test_shadow_width_matches_geometry(z_fg, z_bg, method):
    model = shadow_scene(z_fg, z_bg)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    noise = DepthNoiseModel(DepthNoiseConfig(projector_shadow=True, **QUIET))
    fx = intrinsics(model, "xtion", W, H).fx
    with SensorRenderer(model) as renderer:
        _, depth = renderer.render_rgbd(data, "xtion", W, H)
        proj = renderer.render_depth(data, "xtion", W, H, offset=noise.projector_offset)
    proj = proj if method == "shadow_map" else None  # scanline: from the camera's depth alone
    out = noise.apply(depth, fx, fx, np.random.default_rng(0), projector_depth=proj)
    shadow = (depth > 0) & (out == 0)
    rows = range(H // 2 - 50, H // 2 + 50)  # rows through the box (>= 0.12 m / 1.2 m * f)
    widths = shadow[rows].sum(axis=1)
    expected = fx * B * (1 / z_fg - 1 / z_bg)
    assert np.abs(widths - expected).max() <= 1.0
    cols = np.flatnonzero(shadow[H // 2])
    box_left = np.flatnonzero(np.abs(depth[H // 2] - z_fg) < 1e-3)[0]
    assert cols.max() == box_left - 1  # projector at +x: the shadow is left of the box
    box_rows = (np.abs(depth - z_fg) < 1e-3).any(axis=1)
    assert not shadow[~box_rows].any()  # above and below the box: lit


def bar_scene(width_px: int, z_fg: float = 1.0, z_bg: float = 1.2) -> np.ndarray:
    depth = plane(z_bg)
    depth[100:380, 300 : 300 + width_px] = z_fg
    return depth


def test_thin_parts_vanish_wide_surfaces_survive():
    model = matched()
    for seed in range(3):
        thin = model.apply(bar_scene(3), F, F, np.random.default_rng(seed))
        assert ((thin > 0) & (thin < 1.1)).sum() < 0.05 * 3 * 280  # the bar is (nearly) gone
        assert (thin[100:380, 280:320] > 1.1).mean() > 0.5  # background around it remains
        wide = model.apply(bar_scene(40), F, F, np.random.default_rng(seed))
        fg = (wide > 0) & (wide < 1.1)
        assert fg[100:380, 304:336].mean() > 0.99  # its inside survives
        assert fg.sum() > 0.9 * 40 * 280


def test_edges_fatten_towards_the_near_surface_and_round():
    # A bright near square (0.6 m) on a far wall (1.2 m): dots 4x brighter, so windows where the
    # square holds >= 2/3 of the dot energy take its disparity: the edges grow by 1-2 px.
    depth = plane(1.2)
    depth[150:330, 200:440] = 0.6
    out = matched().apply(depth, F, F, np.random.default_rng(3))
    fg = (out > 0) & (out < 0.9)
    rows = slice(200, 280)  # the square spans columns 200-439 and rows 150-329
    assert fg[rows, 199].mean() > 0.9 and fg[rows, 440].mean() > 0.9  # 1 px fatter
    assert fg[rows, 198].mean() > 0.3 and fg[rows, 441].mean() > 0.3  # partly 2 px
    assert fg[rows, 197].mean() < 0.2 and not fg[rows, :196].any() and not fg[rows, 443:].any()
    assert (out[rows, 193:199] == 0).any(axis=1).mean() > 0.9  # then a band of holes
    assert fg[149, 220] and fg[200, 199]  # both edges grow, but not the corner: it rounds
    assert not fg[149, 199] and not fg[148, 198]


def test_unit_error_drawn_once_in_cited_ranges():
    model = DepthNoiseModel(STRUCTURED_LIGHT)
    units = [model.draw_unit(np.random.default_rng(s)) for s in range(300)]
    scales = np.array([u.depth_scale for u in units])
    offsets = np.array([u.depth_offset_m for u in units])
    shifts = np.array([u.shift_px for u in units])
    assert np.abs(scales).max() <= 0.01 and np.abs(scales).max() > 0.009
    assert np.abs(offsets).max() <= 0.01 and np.abs(offsets).max() > 0.009
    assert set(shifts.ravel()) == {-2, -1, 0, 1, 2}
    assert model.draw_unit(np.random.default_rng(7)) == model.draw_unit(np.random.default_rng(7))
    assert DepthNoiseModel(DEFAULT_CONFIG).draw_unit(np.random.default_rng(0)) is None  # no unit
    # Constant within an episode: every frame gets the same scale, offset and shift.
    quiet = DepthNoiseModel(DepthNoiseConfig(**QUIET))
    unit = UnitError(depth_scale=0.01, depth_offset_m=-0.005, shift_px=(2, -1))
    depth = plane(1.0)
    depth[200:260, 300:340] = 0.8
    rng = np.random.default_rng(0)
    frames = [quiet.apply(depth, F, F, rng, unit=unit) for _ in range(3)]
    for out in frames:
        np.testing.assert_array_equal(out, frames[0])
    ref = quiet.apply(depth, F, F, rng)
    expected = np.zeros_like(ref)
    expected[:-1, 2:] = ref[1:, :-2] * np.float32(1.01) - np.float32(0.005)  # 2 right, 1 up
    np.testing.assert_allclose(frames[0], expected, atol=1e-6)
    fg = np.argwhere((frames[0] > 0) & (frames[0] < 0.9))
    assert fg.min(axis=0).tolist() == [199, 302]  # the RGB-aligned box moved by (dx, dy)


def test_each_effect_switches_off():
    assert len(set(SENSOR_EFFECTS)) == len(SENSOR_EFFECTS) >= 8
    depth = bar_scene(40)
    b = math.radians(70)  # bottom rows: a steep floor, incidence up to ~95 deg
    floor = 1.0 * math.cos(b) / (math.sin(b) * U + math.cos(b)) * np.ones((80, 1))
    depth[400:] = np.where(floor > 0, floor, 0)
    specular = np.zeros((H, W), bool)
    specular[50:90, 50:300] = True
    proj = depth.copy()
    proj[100:380, 300 - 6 : 340 - 6] = 1.0  # the box seen from the projector (~6 px left)
    unit_rng = np.random.default_rng(11)
    full = DepthNoiseModel(STRUCTURED_LIGHT)
    unit = full.draw_unit(unit_rng)
    kwargs = dict(projector_depth=proj, unit=unit)
    ref = full.apply(depth, F, F, np.random.default_rng(5), specular, **kwargs)
    for effect in SENSOR_EFFECTS:
        config = without_effect(STRUCTURED_LIGHT, effect)
        assert config != STRUCTURED_LIGHT
        model = DepthNoiseModel(config)
        u = model.draw_unit(np.random.default_rng(11))
        kwargs = dict(projector_depth=proj, unit=u)
        out = model.apply(depth, F, F, np.random.default_rng(5), specular, **kwargs)
        assert not np.array_equal(out, ref), effect
    with pytest.raises(SensorError, match="projector_shadow.*registration"):
        without_effect(STRUCTURED_LIGHT, "speckle")


def test_defaults_have_no_structured_light_effect():
    c = DepthNoiseConfig()
    assert not (c.projector_shadow or c.block_matching)
    assert c.unit_scale_max == c.unit_offset_max_m == c.unit_shift_max_px == 0


def test_deterministic_for_a_seed():
    model = DepthNoiseModel(STRUCTURED_LIGHT)
    depth = bar_scene(40)
    unit = model.draw_unit(np.random.default_rng(0))
    a, b, c = (
        model.apply(depth, F, F, np.random.default_rng(s), projector_depth=depth, unit=unit)
        for s in (4, 4, 5)
    )
    np.testing.assert_array_equal(a, b)
    assert (a != c).mean() > 0.3


def v1_images() -> dict:
    """The synthetic images whose v1 output digests are stored (recorded before this module);
    ``ipbench check`` digests the same ones."""
    return synthetic_depth_images()


def test_v1_default_output_unchanged():
    stored = json.loads((Path(__file__).parent / "data/depth_noise_v1_digests.json").read_text())
    model = DepthNoiseModel(DepthNoiseConfig())
    for name, (depth, spec) in v1_images().items():
        rng = np.random.default_rng(12345)
        a = model.apply(depth, F, F, rng, spec)
        b = model.apply(depth, F, F, rng, spec)  # a second frame from the same stream
        assert hashlib.sha256(a.tobytes() + b.tobytes()).hexdigest() == stored[name], name


V2_DIGEST_CONFIGS = {
    "all": STRUCTURED_LIGHT,
    **{f"no_{e}": without_effect(STRUCTURED_LIGHT, e) for e in SENSOR_EFFECTS},
    "side_-1": dataclasses.replace(STRUCTURED_LIGHT, projector_side=-1),
}


@pytest.mark.parametrize("config_name", list(V2_DIGEST_CONFIGS))
def test_v2_sensor_output_matches_recorded_digests(config_name):
    """Sorting-v2's sensor (and each effect off) gives the output recorded in
    ``data/depth_noise_v2_digests.json``. Sorting-v2 is released, so this output is frozen: a
    change of the sensor's output belongs to a new env version."""
    stored = json.loads((Path(__file__).parent / "data/depth_noise_v2_digests.json").read_text())
    model = DepthNoiseModel(V2_DIGEST_CONFIGS[config_name])
    for name, (depth, spec) in v1_images().items():
        rng = np.random.default_rng(12345)
        unit = model.draw_unit(rng)
        a = model.apply(depth, F, F, rng, spec, unit=unit)
        b = model.apply(depth, F, F, rng, spec, unit=unit)  # a second frame, same stream
        digest = hashlib.sha256(a.tobytes() + b.tobytes()).hexdigest()
        assert digest == stored[f"{config_name}/{name}"], name


def test_bad_inputs_list_valid_options():
    model = DepthNoiseModel(STRUCTURED_LIGHT)
    rng = np.random.default_rng(0)
    with pytest.raises(SensorError, match="projector_depth must be .* or None"):
        model.apply(plane(1.0), F, F, rng, projector_depth=np.ones((3, 3), np.float32))
    with pytest.raises(SensorError, match="UnitError"):
        model.apply(plane(1.0), F, F, rng, projector_depth=plane(1.0), unit=(0.01, 0.0))
    with pytest.raises(SensorError, match="valid: -1, 1"):
        DepthNoiseConfig(projector_side=0)
    with pytest.raises(SensorError, match="valid: odd"):
        DepthNoiseConfig(bm_window_px=8)
    with pytest.raises(SensorError, match=r"\[0.5, 1\]"):
        DepthNoiseConfig(bm_match_fraction=0.2)


def test_scanline_shadow_agrees_with_the_shadow_map_on_a_cluttered_scene():
    import gymnasium as gym

    import ipbench.envs  # noqa: F401
    from ipbench.envs.sorting import WRIST_CAMERA

    env = gym.make("ipbench/SortingCluttered-v2")
    try:
        env.reset(seed=0)
        base = env.unwrapped
        renderer, data = base.renderer, base.data
        fx = intrinsics(base.model, WRIST_CAMERA, W, H).fx
        _, depth = renderer.render_rgbd(data, WRIST_CAMERA, W, H)
        offset = base.depth_noise.projector_offset
        proj = renderer.render_depth(data, WRIST_CAMERA, W, H, offset=offset)
    finally:
        env.close()
    mapped = projector_lit(depth, proj, fx, offset[0], 0.01)
    scanned = projector_visible(depth, fx, offset[0])
    valid = depth > 0
    assert 0.01 < (~mapped & valid).mean() < 0.2  # the scene casts shadows
    assert (mapped == scanned)[valid].mean() > 0.99
    # a projector on the other side: the mirror image of this one
    mirrored = projector_visible(np.ascontiguousarray(depth[:, ::-1]), fx, -offset[0])[:, ::-1]
    np.testing.assert_array_equal(mirrored, scanned)


def _running_min_reference(depth: np.ndarray, fx: float, b: float, tol: float = 0.05):
    """The scan-line test written as its definition: x(u) < min over u' > u of x(u') - tol."""
    x = np.arange(depth.shape[1], dtype=np.float32) - np.where(
        depth > 0, np.float32(fx * b) / np.where(depth > 0, depth, 1), 0
    ).astype(np.float32)
    ahead = np.minimum.accumulate(x[:, ::-1], axis=1)[:, ::-1] - np.float32(tol)
    lit = np.ones(depth.shape, bool)
    lit[:, :-1] = x[:, :-1] < ahead[:, 1:]
    return lit


@pytest.mark.parametrize("width", [1, 2, 7, 64, 640, 641])
def test_scanline_shadow_equals_its_running_minimum_definition(width):
    rng = np.random.default_rng(width)
    depth = rng.uniform(0.45, 3.0, (12, width)).astype(np.float32)
    depth[rng.random(depth.shape) < 0.2] = 0.0  # holes
    for _ in range(4):  # near boxes that cast shadows
        a = int(rng.integers(0, width))
        depth[:, a : a + int(rng.integers(1, 60))] = rng.uniform(0.45, 0.9)
    lit = projector_visible(depth, F, B)
    np.testing.assert_array_equal(lit, _running_min_reference(depth, F, B))
    if width > 10:
        assert 0 < (~lit).mean() < 1
