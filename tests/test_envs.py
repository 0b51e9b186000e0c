"""One invariant battery over every registered environment id, then Sorting-v1's contract
and what v0 keeps."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import ipbench.envs
from ipbench.assets.compose import BIN_INTERIOR
from ipbench.assets.objects import CATEGORIES
from ipbench.envs.sorting import COMMANDS, InvalidActionError, ResetNeededError
from ipbench.policies.scripted import GroundTruthSorter

ENV_IDS = sorted(ipbench.envs.ENV_IDS)


def test_export_list_is_current():
    import ipbench.envs.sorting as sorting

    for name in sorting.__all__:
        assert hasattr(sorting, name)
    assert set(ENV_IDS) <= set(gym.registry)


def test_every_registered_id_is_in_a_battery():
    """Sorting ids run the battery below; exploration ids ``tests/test_exploration_env.py``'s
    (the same invariants: check_env, determinism, observations in the space, errors)."""
    ours = {i for i in gym.registry if i.startswith("ipbench/")}
    assert ours == set(ipbench.envs.ALL_IDS)
    assert ours == set(ipbench.envs.ENV_IDS) | set(ipbench.envs.EXPLORATION_IDS)


@pytest.fixture(scope="module", params=ENV_IDS)
def env(request):
    env = gym.make(request.param, render_mode="rgb_array")
    yield env
    env.close()


def _assert_equal_obs(a: dict, b: dict) -> None:
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)


def test_check_env(env):
    check_env(env.unwrapped, skip_render_check=False)


def test_reset_is_deterministic_and_seeds_differ(env):
    obs1, info1 = env.reset(seed=3)
    obs2, info2 = env.reset(seed=3)
    _assert_equal_obs(obs1, obs2)
    np.testing.assert_array_equal(info1["wrist_mask"], info2["wrist_mask"])
    assert [o["instance"] for o in info1["objects"].values()] == [
        o["instance"] for o in info2["objects"].values()
    ]
    obs3, info3 = env.reset(seed=4)
    assert not np.array_equal(obs1["wrist_rgb"], obs3["wrist_rgb"])
    poses1 = np.array([o["pose"] for o in info1["objects"].values()])
    poses3 = np.array([o["pose"] for o in info3["objects"].values()])
    assert not np.allclose(poses1, poses3)


def test_observations_are_in_the_space_and_not_constant(env):
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    for key in ("wrist_rgb", "wrist_depth", "head_left", "head_right"):
        assert obs[key].std() > 1.0 if obs[key].dtype == np.uint8 else obs[key].std() > 0.01, key
    depth = obs["wrist_depth"]
    assert 0.3 < (depth > 0).mean() < 1.0  # holes exist, most pixels have depth
    # the camera sees the objects (ground-truth mask, for evaluation only)
    visible = set(np.unique(info["wrist_mask"])) - {-1}
    assert len(visible) >= 0.7 * len(info["objects"])
    frame = env.render()
    assert frame.shape == (480, 640, 3) and frame.std() > 1.0


def test_step_is_deterministic(env):
    results = []
    for _ in range(2):
        obs, info = env.reset(seed=1)
        action = GroundTruthSorter("opening" in env.action_space.spaces).act(obs, info)
        results.append(env.step(action))
    (o1, r1, t1, tr1, i1), (o2, r2, t2, tr2, i2) = results
    _assert_equal_obs(o1, o2)
    assert (r1, t1, tr1) == (r2, t2, tr2)
    assert [o["status"] for o in i1["objects"].values()] == [
        o["status"] for o in i2["objects"].values()
    ]
    assert env.observation_space.contains(o1)


def _sort(env, seed: int):
    policy = GroundTruthSorter()
    obs, info = env.reset(seed=seed)
    done, skills, total = False, 0, 0.0
    while not done:
        obs, reward, terminated, truncated, info = env.step(policy.act(obs, info))
        total += reward
        skills += sum(s["sim_time"] > 0 for s in info["skills"])
        done = terminated or truncated
    return info, terminated, total, skills


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_scripted_sorting_of_uncluttered_scene(seed):
    """Only the public contract: info's object centre as position, its category as bin."""
    env = gym.make("ipbench/SortingUncluttered-v1")
    info, terminated, total, skills = _sort(env, seed)
    env.close()
    statuses = [(o["status"], o["category"]) for o in info["objects"].values()]
    correct = sum(s == f"in_bin:{c}" for s, c in statuses)
    assert len(statuses) == 10 and correct >= 9, statuses
    assert terminated and not info["physics_unstable"]
    wrong = sum(s.startswith("in_bin:") and s != f"in_bin:{c}" for s, c in statuses)
    assert total == pytest.approx(correct - wrong - 0.01 * skills)


