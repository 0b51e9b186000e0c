"""Sorting-v2's ``pick`` command, and the two oracles built on it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ipbench.envs  # noqa: F401
from ipbench.envs.sorting import COMMANDS, PICK, InvalidActionError
from ipbench.policies.scripted import GroundTruthSorter

V1, V2 = "ipbench/Sorting-v1", "ipbench/Sorting-v2"


def _env(env_id: str):
    return gym.make(env_id, scene="uncluttered", cameras=("wrist",))


def test_only_v2_has_the_pick_command() -> None:
    with _env(V1) as v1, _env(V2) as v2:
        assert v1.unwrapped.commands == COMMANDS
        assert v1.action_space["command"].n == 3
        assert v2.unwrapped.commands == (*COMMANDS, PICK)
        assert v2.action_space["command"].n == 4
        v1.reset(seed=0)
        action = v1.action_space.sample()
        action["command"] = 3
        with pytest.raises(InvalidActionError, match="2=inspect_in_hand"):
            v1.step(action)


def test_pick_then_place_is_one_place_in_bin_with_a_look_in_between() -> None:
    """The object is held after the pick (info and the jaws say so); placing it then ends
    in exactly the state one place_in_bin step reaches."""
    finals = []
    for split in (False, True):
        with _env(V2) as env:
            obs, info = env.reset(seed=3)
            action = GroundTruthSorter().act(obs, info)
            aimed = min(
                info["objects"],
                key=lambda k: np.linalg.norm(info["objects"][k]["center"] - action["position"]),
            )
            if split:
                obs, _, _, _, info = env.step(action | {"command": 3})
                held = [k for k, o in info["objects"].items() if o["status"] == "in_hand"]
                assert held == [aimed]
                assert [s["name"] for s in info["skills"]] == ["pick"]
                assert env.unwrapped.skills.holding
                elsewhere = action | {"position": action["position"] + np.float32(0.2)}
                obs, _, _, _, info = env.step(elsewhere)  # position ignored while holding
            else:
                obs, _, _, _, info = env.step(action)
            category = info["objects"][aimed]["category"]
            assert info["objects"][aimed]["status"] == f"in_bin:{category}"
            finals.append(env.unwrapped.data.qpos.copy())
    np.testing.assert_array_equal(finals[0], finals[1])


def _uniform_models():
    from ipbench.assets.objects import CATEGORIES
    from ipbench.envs.sorting import workcell_places
    from ipbench.eval.repro.stages_sim import _Uniform
    from ipbench.perception.features import FPFH_DIM, Codebook
    from ipbench.perception.model import PerceptionModel
    from ipbench.policies import PolicyModels

    codebook = Codebook(np.random.default_rng(0).random((2, FPFH_DIM)))
    model = PerceptionModel(CATEGORIES, codebook, _Uniform(len(CATEGORIES)), "test")
    area = tuple(float(v) for v in workcell_places().inspection_area.center)
    return PolicyModels(gp=model, inspection_area=area, thresholds={})


def test_the_oracle_labels_what_it_holds_and_oracle_scene_what_it_aimed_at() -> None:
    """On v2 the oracle picks, reads the object in hand from info and sends it to that
    object's bin; oracle-scene (and the oracle on v1, which has no pick) picks and places in
    one step with the label of the segment it aimed at."""
    from ipbench.assets.objects import CATEGORIES
    from ipbench.policies import make_policy

    models = _uniform_models()
    with _env(V2) as env:
        obs, info = env.reset(seed=0)
        oracle = make_policy("oracle", models, commands=env.unwrapped.commands)
        oracle.reset(0)
        first = oracle.act(obs, info)
        assert env.unwrapped.commands[first["command"]] == PICK
        obs, _, _, _, info = env.step(first)
        held = [k for k, o in info["objects"].items() if o["status"] == "in_hand"]
        assert len(held) == 1  # seed 0's first pick holds one object
        second = oracle.act(obs, info)
        assert second["command"] == 0
        category = info["objects"][held[0]]["category"]
        assert CATEGORIES[second["bin"]] == category == oracle.decisions[-1].label
        assert len(oracle.decisions) == 1  # one decision: the pick and its place
        scene = make_policy("oracle-scene", models, commands=env.unwrapped.commands)
        scene.reset(0)
        obs, info = env.reset(seed=0)
        assert scene.act(obs, info)["command"] == 0
    with _env(V1) as env:
        obs, info = env.reset(seed=0)
        on_v1 = make_policy("oracle", models, commands=env.unwrapped.commands)
        on_v1.reset(0)
        assert on_v1.act(obs, info)["command"] == 0


def test_a_wide_bowl_is_held_with_the_pads_under_its_rim() -> None:
    """A 18 cm noodle bowl alone on the table, picked on its axis at three yaws with the TCP
    where grasp planning puts it for a short object (``TOP_MARGIN`` under the top, the skill's
    ``grasp_depth`` added back), is held every time."""
    from ipbench.assets.objects import instances
    from ipbench.eval.capture.hand_views import _layout
    from ipbench.policies.grasping.boxes import TOP_MARGIN
    from ipbench.policies.grasping.free import GRASP_DEPTH

    bowl = instances(catalog="v2", family="noodle")[0]
    layout = _layout(bowl, "upright", 0.0)
    assert layout is not None
    with _env(V2) as env:
        for yaw in (0.3, 1.2, 2.4):
            _, info = env.reset(seed=0, options={"layout": layout})
            obj = info["objects"][0]
            top = obj["pose"][2] + bowl.size[2]
            position = [obj["center"][0], obj["center"][1], top - TOP_MARGIN + GRASP_DEPTH]
            action = {
                "command": 3,
                "position": np.array(position, np.float32),
                "yaw": np.array([yaw], np.float32),
                "bin": 0,
                "opening": np.array([0.21], np.float32),
            }
            _, _, _, _, info = env.step(action)
            assert info["objects"][0]["status"] == "in_hand", yaw
