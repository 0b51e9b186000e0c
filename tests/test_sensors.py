"""Rendering, intrinsics and poses of the camera sensors, on a toy model (EGL: conftest)."""

import cv2
import mujoco
import numpy as np
import pytest

from ipbench.envs.sensors import (
    RgbdCamera,
    SensorError,
    SensorRenderer,
    camera_pose,
    intrinsics,
    specular_geoms,
)
from ipbench.envs.sensors.depth_noise import DepthNoiseConfig, DepthNoiseModel


def look_at(pos, target):
    """MuJoCo camera xyaxes looking from pos at target, world z up."""
    f = np.subtract(target, pos) / np.linalg.norm(np.subtract(target, pos))
    x = np.cross(f, [0, 0, 1])
    x /= np.linalg.norm(x)
    return " ".join(f"{a:.9f}" for a in (*x, *np.cross(x, f)))


OBLIQUE = (0.7, -0.5, 0.9)
XML = f"""
<mujoco>
  <visual><quality shadowsize="0" offsamples="0"/><global offwidth="1280" offheight="960"/>
  </visual>
  <asset>
    <texture type="skybox" builtin="gradient" rgb1=".4 .6 .8" rgb2="0 0 0" width="32"
             height="32"/>
    <material name="glaze" specular="0.9" shininess="0.8" rgba=".9 .9 .85 1"/>
    <material name="matte" specular="0.1" rgba=".2 .5 .2 1"/>
  </asset>
  <worldbody>
    <light pos="0 0 3"/>
    <camera name="down" pos="0 0 1" fovy="45"/>
    <camera name="pp" pos="0 0 1" focalpixel="500 520" principalpixel="30 -20"
            sensorsize="0.0064 0.0048" resolution="640 480"/>
    <camera name="oblique" pos="{" ".join(map(str, OBLIQUE))}"
            xyaxes="{look_at(OBLIQUE, (0, 0, 0))}" fovy="60"/>
    <camera name="up" pos="0 0 1" xyaxes="1 0 0 0 -1 0"/>
    <camera name="ortho" pos="0 0 1" projection="orthographic" fovy="1"/>
    <geom name="floor" type="box" size="5 5 0.01" pos="0 0 -0.01" rgba=".6 .5 .4 1"/>
    <geom name="on_axis" type="sphere" size="0.03" pos="0 0 0.5" rgba="1 0 0 1"/>
    <geom name="ball" type="sphere" size="0.02" pos="0.12 -0.08 0.3" rgba="0 0 1 1"/>
    <geom name="plate" type="box" size="0.06 0.06 0.005" pos="-0.15 -0.12 0.3"
          material="glaze"/>
    <geom name="mug" type="box" size="0.05 0.05 0.005" pos="0.15 0.12 0.3" material="matte"/>
    <geom name="collision" type="box" size="0.06 0.06 0.06" pos="-0.15 0.12 0.4" group="3"/>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def model():
    return mujoco.MjModel.from_xml_string(XML)


@pytest.fixture(scope="module")
def data(model):
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    return data


@pytest.fixture(scope="module")
def renderer(model):
    with SensorRenderer(model) as renderer:
        yield renderer


def gid(model, name):
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)


def project(model, data, camera, width, height, point):
    k = intrinsics(model, camera, width, height)
    x = np.linalg.inv(camera_pose(model, data, camera)) @ np.append(point, 1.0)
    assert x[2] > 0  # in front of the camera (OpenCV: +z forward)
    uv = k.K @ x[:3]
    return uv[:2] / uv[2]


@pytest.mark.parametrize("size", [(640, 480), (320, 240)])
def test_depth_of_a_plane_is_its_distance(model, data, renderer, size):
    rgb, depth = renderer.render_rgbd(data, "down", *size)
    floor = renderer.render_segmentation(data, "down", *size) == gid(model, "floor")
    assert floor.mean() > 0.8
    assert depth.dtype == np.float32 and depth.shape == size[::-1]
    assert np.abs(depth[floor] - 1.0).max() < 1e-3  # z-depth: constant over the image


def test_nothing_hit_is_zero(model, data, renderer):
    rgb, depth = renderer.render_rgbd(data, "up", 320, 240)  # sees only the skybox
    assert (depth == 0).all()
    assert rgb.std() > 1  # the skybox gradient is rendered
    assert (renderer.render_segmentation(data, "up", 320, 240) == -1).all()


def test_horizon_background_is_zero():
    """Skybox and haze over an infinite floor: no depth where no geom is seen."""
    model = mujoco.MjModel.from_xml_string(
        XML.replace(
            'type="box" size="5 5 0.01" pos="0 0 -0.01"', 'type="plane" size="0 0 1"'
        ).replace(
            '<camera name="up"', '<camera name="level" pos="0 0 0.5" xyaxes="1 0 0 0 0 1"/><camera'
        )
    )
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    with SensorRenderer(model) as renderer:
        _, depth = renderer.render_rgbd(data, "level", 320, 240)
        seg = renderer.render_segmentation(data, "level", 320, 240)
    sky, floor = seg == -1, seg == gid(model, "floor")
    assert sky.mean() > 0.3 and floor.mean() > 0.3
    assert (depth[sky] == 0).all()
    assert (depth[-20:][floor[-20:]] > 0).all()  # the near floor, at the bottom


@pytest.mark.parametrize("camera", ["down", "pp", "oblique"])
@pytest.mark.parametrize("size", [(640, 480), (400, 300)])
def test_sphere_projects_onto_k_and_pose(model, data, renderer, camera, size):
    seg = renderer.render_segmentation(data, camera, *size)
    for name in ("on_axis", "ball"):
        rows, cols = np.nonzero(seg == gid(model, name))
        assert rows.size > 50, name
        expected = project(model, data, camera, *size, data.geom_xpos[gid(model, name)])
        np.testing.assert_allclose([cols.mean(), rows.mean()], expected, atol=1.0)
    if camera != "oblique":  # on the optical axis: exactly the principal point
        k = intrinsics(model, camera, *size)
        rows, cols = np.nonzero(seg == gid(model, "on_axis"))
        np.testing.assert_allclose([cols.mean(), rows.mean()], [k.cx, k.cy], atol=0.1)


def test_intrinsics_values(model):
    k = intrinsics(model, "down", 640, 480)
    f = 240 / np.tan(np.radians(45 / 2))
    np.testing.assert_allclose([k.fx, k.fy, k.cx, k.cy], [f, f, 319.5, 239.5], rtol=1e-6)
    np.testing.assert_allclose(k.K, [[f, 0, 319.5], [0, f, 239.5], [0, 0, 1]], rtol=1e-6)
    k = intrinsics(model, "pp", 640, 480)  # focalpixel / principalpixel at its resolution
    np.testing.assert_allclose([k.fx, k.fy], [500, 520], rtol=1e-5)
    with pytest.raises(SensorError, match="orthographic"):
        intrinsics(model, "ortho", 640, 480)


def test_backprojection_recovers_the_floor(model, data, renderer):
    width, height = 640, 480
    _, depth = renderer.render_rgbd(data, "oblique", width, height)
    floor = renderer.render_segmentation(data, "oblique", width, height) == gid(model, "floor")
    k = intrinsics(model, "oblique", width, height)
    v, u = np.nonzero(floor)
    z = depth[v, u].astype(np.float64)
    cam = np.stack([(u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z, np.ones_like(z)])
    world = camera_pose(model, data, "oblique") @ cam
    assert np.ptp(z) > 0.5  # an oblique view: depth varies a lot
    assert np.abs(world[2]).max() < 2e-3  # yet every floor pixel lands on z = 0


def test_rgb(model, data, renderer):
    rgb = renderer.render_rgb(data, "down", 640, 480)
    assert rgb.shape == (480, 640, 3) and rgb.dtype == np.uint8
    assert rgb.std() > 5
    ball = renderer.render_segmentation(data, "down", 640, 480) == gid(model, "on_axis")
    red = rgb[ball].astype(int).mean(axis=0)
    assert red[0] > 2 * red[1] and red[0] > 2 * red[2]
    np.testing.assert_array_equal(rgb, renderer.render_rgbd(data, "down", 640, 480)[0])


def test_segmentation_ids(model, data, renderer):
    seg = renderer.render_segmentation(data, "down", 640, 480)
    assert seg.dtype == np.int32 and seg.shape == (480, 640)
    expected = {gid(model, n) for n in ("floor", "on_axis", "ball", "plate", "mug")}
    assert set(np.unique(seg)) == expected  # no collision geom (group 3), no background
    # The hidden collision box does not occlude the floor in depth either.
    _, depth = renderer.render_rgbd(data, "down", 640, 480)
    cu, cv = project(model, data, "down", 640, 480, [-0.15, 0.12, 0.4])
    assert depth[round(cv), round(cu)] == pytest.approx(1.0, abs=1e-3)


def test_errors(model, data, renderer):
    with pytest.raises(SensorError, match="'down'.*'oblique'"):
        renderer.render_rgb(data, "nope", 64, 48)
    with pytest.raises(SensorError, match="unknown camera"):
        renderer.render_rgbd(data, model.ncam, 64, 48)
    with pytest.raises(SensorError, match="offwidth"):
        renderer.render_rgbd(data, "down", 1281, 480)
    with pytest.raises(SensorError, match="offheight"):
        intrinsics(model, "down", 640, 961)
    with pytest.raises(ValueError):  # SensorError is a ValueError
        camera_pose(model, data, "nope")


def test_close_is_idempotent(model, data):
    renderer = SensorRenderer(model)
    renderer.render_rgb(data, "down", 32, 24)
    renderer.close()
    renderer.close()
    with pytest.raises(SensorError, match="closed"):
        renderer.render_rgb(data, "down", 32, 24)


def test_rgbd_camera(model, data, renderer):
    camera = RgbdCamera(renderer, "down", 640, 480)
    np.testing.assert_array_equal(camera.pose(data), camera_pose(model, data, "down"))
    assert camera.intrinsics == intrinsics(model, "down", 640, 480)
    assert camera.needs_segmentation  # the model has a glazed (specular) plate
    rgb, depth = camera.capture(data, np.random.default_rng(0))
    assert rgb.shape == (480, 640, 3) and depth.shape == (480, 640)
    seg = renderer.render_segmentation(data, "down", 640, 480)
    plate = _eroded(seg == gid(model, "plate"))  # away from edges (and lateral noise)
    floor = _eroded(seg == gid(model, "floor"))
    assert (depth[plate] == 0).mean() > 0.95  # the glaze faces the camera: no depth
    assert (depth[floor] > 0).all()
    assert abs(depth[floor].mean() - 1.0) < 2e-3 and depth[floor].std() > 5e-4
    np.testing.assert_array_equal(
        camera.capture(data, np.random.default_rng(0))[1], depth
    )  # seeded


def test_rgbd_camera_skips_segmentation_without_specular(model, data, renderer, monkeypatch):
    def fail(*args):
        raise AssertionError("segmentation rendered")

    monkeypatch.setattr(renderer, "render_segmentation", fail)
    cameras = [
        RgbdCamera(renderer, "down", 320, 240, specular=np.zeros(model.ngeom, bool)),
        RgbdCamera(renderer, "down", 320, 240, DepthNoiseModel(DepthNoiseConfig(enabled=False))),
    ]
    for camera in cameras:
        assert not camera.needs_segmentation
        camera.capture(data, np.random.default_rng(0))
    ideal = renderer.render_rgbd(data, "down", 320, 240)[1]
    np.testing.assert_array_equal(cameras[1].capture(data, np.random.default_rng(0))[1], ideal)


def test_specular_geoms(model):
    expected = np.zeros(model.ngeom, bool)
    expected[gid(model, "plate")] = True  # "mug" has a matte material, the rest none
    np.testing.assert_array_equal(specular_geoms(model), expected)


def _eroded(mask: np.ndarray, r: int = 4) -> np.ndarray:
    """Pixels of ``mask`` at least ``r`` px (Chebyshev) from its border."""
    return cv2.erode(mask.astype(np.uint8), np.ones((2 * r + 1, 2 * r + 1), np.uint8)) > 0


def test_render_depth_from_an_offset_pose(model, data, renderer):
    _, depth = renderer.render_rgbd(data, "down", 320, 240)
    np.testing.assert_array_equal(renderer.render_depth(data, "down", 320, 240), depth)
    # 7.5 cm along the camera's x axis = world +x for "down": the on-axis sphere (0.5 m deep)
    # (centre 0.5 m deep) moves f b / z px to the left in the image.
    k = intrinsics(model, "down", 320, 240)
    moved = renderer.render_depth(data, "down", 320, 240, offset=(0.075, 0.0, 0.0))
    rows = np.flatnonzero((depth < 0.6).any(axis=1))
    centre = lambda img: np.flatnonzero(img[rows[len(rows) // 2]] < 0.6).mean()  # noqa: E731
    assert centre(depth) - centre(moved) == pytest.approx(k.fx * 0.075 / 0.5, abs=1.0)
    np.testing.assert_allclose(moved[moved > 0.9], 1.0, atol=1e-3)  # same orientation
    closer = renderer.render_depth(data, "down", 320, 240, offset=(0.0, 0.0, 0.1))
    floor = (depth > 0.99) & (closer > 0.85)  # the floor, seen from both poses
    assert floor.sum() > 0.9 * (depth > 0.99).sum()
    np.testing.assert_allclose(closer[floor], depth[floor] - 0.1, atol=1e-3)
    rgb_after, depth_after = renderer.render_rgbd(data, "down", 320, 240)  # no lasting effect
    np.testing.assert_array_equal(depth_after, depth)
    with pytest.raises(SensorError, match="offset"):
        renderer.render_depth(data, "down", 320, 240, offset=(0.1, 0.0))