def test_inspect_in_hand_then_place():
    env = gym.make("ipbench/SortingUncluttered-v1")
    obs, info = env.reset(seed=5)
    action = GroundTruthSorter().act(obs, info)
    target = max(info["objects"], key=lambda k: info["objects"][k]["center"][1])
    category = info["objects"][target]["category"]
    action["command"] = COMMANDS.index("inspect_in_hand")
    obs, reward, *_, info = env.step(action)
    assert info["objects"][target]["status"] == "in_hand", info["skills"]
    first_view = obs["wrist_rgb"]
    # turn it by 30 degrees: a new view of the same object
    obs, reward, *_, info = env.step(dict(action, yaw=np.array([np.pi / 6], np.float32)))
    assert info["objects"][target]["status"] == "in_hand"
    assert not np.array_equal(first_view, obs["wrist_rgb"])
    # place_in_bin acts on the object in hand, whatever the position says
    far = dict(
        action,
        command=0,
        position=np.array([-1.9, -1.9, 0.0], np.float32),
        bin=CATEGORIES.index(category),
    )
    obs, reward, *_, info = env.step(far)
    assert info["objects"][target]["status"] == f"in_bin:{category}"
    assert reward == pytest.approx(1.0 - 0.01 * len(info["skills"]), abs=0.05)
    env.close()


def test_inspect_in_area_turns_and_places():
    env = gym.make("ipbench/SortingUncluttered-v1")
    obs, info = env.reset(seed=6)
    action = GroundTruthSorter().act(obs, info)
    target = max(info["objects"], key=lambda k: info["objects"][k]["center"][1])
    action["command"] = COMMANDS.index("inspect_in_area")
    obs, _, _, _, info = env.step(action)
    assert info["objects"][target]["status"] == "in_inspection_area", info["skills"]
    yaw_before = info["objects"][target]["pose"][3:]
    obs, _, _, _, info = env.step(dict(action, yaw=np.array([np.pi / 6], np.float32)))
    assert info["objects"][target]["status"] == "in_inspection_area", info["skills"]
    assert not np.allclose(yaw_before, info["objects"][target]["pose"][3:], atol=1e-2)
    category = info["objects"][target]["category"]
    obs, _, _, _, info = env.step(dict(action, command=0, bin=CATEGORIES.index(category)))
    assert info["objects"][target]["status"] == f"in_bin:{category}", info["skills"]
    env.close()


@pytest.mark.parametrize(
    "change, message",
    [
        ({"bin": 5}, "valid: 0=juice_bottle"),
        ({"command": 3}, "valid: 0=place_in_bin"),
        ({"position": np.zeros(2, np.float32)}, "shape"),
        ({"position": np.array([0.0, 0.0, 9.0], np.float32)}, "outside"),
        ({"yaw": np.array([4.0], np.float32)}, "outside"),
        ({"extra": 1}, "keys"),
    ],
)
def test_invalid_actions_raise_clear_errors(change, message):
    env = gym.make("ipbench/SortingUncluttered-v1").unwrapped
    obs, info = env.reset(seed=0)
    action = dict(GroundTruthSorter().act(obs, info), **change)
    with pytest.raises(InvalidActionError, match=message):
        env.step(action)
    env.close()


