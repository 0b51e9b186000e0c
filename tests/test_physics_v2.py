"""Sorting-v2's physics options (ipbench.envs.world.PhysicsConfig): objects at rest sleep, wake
when something acts on them, and v0/v1 keep the MJCF's physics untouched."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import ipbench.envs  # noqa: F401
from ipbench.envs.world import FAST_PHYSICS, PhysicsConfig

SLEEP = int(mujoco.mjtEnableBit.mjENBL_SLEEP)


def _env(env_id: str):
    env = gym.make(env_id, scene="cluttered", cameras=("wrist",))
    env.reset(seed=3)
    return env, env.unwrapped


def _object_trees(base) -> np.ndarray:
    return base.model.body_treeid[base.world.object_bodies]


@pytest.mark.parametrize("env_id", ["ipbench/Sorting-v0", "ipbench/Sorting-v1"])
def test_released_ids_keep_the_mjcf_physics(env_id):
    env, base = _env(env_id)
    try:
        assert base.config.physics == PhysicsConfig()
        assert not base.model.opt.enableflags & SLEEP
        for _ in range(200):
            mujoco.mj_step(base.model, base.data)
        assert base.data.ntree_awake == base.model.ntree  # nothing ever sleeps
    finally:
        env.close()


def test_v2_objects_at_rest_sleep_and_wake_when_pushed():
    env, base = _env("ipbench/Sorting-v2")
    model, data = base.model, base.data
    try:
        assert base.config.physics == FAST_PHYSICS and model.opt.enableflags & SLEEP
        assert model.opt.sleep_tolerance == pytest.approx(1e-3)  # MuJoCo's default
        for _ in range(500):  # 1 s with the robot holding still
            mujoco.mj_step(model, data)
        trees = _object_trees(base)
        asleep = data.tree_asleep[trees] >= 0
        assert asleep.mean() > 0.5, "most objects resting on the table should sleep"
        # the robot is actuated and never sleeps
        robot_tree = model.body_treeid[model.jnt_bodyid[model.actuator_trnid[0, 0]]]
        assert data.tree_asleep[robot_tree] < 0
        # a force on a sleeping object wakes it, and it moves as it would awake
        k = int(np.flatnonzero(asleep)[0])
        body = int(base.world.object_bodies[k])
        start = data.xpos[body].copy()
        data.xfrc_applied[body, :3] = [0.0, 0.0, 40.0 * model.body_subtreemass[body] * 9.81]
        for _ in range(50):
            mujoco.mj_step(model, data)
        assert data.tree_asleep[trees[k]] < 0
        assert data.xpos[body][2] > start[2] + 0.01
    finally:
        env.close()


def test_v2_physics_is_deterministic_with_sleeping():
    def run() -> np.ndarray:
        env, base = _env("ipbench/Sorting-v2")
        try:
            for _ in range(300):
                mujoco.mj_step(base.model, base.data)
            return base.data.qpos.copy()
        finally:
            env.close()

    np.testing.assert_array_equal(run(), run())
