"""Head images at any size: the offscreen buffer follows, K scales with the image."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ipbench.envs  # noqa: F401  (registers the ids)
from ipbench.envs.exploration_scene import build_model, sample_scene
from ipbench.envs.sensors import SensorError, fit_offscreen, intrinsics
from ipbench.eval.cli_options import parse_size


def _fraction(K: np.ndarray, size: tuple[int, int], point_cam: np.ndarray) -> np.ndarray:
    """Where a camera-frame point lands, as a fraction of the image (pixel edges 0 and 1)."""
    uv = (K @ (point_cam / point_cam[2]))[:2]
    return (uv + 0.5) / np.array([size[1], size[0]])


@pytest.mark.parametrize(
    ("small", "big"), [((680, 1024), (1360, 2048)), ((1632, 2464), (3264, 4928))]
)
def test_k_scales_exactly_with_the_image(small, big):
    model = build_model(sample_scene("simple", 0))
    point = np.array([0.031, -0.017, 1.4])  # camera frame, m: inside the view
    fit_offscreen(model, big[1], big[0])
    Ks = [intrinsics(model, "head_left_camera", s[1], s[0]).K for s in (small, big)]
    f_small, f_big = (_fraction(K, s, point) for K, s in zip(Ks, (small, big), strict=True))
    np.testing.assert_allclose(f_big, f_small, rtol=0, atol=1e-6)
    np.testing.assert_allclose(Ks[1][:2, :2], 2 * Ks[0][:2, :2], rtol=1e-6)


def test_the_offscreen_buffer_is_raised_never_lowered():
    model = build_model(sample_scene("simple", 0))
    g = model.vis.global_
    before = (g.offwidth, g.offheight)
    fit_offscreen(model, 16, 16)
    assert (g.offwidth, g.offheight) == before
    fit_offscreen(model, 2464, 1632)
    assert (g.offwidth, g.offheight) == (max(2464, before[0]), max(1632, before[1]))
    with pytest.raises(SensorError, match="valid: width and height >= 1 px"):
        fit_offscreen(model, 0, 10)


def test_exploration_renders_beyond_the_scene_files_buffer():
    size = (1020, 1536)  # taller than the work cell's default 960-row buffer
    env = gym.make("ipbench/Exploration-v0", scene="simple", head_size=size)
    try:
        obs, info = env.reset(seed=0)
        assert obs["head_left"].shape == (*size, 3) and info["head_left_mask"].shape == size
        assert env.observation_space.contains(obs)
        # the same scene at the default size: the objects land at the same image fractions
        small = gym.make("ipbench/Exploration-v0", scene="simple")
        obs_s, info_s = small.reset(seed=0)
        small.close()
        ys, xs = np.nonzero(info["head_left_mask"] >= 0)
        ys_s, xs_s = np.nonzero(info_s["head_left_mask"] >= 0)
        assert abs(xs.mean() / size[1] - xs_s.mean() / 1024) < 0.005
        assert abs(ys.mean() / size[0] - ys_s.mean() / 680) < 0.005
    finally:
        env.close()


@pytest.mark.parametrize(("text", "size"), [("3264x4928", (3264, 4928)), ("680X1024", (680, 1024))])
def test_head_size_option_parses_height_by_width(text, size):
    assert parse_size(text) == size


@pytest.mark.parametrize("text", ["4928", "0x10", "axb", "10x10x3"])
def test_a_bad_head_size_option_says_how_to_write_it(text):
    with pytest.raises(SystemExit, match="give HEIGHTxWIDTH in pixels"):
        parse_size(text)
