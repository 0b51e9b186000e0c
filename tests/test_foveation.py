"""Foveated head cameras (envs/sensors/foveation.py), the working frame of ``look`` and
``ipbench/Exploration-v1``."""

from __future__ import annotations

import cv2
import gymnasium as gym
import numpy as np
import pytest

import ipbench.envs
from ipbench.assets.objects.object_model import ObjectModel
from ipbench.envs.exploration import EXPLORATION_V1
from ipbench.envs.exploration_scene import build_model, sample_scene
from ipbench.envs.sensors import SensorError, SensorRenderer
from ipbench.envs.sensors.cameras import fit_offscreen
from ipbench.envs.sensors.foveation import (
    fovea_to_periphery,
    fovea_window,
    foveate,
    scale_intrinsics,
)
from ipbench.perception.features2d import detect
from ipbench.policies.stereo_look import WORK_WIDTH, eye_features

K_FULL = np.array([[3650.0, 0.0, 2463.5], [0.0, 3650.0, 1631.5], [0.0, 0.0, 1.0]])
SIZE = (256, 384)  # a small head with a centred 1/4 fovea


def _project(K, p):  # noqa: N803
    return (K @ (p / p[2]))[:2]


def test_a_point_lands_where_each_image_sees_it():
    rng = np.random.default_rng(0)
    image = rng.integers(0, 256, (3264, 4928, 3), dtype=np.uint8)
    eye = foveate(image, K_FULL, 4)
    r0, c0, rows, cols = fovea_window(3264, 4928, 4)
    assert (r0, c0, rows, cols) == (1224, 1848, 816, 1232)
    assert eye.periphery.shape == eye.fovea.shape == (816, 1232, 3)
    for p in rng.uniform([-0.5, -0.3, 1.0], [0.5, 0.3, 2.0], (20, 3)):
        u = _project(K_FULL, p)
        np.testing.assert_allclose(_project(eye.periphery_K, p), (u + 0.5) / 4 - 0.5, atol=1e-9)
        np.testing.assert_allclose(_project(eye.fovea_K, p), u - [c0, r0], atol=1e-9)
        mapped = fovea_to_periphery(_project(eye.fovea_K, p)[None], eye.fovea_K, eye.periphery_K)
        np.testing.assert_allclose(mapped[0], _project(eye.periphery_K, p), atol=1e-9)


def test_fovea_is_the_full_image_window_and_periphery_its_block_means():
    rng = np.random.default_rng(1)
    image = rng.integers(0, 256, (64, 96, 3), dtype=np.uint8)
    eye = foveate(image, K_FULL, 4)
    np.testing.assert_array_equal(eye.fovea, image[24:40, 36:60])
    means = image.reshape(16, 4, 24, 4, 3).astype(float).mean(axis=(1, 3))
    assert np.abs(eye.periphery.astype(float) - means).max() <= 0.5 + 1e-9  # rounded means


def test_scaling_k_is_exact_and_bad_foveae_are_refused():
    K2 = scale_intrinsics(K_FULL, 0.5)  # noqa: N806
    np.testing.assert_allclose(K2[:2, :2], K_FULL[:2, :2] / 2)
    np.testing.assert_allclose(scale_intrinsics(K2, 2.0), K_FULL)
    for h, w, f in ((120, 180, 4), (100, 100, 3), (64, 96, 1)):
        with pytest.raises(SensorError, match="valid"):
            fovea_window(h, w, f)
    with pytest.raises(SensorError, match="factor 4"):
        gym.make("ipbench/Exploration-v1", head_size=(120, 180))


def test_the_working_frame_keeps_every_pixel_setting_at_its_angle():
    rng = np.random.default_rng(2)
    image = np.kron(rng.integers(0, 256, (85, 128)), np.ones((16, 16))).astype(np.uint8)
    K = scale_intrinsics(K_FULL, 2048 / 4928)  # noqa: N806
    obs = {"head_left": np.dstack([image] * 3), "head_left_K": K}  # 1360x2048
    features, K_work, size, scale = eye_features(obs, "left", "sift")  # noqa: N806
    raw = detect(obs["head_left"], "sift")
    assert size == (680, WORK_WIDTH) and scale == 0.5
    np.testing.assert_allclose(features.xy, (raw.xy + 0.5) * 0.5 - 0.5, atol=1e-4)
    np.testing.assert_allclose(features.size, raw.size * 0.5, rtol=1e-6)
    np.testing.assert_allclose(K_work, scale_intrinsics(K, 0.5))