def test_unreachable_or_empty_positions_fail_softly():
    env = gym.make("ipbench/SortingUncluttered-v1").unwrapped
    obs, info = env.reset(seed=0)
    base = {"command": 0, "yaw": np.zeros(1, np.float32), "bin": 0, "opening": np.ones(1) * 0.1}
    far = dict(base, position=np.array([-1.8, -1.8, 0.8], np.float32))
    obs, reward, terminated, truncated, info = env.step(far)
    failed = [s for s in info["skills"] if not s["success"]]
    assert failed and "unreachable" in failed[0]["reason"]
    assert reward < 0 and not terminated
    area = env.world.places.inspection_area.center  # an empty spot on the table
    empty = dict(base, position=(area + [0, 0, 0.05]).astype(np.float32))
    obs, reward, terminated, truncated, info = env.step(empty)
    failed = [s for s in info["skills"] if not s["success"]]
    assert failed and "grasp failed" in failed[0]["reason"]
    assert all(o["status"] == "on_table" for o in info["objects"].values())
    env.close()


def test_v0_truncates_on_a_physics_blow_up():
    env = gym.make("ipbench/SortingUncluttered-v0").unwrapped
    assert "opening" not in env.action_space.spaces
    obs, info = env.reset(seed=0)
    env.data.qvel[-6:] = 1e12  # an object's free joint flung at an absurd speed
    action = GroundTruthSorter(jaw_opening=False).act(obs, info)
    obs, reward, terminated, truncated, info = env.step(action)
    assert truncated and info["physics_unstable"]
    env.close()


def _fling_mid_step(env) -> None:
    """Fling the last object at 50 m/s the first time the step records a frame."""
    flung = []

    def fling() -> None:
        if not flung:
            env.data.qvel[-6:-3] = (50.0, 0.0, 0.0)
            flung.append(True)

    env.add_frame_listener(fling, fps=30)


def test_v1_rolls_a_blow_up_back():
    env = gym.make("ipbench/SortingUncluttered-v1").unwrapped
    obs, info = env.reset(seed=0)
    qpos, t0 = env.data.qpos.copy(), info["sim_time"]
    _fling_mid_step(env)
    obs, reward, terminated, truncated, info = env.step(GroundTruthSorter().act(obs, info))
    assert info["physics_undone"] and not info["physics_unstable"] and not truncated
    assert [s["success"] for s in info["skills"]] == [False]
    assert "rolled back" in info["skills"][0]["reason"]
    assert info["sim_time"] == t0 and not env.skills.holding
    np.testing.assert_array_equal(env.data.qpos, qpos)  # objects and robot as before
    # the episode goes on: the same action now runs normally
    env._frame_listeners.clear()
    obs, reward, terminated, truncated, info = env.step(GroundTruthSorter().act(obs, info))
    assert not info["physics_undone"] and info["skills"][0]["success"], info["skills"]
    env.close()


