"""Observation modes (``cameras=``): a camera not asked for is not rendered and is absent from
the observation and its space; everything else is what the default gives."""

from __future__ import annotations

from collections import Counter

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from small_models import small_models

import ipbench.envs
from ipbench.envs.sensors import SensorRenderer
from ipbench.envs.sorting import CAMERAS, COMMANDS, WRIST_CAMERA, SortingConfig
from ipbench.policies import EVAL_CAMERAS, INTERACTIVE, POLICIES, PolicyModels, make_policy
from ipbench.policies.scripted import GroundTruthSorter

HEAD_KEYS = {f"head_{side}{suffix}" for side in ("left", "right") for suffix in ("", "_K", "_pose")}
WRIST_KEYS = {"wrist_rgb", "wrist_depth", "wrist_K", "wrist_pose"}
ENV_ID, SCENE, SEED = "ipbench/Sorting-v2", "cluttered", 0


@pytest.fixture
def rendered(monkeypatch) -> Counter:
    """Camera name -> how many images the sensor renderer made of it (any kind)."""
    counts: Counter = Counter()
    for method in ("render_rgb", "render_rgbd", "render_segmentation", "render_depth"):
        original = getattr(SensorRenderer, method)

        def counting(self, data, camera, *args, _original=original, **kwargs):
            counts[camera] += 1
            return _original(self, data, camera, *args, **kwargs)

        monkeypatch.setattr(SensorRenderer, method, counting)
    return counts


def _episode(cameras=None) -> tuple[list[tuple[dict, dict]], dict, gym.spaces.Dict]:
    """(obs, info) after reset and after one ground-truth step, the env's random state after,
    and the observation space."""
    kwargs = {} if cameras is None else {"cameras": cameras}
    env = gym.make(ENV_ID, scene=SCENE, **kwargs)
    try:
        obs, info = env.reset(seed=SEED)
        steps = [(obs, info)]
        if "wrist_rgb" in obs:
            obs, _, _, _, info = env.step(GroundTruthSorter().act(obs, info))
            steps.append((obs, info))
        state = env.unwrapped.np_random.bit_generator.state
        return steps, state, env.observation_space
    finally:
        env.close()


def _assert_same_values(mode: dict, default: dict) -> None:
    for key, value in mode.items():
        np.testing.assert_array_equal(value, default[key], err_msg=key)


@pytest.fixture(scope="module")
def default_episode():
    return _episode()


def test_default_is_both_cameras_and_renders_the_head(rendered):
    assert SortingConfig().cameras == CAMERAS == ("wrist", "head")
    steps, _, space = _episode()
    assert HEAD_KEYS | WRIST_KEYS | {"qpos"} == set(space.spaces)
    assert all(set(obs) == set(space.spaces) for obs, _ in steps)
    assert rendered["head_left_camera"] == rendered["head_right_camera"] == len(steps)


def test_wrist_only_renders_no_head_and_keeps_every_other_value(rendered, default_episode):
    rendered.clear()
    steps, state, space = _episode(("wrist",))
    assert set(space.spaces) == WRIST_KEYS | {"qpos"}
    assert not any(c.startswith("head_") for c in rendered), rendered
    assert rendered[WRIST_CAMERA] > 0
    want_steps, want_state, _ = default_episode
    assert len(steps) == len(want_steps) == 2
    for (obs, info), (want_obs, want_info) in zip(steps, want_steps, strict=True):
        assert space.contains(obs) and set(obs) == set(space.spaces)
        _assert_same_values(obs, want_obs)
        np.testing.assert_array_equal(info["wrist_mask"], want_info["wrist_mask"])
        assert [o["status"] for o in info["objects"].values()] == [
            o["status"] for o in want_info["objects"].values()
        ]
    assert state == want_state  # the same random stream: later episodes agree too


def test_head_only_renders_no_wrist(rendered, default_episode):
    rendered.clear()
    steps, _, space = _episode(["head"])  # a list is taken as a tuple
    assert set(space.spaces) == HEAD_KEYS | {"qpos"}
    assert WRIST_CAMERA not in rendered and rendered["head_left_camera"] == 1
    (obs, info), (want_obs, _) = steps[0], default_episode[0][0]
    assert space.contains(obs) and "wrist_mask" not in info
    _assert_same_values(obs, want_obs)


@pytest.mark.parametrize(
    ("cameras", "message"),
    [
        ("wrist", "must be a tuple of camera names, got 'wrist'"),
        ((), "no camera"),
        (("wrist", "wrist"), "named twice"),
        (("wrist", "stereo"), r"unknown camera\(s\) \['stereo'\]"),
        (None, "must be a tuple"),
    ],
)
def test_bad_cameras_are_clear_errors_listing_the_valid_ones(cameras, message):
    for make in (
        lambda: gym.make(ENV_ID, cameras=cameras),
        lambda: ipbench.envs.env_config(ENV_ID, cameras=cameras),
    ):
        with pytest.raises(ValueError, match=message) as error:
            make()
        assert "valid: a non-empty tuple of 'wrist', 'head'" in str(error.value)


def test_env_config_takes_cameras_in_their_canonical_order():
    assert ipbench.envs.env_config(ENV_ID, cameras=("wrist",)).cameras == ("wrist",)
    assert ipbench.envs.env_config(ENV_ID, cameras=["head", "wrist"]) == SortingConfig(
        **ipbench.envs.ENV_IDS[ENV_ID]
    )


def test_check_env_passes_without_the_head():
    env = gym.make(ENV_ID, render_mode="rgb_array", cameras=("wrist",))
    try:
        check_env(env.unwrapped, skip_render_check=False)
    finally:
        env.close()


@pytest.fixture(scope="module")
def models() -> PolicyModels:
    """A small real model from the segments of a few wrist views (as the evaluation's tests),
    with thresholds no view reaches: the interactive policies inspect in hand."""
    return small_models((500, 501), 16, 1.0, cameras=EVAL_CAMERAS)


def test_every_policy_acts_on_the_evaluation_cameras_alone(models):
    assert EVAL_CAMERAS == ("wrist",)
    env = gym.make("ipbench/Sorting-v1", scene="uncluttered", cameras=EVAL_CAMERAS)
    try:
        for name in [p if p != "random-inspect" else "random-inspect@0.5" for p in POLICIES]:
            policy = make_policy(name, models)
            policy.reset(1)
            obs, info = env.reset(seed=1)
            assert not HEAD_KEYS & set(obs)
            action = policy.act(obs, info)  # the scene view
            if name in INTERACTIVE:  # nothing reaches the threshold: inspect it
                inspection = INTERACTIVE[name][1]
                assert COMMANDS[action["command"]] == f"inspect_in_{inspection}", name
            obs, _, _, _, info = env.step(action)
            policy.act(obs, info)  # the interactive ones: the inspection view
            assert policy.decisions, name
    finally:
        env.close()
