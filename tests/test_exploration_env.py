"""``ipbench/Exploration-v0``: scenes (envs/exploration_scene.py) and the environment."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import ipbench.envs
from ipbench.assets.objects.geometry import object_geometry
from ipbench.envs.exploration import GAZE_JOINTS, ExplorationEnv
from ipbench.envs.exploration_scene import (
    BACK_STRIP,
    DATABASE_CLASSES,
    FRONT_AREA,
    LEVELS,
    SceneError,
    aim_head,
    database_instance,
    sample_scene,
)
from ipbench.envs.ptu import STEP_RAD
from ipbench.envs.sorting import InvalidActionError, ResetNeededError

ID = "ipbench/Exploration-v0"
ID_V1 = "ipbench/Exploration-v1"
SMALL = (128, 192)  # a centred fovea at every id's factor (1, 4)


# -- scenes ---------------------------------------------------------------------------------
def test_database_has_distinct_textured_classes():
    assert len(DATABASE_CLASSES) >= 9 and len(set(DATABASE_CLASSES)) == len(DATABASE_CLASSES)
    prints = []
    for label in DATABASE_CLASSES:
        inst = database_instance(label)
        assert inst.catalog == "v2" and inst.category in (
            "juice_bottle",
            "milk_carton",
            "juice_box",
        )
        tex = [p.texture for p in object_geometry(inst).visual if p.texture is not None]
        assert tex, label
        prints.append(tex[0].astype(float))
    for i in range(len(prints)):
        for j in range(i):
            a, b = prints[i], prints[j]
            if a.shape == b.shape:  # differ by far more than noise: another print
                assert np.abs(a - b).mean() > 20, (DATABASE_CLASSES[i], DATABASE_CLASSES[j])


def _check_scene(level, seed):
    scene = sample_scene(level, seed)
    cfg = LEVELS[level]
    roles = [o.role for o in scene.objects]
    assert roles.count("database") == cfg.n_classes + cfg.n_duplicates
    assert roles.count("distractor") == cfg.n_distractors
    assert roles.count("background") == cfg.n_background
    labels = [o.label for o in scene.objects if o.role == "database"]
    assert max(labels.count(c) for c in set(labels)) >= 2  # a class present twice or more
    assert all(o.label is None for o in scene.objects if o.role != "database")
    assert all(
        o.instance.name not in {database_instance(c).name for c in DATABASE_CLASSES}
        for o in scene.objects
        if o.role != "database"
    )
    for o in scene.objects:
        (x0, x1), (y0, y1) = FRONT_AREA if o.role != "background" else BACK_STRIP
        assert x0 - 0.1 <= o.position[0] <= x1 + 0.1 and y0 - 0.1 <= o.position[1] <= y1 + 0.1
    return scene


def test_every_level_lays_out_for_a_wide_seed_range():
    for level in LEVELS:
        for seed in range(500):
            _check_scene(level, seed)
    assert LEVELS["simple"].n_table == 5 and LEVELS["medium"].n_table == 9
    assert LEVELS["complex"].n_table >= 14


def test_scenes_are_deterministic_and_seeds_differ():
    for level in LEVELS:
        assert sample_scene(level, 7) == sample_scene(level, 7)
        a, b = sample_scene(level, 7), sample_scene(level, 8)
        assert [o.position for o in a.objects] != [o.position for o in b.objects]
        assert a.home_gaze != b.home_gaze
    with pytest.raises(SceneError, match="valid: simple, medium, complex"):
        sample_scene("hard", 0)


# -- environment ----------------------------------------------------------------------------
@pytest.fixture(scope="module", params=sorted(ipbench.envs.EXPLORATION_IDS))
def env(request):
    """The battery runs on every exploration id (tests/test_envs.py checks that every
    registered id is in a battery)."""
    kwargs = {"scene": "complex", **ipbench.envs.EXPLORATION_IDS[request.param], "head_size": SMALL}
    env = gym.make(request.param, render_mode="rgb_array", **kwargs).unwrapped
    yield env
    env.close()


def _action(gaze, kind=0, label=0, position=(0.0, 0.0, 0.0)):
    return {
        "gaze": np.asarray(gaze, float),
        "report": {"kind": kind, "label": label, "position": np.asarray(position, float)},
    }


def test_registration():
    assert ID in gym.registry and ID_V1 in gym.registry
    assert ID not in ipbench.envs.UNDER_DEVELOPMENT and ID_V1 not in ipbench.envs.UNDER_DEVELOPMENT
    assert ipbench.envs.env_status(ID_V1) == "released"
    assert ID not in ipbench.envs.ENV_IDS and ID in ipbench.envs.EXPLORATION_IDS
    assert set(ipbench.envs.ALL_IDS) == set(ipbench.envs.ENV_IDS) | {ID, ID_V1}
    assert set(ipbench.envs.ALL_IDS) <= set(gym.registry)
    assert gym.make(ID, scene="medium").unwrapped.config.scene == "medium"


def test_check_env(env):
    check_env(env, skip_render_check=False)


def test_reset_is_deterministic_and_seeds_differ(env):
    obs1, info1 = env.reset(seed=3)
    obs2, info2 = env.reset(seed=3)
    for key in obs1:
        np.testing.assert_array_equal(obs1[key], obs2[key], err_msg=key)
    np.testing.assert_array_equal(info1["head_left_mask"], info2["head_left_mask"])
    obs3, info3 = env.reset(seed=4)
    assert not np.array_equal(obs1["head_left"], obs3["head_left"])
    assert [o["instance"] for o in info1["objects"].values()] != [
        o["instance"] for o in info3["objects"].values()
    ]


def test_observations_are_in_the_space(env):
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    f = env.config.fovea_factor
    assert obs["head_left"].shape == (SMALL[0] // f, SMALL[1] // f, 3)
    assert obs["head_left"].std() > 1.0
    np.testing.assert_array_equal(env.render(), obs["head_left"])
    obs, *_ = env.step(_action(obs["head_qpos"] + [0.3, 0.1, -0.2, 0.2]))
    assert env.observation_space.contains(obs)


def test_head_reaches_the_gaze_in_real_time(env):
    obs, _ = env.reset(seed=1)
    speed = np.array([env.ptus[0].speed[0], env.ptus[0].speed[1]] * 2)
    start = obs["head_qpos"]
    target = np.clip(start + [0.8, -0.2, 0.6, 0.25], env._lower, env._upper)
    obs, _, _, _, info = env.step(_action(target))
    # the encoder reads the quantised target; the joints are within half a step of it
    assert np.abs(obs["head_qpos"] - target).max() <= STEP_RAD / 2 + 1e-12
    q = env.data.qpos[env._qadr]
    assert np.abs(q - target).max() <= STEP_RAD
    assert info["saccade_s"] >= np.max(np.abs(target - start) / speed)
    assert info["saccade_s"] < env.config.max_saccade_time
    # the pose the robot knows (FK of the encoders) is the rendered camera's, up to a step
    from ipbench.envs.sensors import camera_pose

    for side in ("left", "right"):
        true = camera_pose(env.model, env.data, f"head_{side}_camera")
        np.testing.assert_allclose(obs[f"head_{side}_pose"], true, atol=5e-3)
    # a swing of the whole tilt range takes at least 77.7 deg / 60 deg/s
    low = obs["head_qpos"].copy()
    low[1], low[3] = env._lower[1], env._lower[3]
    env.step(_action(low))
    high = low.copy()
    high[1], high[3] = env._upper[1], env._upper[3]
    *_, info = env.step(_action(high))
    assert info["saccade_s"] >= (env._upper[1] - env._lower[1]) / speed[1]


def test_a_command_outside_the_limits_is_rejected(env):
    obs, _ = env.reset(seed=2)
    gaze = obs["head_qpos"].copy()
    gaze[1] = env._upper[1] + 0.05
    with pytest.raises(InvalidActionError, match=r"head_left_tilt.*outside the PTU limits"):
        env.step(_action(gaze))
    with pytest.raises(InvalidActionError, match="46.6"):
        env.step(_action(gaze))
    with pytest.raises(InvalidActionError, match="report'\\]\\['kind'\\]"):
        env.step(_action(obs["head_qpos"], kind=5))
    with pytest.raises(InvalidActionError, match="keys"):
        env.step({"gaze": obs["head_qpos"]})


def test_reports_score_and_done_counts_not_found(env):
    obs, info = env.reset(seed=5)
    objects = info["objects"]
    name, truth = next((n, o) for n, o in objects.items() if o["class"] is not None)
    label = DATABASE_CLASSES.index(truth["class"])
    gaze = obs["head_qpos"]
    _, reward, term, trunc, info = env.step(_action(gaze, 1, label, truth["position"]))
    assert reward == 1.0 and info["report"]["kind"] == "true_positive"
    assert info["report"]["instance"] == name and not term
    other = (label + 1) % len(DATABASE_CLASSES)
    if DATABASE_CLASSES[other] == truth["class"]:
        other = (other + 1) % len(DATABASE_CLASSES)
    _, reward, *_, info = env.step(_action(gaze, 1, other, truth["position"]))
    assert reward == -1.0 and info["report"]["reason"] == "wrong_class"
    n_database = sum(o["class"] is not None for o in objects.values())
    _, reward, term, trunc, info = env.step(_action(gaze, 2))
    assert term and not trunc and info["saccade_s"] == 0.0
    assert info["score"] == {
        "true_positives": 1,
        "false_positives": 1,
        "not_found": n_database - 1,
        "performance": pytest.approx(1 / (n_database + 1)),
    }


def test_the_saccade_budget_truncates():
    env = ExplorationEnv(scene="simple", head_size=(60, 90), saccade_budget=3)
    obs, _ = env.reset(seed=0)
    for k in range(3):
        obs, _, term, trunc, info = env.step(_action(obs["head_qpos"]))
        assert info["saccades"] == k + 1 and trunc == (k == 2) and not term
    env.close()


def test_masks_agree_with_ground_truth(env):
    obs, info = env.reset(seed=6)
    names = list(info["objects"])
    for k, (name, truth) in enumerate(info["objects"].items()):
        if truth["role"] == "background":
            continue
        # look at the object: its pixels are in the mask, and an object is at the centre
        gaze = aim_head(truth["position"])
        obs, *_, info = env.step(_action(gaze))
        mask = info["head_left_mask"]
        h, w = mask.shape
        centre = mask[h // 2 - 5 : h // 2 + 6, w // 2 - 5 : w // 2 + 6]
        assert (mask == k).sum() > 0, name
        assert (centre >= 0).any(), name  # the object, or one in front of it
        if k >= 4:
            break
    assert set(np.unique(info["head_right_mask"])) <= set(range(-1, len(names)))


def test_errors_before_reset_and_after_close():
    env = ExplorationEnv(head_size=(60, 90))
    gaze = np.zeros(len(GAZE_JOINTS))
    with pytest.raises(ResetNeededError, match="no episode has started"):
        env.step(_action(gaze))
    env.reset(seed=0)
    env.close()
    env.close()  # idempotent
    with pytest.raises(ResetNeededError, match="closed"):
        env.step(_action(gaze))
    with pytest.raises(ValueError, match="valid: simple, medium, complex"):
        ExplorationEnv(scene="hard")