def test_foveated_features_replace_the_periphery_inside_the_window():
    rng = np.random.default_rng(3)
    image = np.kron(rng.integers(0, 256, (102, 154)), np.ones((16, 16))).astype(np.uint8)
    full = np.dstack([image] * 3)[:1632, :2464]
    K = scale_intrinsics(K_FULL, 0.5)  # noqa: N806
    eye = foveate(full, K, 4)  # two 408x616 images
    obs = {
        "head_left": eye.periphery,
        "head_left_K": eye.periphery_K,
        "head_left_fovea": eye.fovea,
        "head_left_fovea_K": eye.fovea_K,
    }
    features, _, size, scale = eye_features(obs, "left", "sift")
    assert size == (678, WORK_WIDTH) and scale == pytest.approx(WORK_WIDTH / 616)
    periphery, fovea = detect(eye.periphery, "sift"), detect(eye.fovea, "sift")
    lo, hi = [230.5, 152.5], [384.5, 254.5]  # the fovea's window in periphery px (its edges)
    xy = (features.xy.astype(float) + 0.5) / scale - 0.5  # back to periphery px
    inside = np.all((xy >= lo) & (xy < hi), axis=1)
    kept = ~np.all((periphery.xy >= lo) & (periphery.xy < hi), axis=1)
    assert inside.sum() == len(fovea) > 50 and (~inside).sum() == kept.sum() > 50
    # a fovea keypoint's place in the periphery: its full-resolution pixel divided by 4
    expected = ((fovea.xy + [924, 612]) + 0.5) / 4 - 0.5
    np.testing.assert_allclose(np.sort(xy[inside], 0), np.sort(expected, 0), atol=1e-3)


def _make(fovea_factor: int, objects=EXPLORATION_V1["objects"]):
    return gym.make(
        "ipbench/Exploration-v1", scene="simple", head_size=SIZE, fovea_factor=fovea_factor,
        objects=objects,
    ).unwrapped  # fmt: skip


def test_a_foveated_observation_is_the_full_render_inside_and_downsampled_outside():
    full_env, fov_env = _make(1), _make(4)
    full, full_info = full_env.reset(seed=4)
    fov, fov_info = fov_env.reset(seed=4)
    full_env.close(), fov_env.close()
    assert fov_env.observation_space.contains(fov)
    r0, c0, rows, cols = fovea_window(*SIZE, 4)
    for side in ("left", "right"):
        image = full[f"head_{side}"]
        np.testing.assert_array_equal(
            fov[f"head_{side}_fovea"], image[r0 : r0 + rows, c0 : c0 + cols]
        )
        means = image.reshape(rows, 4, cols, 4, 3).astype(float).mean(axis=(1, 3))
        assert np.abs(fov[f"head_{side}"].astype(float) - means).max() <= 0.5 + 1e-9
        eye = foveate(image, full[f"head_{side}_K"], 4)
        np.testing.assert_allclose(fov[f"head_{side}_K"], eye.periphery_K)
        np.testing.assert_allclose(fov[f"head_{side}_fovea_K"], eye.fovea_K)
        mask = full_info[f"head_{side}_mask"]
        np.testing.assert_array_equal(fov_info[f"head_{side}_mask"], mask[2::4, 2::4])
        np.testing.assert_array_equal(
            fov_info[f"head_{side}_fovea_mask"], mask[r0 : r0 + rows, c0 : c0 + cols]
        )


def test_exploration_v1_looks_at_upright_prints_at_the_thesis_resolution():
    assert ipbench.envs.EXPLORATION_IDS["ipbench/Exploration-v1"] == EXPLORATION_V1
    assert EXPLORATION_V1["head_size"] == (3264, 4928)  # Nikon D5100, 4928x3264
    assert EXPLORATION_V1["objects"].upright_prints
    scene = sample_scene("simple", 0)
    released = build_model(scene)
    upright = build_model(scene, objects=ObjectModel(upright_prints=True))
    np.testing.assert_array_equal(released.tex_data, upright.tex_data)  # the same prints ...
    assert released.mesh_texcoord.shape == upright.mesh_texcoord.shape
    assert not np.array_equal(released.mesh_texcoord, upright.mesh_texcoord)  # ... turned


def test_one_sample_per_pixel_already_integrates_the_surfaces():
    """The fovea is one render sample per pixel; a sensor pixel integrates light over its area.
    Texture sampling is filtered over each pixel's footprint, so on surfaces the render equals
    its pixel-integrated (2x2 supersampled) version within a grey level; only outlines, where
    the sensor cameras leave out multisampling, differ."""
    env = gym.make("ipbench/Exploration-v1", scene="medium", head_size=(680, 1024)).unwrapped
    env.reset(seed=1)
    h, w = 680, 1024
    fit_offscreen(env.model, 2 * w, 2 * h)
    renderer = SensorRenderer(env.model)
    try:
        one = renderer.render_rgb(env.data, "head_left_camera", w, h).astype(float)
        four = renderer.render_rgb(env.data, "head_left_camera", 2 * w, 2 * h).astype(float)
        labels = renderer.render_segmentation(env.data, "head_left_camera", w, h)
    finally:
        renderer.close()
        env.close()
    integrated = four.reshape(h, 2, w, 2, 3).mean(axis=(1, 3))
    labels = labels.reshape(h, w, -1)[..., 0].astype(np.float32)
    block = np.ones((5, 5), np.uint8)
    surface = cv2.dilate(labels, block) == cv2.erode(labels, block)
    diff = np.abs(one - integrated).mean(axis=2)
    assert surface.mean() > 0.85
    assert diff[surface].mean() < 0.5
    assert diff[~surface].mean() > 2  # outlines alias: the comparison sees a difference