def test_pick_preshapes_the_jaws_and_guards_the_descent():
    env = gym.make("ipbench/SortingUncluttered-v1").unwrapped
    obs, info = env.reset(seed=0)
    sk = env.skills
    widths = []
    env.add_frame_listener(lambda: widths.append(2 * float(env.data.qpos[sk._finger])), fps=60)
    action = GroundTruthSorter().act(obs, info)
    opening = float(action["opening"][0])
    assert 0.03 < opening < 0.2
    # aim 10 cm below the object's grasp point: the jaws land on it and the arm stops there
    position = np.asarray(action["position"], float) - [0.0, 0.0, 0.10]
    pad_z = []
    sk.pick(position, float(action["yaw"][0]), opening)
    pad_z.append(sk.grasp_height + env.world.places.table_height)
    half_way = widths[len(widths) // 3 :]
    assert max(half_way) <= opening + 0.005  # pre-shaped, never wider on the way down
    assert pad_z[0] > position[2] - sk.config.grasp_depth + 0.02  # stopped above the target
    env.close()


def test_v0_keeps_its_manipulation():
    v0 = gym.make("ipbench/SortingUncluttered-v0").unwrapped
    v1 = gym.make("ipbench/SortingUncluttered-v1").unwrapped
    v0.reset(seed=0)
    v1.reset(seed=0)
    assert v0.skills.config.guard_force is None and v1.skills.config.guard_force is not None
    adr = v0.model.joint("left_gripper_finger_a").dofadr[0]
    assert v0.model.dof_armature[adr] == pytest.approx(0.05)
    assert v1.model.dof_armature[adr] > v0.model.dof_armature[adr]
    depth = {v: 2 * env.world.places.bins["juice_bottle"].half[2] for v, env in ((0, v0), (1, v1))}
    assert depth[0] == pytest.approx(0.24) and depth[1] == pytest.approx(BIN_INTERIOR[2])
    v0.close()
    v1.close()


def test_step_and_render_without_an_episode_ask_for_reset():
    assert issubclass(ResetNeededError, gym.error.ResetNeeded)
    assert issubclass(ResetNeededError, RuntimeError)  # (what step before reset raised)
    env = gym.make("ipbench/SortingUncluttered-v1", render_mode="rgb_array")
    base = env.unwrapped
    action = {"command": 0, "position": np.zeros(3), "yaw": [0.0], "bin": 0, "opening": [0.1]}
    for call in (lambda: base.step(action), base.render):
        with pytest.raises(ResetNeededError, match=r"no episode has started: call reset\(\)"):
            call()
    obs, info = env.reset(seed=0)
    action = GroundTruthSorter().act(obs, info)
    env.close()
    env.close()  # harmless
    for call in (lambda: env.step(action), env.render, lambda: base.step(action)):
        with pytest.raises(ResetNeededError, match=r"was closed: call reset\(\) before"):
            call()
    assert base.renderer is None
    obs, info = env.reset(seed=0)  # a new episode
    assert env.render().shape == (480, 640, 3)
    obs, reward, *_ = env.step(action)
    assert env.observation_space.contains(obs)
    env.close()


def test_unknown_scene_is_a_clear_error():
    with pytest.raises(ValueError, match="valid scenes: uncluttered, cluttered"):
        gym.make("ipbench/Sorting-v1", scene="kitchen")


def test_reset_with_a_layout_option_places_exactly_those_objects():
    from dataclasses import replace

    from ipbench.envs.layout import Layout
    from ipbench.envs.sorting import workcell_places

    env = gym.make("ipbench/Sorting-v1", scene="cluttered")
    _, sampled = env.reset(seed=4)
    one = env.unwrapped.world.layout.objects[3]
    places = workcell_places()
    custom = Layout("custom", 0, (replace(one, object_id=0),))
    obs, info = env.reset(seed=4, options={"layout": custom})
    assert env.observation_space.contains(obs)
    assert len(info["objects"]) == 1 and len(sampled["objects"]) > 1
    obj = info["objects"][0]
    assert obj["instance"] == one.instance.name and obj["status"] == "on_table"
    np.testing.assert_allclose(obj["pose"][:2], one.position[:2], atol=0.01)  # settled in place
    assert abs(obj["pose"][2] - one.position[2]) < 0.01
    assert places.table_height < obj["center"][2]
    _, again = env.reset(seed=4)  # without options: the scene's own layout again
    assert [o["instance"] for o in again["objects"].values()] == [
        o["instance"] for o in sampled["objects"].values()
    ]
    with pytest.raises(ValueError, match="valid: layout"):
        env.reset(seed=4, options={"objects": custom})
    with pytest.raises(ValueError, match="at least one object"):
        env.reset(seed=4, options={"layout": Layout("custom", 0, ())})
    env.close()
