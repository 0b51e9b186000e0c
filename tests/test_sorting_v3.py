"""Sorting-v3 (under development): what it changes from v2, and only that, and the inspection
area's memory after a failed re-pick."""

from __future__ import annotations

from dataclasses import replace

import gymnasium as gym
import mujoco
import numpy as np
import pytest

import ipbench.envs
from ipbench.assets.compose import build_workcell_spec
from ipbench.assets.objects import CATEGORIES, add_object, instances, resting_poses
from ipbench.assets.objects.object_model import ObjectModel
from ipbench.envs import UNDER_DEVELOPMENT, V2_IDS, V3_IDS, env_config
from ipbench.envs.skills import SkillResult
from ipbench.envs.sorting import COMMANDS, V2, V3
from ipbench.envs.world import FAST_PHYSICS
from ipbench.policies.scripted import GroundTruthSorter


def test_v3_ids_are_registered_under_development_beside_every_v2_id():
    assert set(V3_IDS) == {i.replace("-v2", "-v3") for i in V2_IDS}
    assert set(V3_IDS) <= set(UNDER_DEVELOPMENT) and set(V3_IDS) <= set(gym.registry)
    assert not set(V2_IDS) & set(UNDER_DEVELOPMENT)
    assert ipbench.envs.LATEST not in UNDER_DEVELOPMENT


def test_v3_changes_from_v2_only_what_its_settings_name():
    v2, v3 = env_config("ipbench/Sorting-v2"), env_config("ipbench/Sorting-v3")
    assert v2.objects == ObjectModel() and not v2.keep_area_after_failed_pick
    assert v2.bin_floor_backing == 0.0
    assert v3.objects == ObjectModel(hollow_collision="convex", upright_prints=True)
    changed = {k for k in V3 if V3[k] != V2.get(k, getattr(v2, k))}
    assert changed == set(V3) - set(V2)  # v3 keeps every v2 setting it does not add
    assert replace(v3, **{k: getattr(v2, k) for k in changed}) == v2
    for scene in ("uncluttered", "cluttered", "pile"):
        assert env_config(f"ipbench/Sorting{scene.title()}-v3").scene == scene


def test_a_bad_object_model_names_the_valid_ones():
    with pytest.raises(ValueError, match="valid: box_rings, convex"):
        ObjectModel(hollow_collision="spheres")


def _fail_next_pick(env) -> None:
    """The next pick fails without moving (as a grasp that closes on nothing would)."""
    skills = env.skills
    real = skills.pick

    def pick(*args, **kwargs):
        skills.pick = real
        return SkillResult("pick", False, "jaws closed on nothing")

    skills.pick = pick


@pytest.mark.parametrize("env_id, keeps", [("ipbench/SortingUncluttered-v2", False),
                                           ("ipbench/SortingUncluttered-v3", True)])  # fmt: skip
def test_a_failed_repick_from_the_area_keeps_the_object_in_the_envs_memory(env_id, keeps):
    env = gym.make(env_id).unwrapped
    obs, info = env.reset(seed=6)
    action = GroundTruthSorter().act(obs, info)
    target = max(info["objects"], key=lambda k: info["objects"][k]["center"][1])
    obs, _, _, _, info = env.step(dict(action, command=COMMANDS.index("inspect_in_area")))
    assert info["objects"][target]["status"] == "in_inspection_area", info["skills"]
    category = info["objects"][target]["category"]
    # the re-pick from the area fails; the object is still there
    _fail_next_pick(env)
    place = dict(action, command=0, bin=CATEGORIES.index(category))
    obs, _, _, _, info = env.step(place)
    assert info["objects"][target]["status"] == "in_inspection_area"
    # the next place names a spot where nothing is: v3 takes the object from the area
    nowhere = dict(place, position=np.array([-1.8, -1.8, 0.8], np.float32))
    obs, _, _, _, info = env.step(nowhere)
    status = info["objects"][target]["status"]
    if keeps:
        assert status == f"in_bin:{category}", info["skills"]
    else:
        assert status == "in_inspection_area"
        assert "unreachable" in next(s for s in info["skills"] if not s["success"])["reason"]
    env.close()


def test_env_status_says_which_ids_may_still_change():
    from ipbench.envs import EnvIdError, env_status

    assert env_status("ipbench/SortingPile-v3") == "under development"
    assert env_status("ipbench/Sorting-v2") == env_status("ipbench/Exploration-v0") == "released"
    with pytest.raises(EnvIdError, match="valid: ipbench/Sorting-v0"):
        env_status("ipbench/Sorting-v9")


def _dropped_into_a_bin(inst, pose_name: str, floor_backing: float) -> float:
    """Height (m) of ``inst``'s frame origin above the bin floor's top after a drop from
    0.42 m, the fall of an object released above a bin's rim, and 1.5 s of settling."""
    spec = build_workcell_spec(bin_floor_backing=floor_backing)
    bin_origin = np.array(spec.body("bin_bowl").pos)
    pose = next(p for p in resting_poses(inst) if p.name == pose_name)
    start = bin_origin + [0.0, 0.0, 0.01 + 0.42 + pose.height]
    add_object(spec, inst, "dropped", pos=start, quat=pose.quat)
    model = spec.compile()
    FAST_PHYSICS.apply_to_model(model)
    data = mujoco.MjData(model)
    for _ in range(int(1.5 / model.opt.timestep)):
        mujoco.mj_step(model, data)
    return float(data.body("dropped").xpos[2] - (bin_origin[2] + 0.01))


@pytest.mark.parametrize("family, pose", [("footed", "upright"), ("straight", "side")])
def test_nothing_dropped_into_a_v3_bin_sticks_in_its_floor(family, pose):
    inst = next(i for i in instances(catalog="v2") if i.family == family)
    resting = next(p for p in resting_poses(inst) if p.name == pose).height
    backing = env_config("ipbench/Sorting-v3").bin_floor_backing
    assert _dropped_into_a_bin(inst, pose, backing) == pytest.approx(resting, abs=0.003)
    # the released 1 cm floor: the foot or the handle passes its mid-plane and stays in it
    assert _dropped_into_a_bin(inst, pose, 0.0) < resting - 0.008
