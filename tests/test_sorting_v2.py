"""Sorting-v2: the v2 objects and the structured-light sensor, behind
the same contract as v1 (the battery in test_envs.py runs over every id, v2 included)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ipbench.envs
from ipbench.assets.objects import CATEGORIES, FAMILIES
from ipbench.envs import UNDER_DEVELOPMENT, V2_IDS, EnvIdError, env_config
from ipbench.envs.layout import LayoutError, sample_layout
from ipbench.envs.sensors.depth_noise import STRUCTURED_LIGHT, DepthNoiseConfig
from ipbench.envs.sorting import workcell_places
from ipbench.envs.sorting_scenes import SCENES


def _layout(scene: str, seed: int, catalog: str = "v2"):
    places = workcell_places()
    return sample_layout(
        scene,
        seed,
        places.spawn_area.center,
        places.spawn_area.half,
        places.table_height,
        catalog=catalog,
    )


def test_v2_ids_are_registered_released_and_configured():
    assert not set(V2_IDS) & set(UNDER_DEVELOPMENT)  # released
    for env_id in V2_IDS:
        assert env_id in ipbench.envs.ENV_IDS and env_id in gym.registry
        config = env_config(env_id)
        assert config.catalog == "v2" and config.depth_noise == STRUCTURED_LIGHT
    assert env_config("ipbench/Sorting-v1").catalog == "v1"
    assert env_config("ipbench/Sorting-v1").depth_noise == DepthNoiseConfig()
    assert env_config("ipbench/SortingCluttered-v2").scene == "cluttered"
    assert ipbench.envs.LATEST == "ipbench/Sorting-v2"  # the benchmark runs a released id
    assert ipbench.envs.LATEST not in UNDER_DEVELOPMENT


def test_bad_ids_and_catalogues_name_the_valid_ones():
    with pytest.raises(EnvIdError, match="valid: ipbench/Sorting-v0.*ipbench/Sorting-v2"):
        env_config("ipbench/Sorting-v9")
    with pytest.raises(ValueError, match="valid: v1, v2"):
        gym.make("ipbench/Sorting-v2", catalog="v7")
    with pytest.raises(LayoutError, match="valid: v1, v2"):
        _layout("cluttered", 0, catalog="v3")


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_v2_scenes_keep_the_thesis_compositions_with_every_family(scene):
    counts = np.zeros(len(CATEGORIES), int)
    families, splits = set(), set()
    for seed in range(40):
        layout = _layout(scene, seed)
        per_category = np.bincount(
            [CATEGORIES.index(o.instance.category) for o in layout.objects],
            minlength=len(CATEGORIES),
        )
        np.testing.assert_array_equal(per_category, SCENES[scene].counts)
        names = [o.instance.name for o in layout.objects]
        assert len(set(names)) == len(names)  # no instance twice
        assert len({o.instance.split for o in layout.objects}) >= 2
        families |= {(o.instance.category, o.instance.family) for o in layout.objects}
        splits |= {o.instance.split for o in layout.objects}
        counts += per_category
    used = {c for c, n in zip(CATEGORIES, SCENES[scene].counts, strict=True) if n}
    assert families == {(c, f) for c in used for f in FAMILIES[c]}  # every family appears
    assert splits == {"train", "similar", "novel"}


def test_v1_layouts_are_drawn_as_before():
    for seed in (0, 5):
        a, b = _layout("cluttered", seed, catalog="v1"), _layout("cluttered", seed, "v1")
        assert a == b
        assert all(
            o.instance.name == f"{o.instance.category}_{o.instance.index:02d}" for o in a.objects
        )


def test_v2_episode_has_a_sensor_unit_for_the_whole_episode():
    env = gym.make("ipbench/SortingUncluttered-v2")
    try:
        obs, info = env.reset(seed=3)
        unit = env.unwrapped._unit
        assert unit is not None
        assert {o["instance"].split("_")[0] for o in info["objects"].values()} <= {
            "juice",
            "milk",
            "mug",
        }
        assert env.observation_space.contains(obs)
        env.reset(seed=3)
        assert env.unwrapped._unit == unit  # the same unit for the same seed
        env.reset(seed=4)
        assert env.unwrapped._unit != unit  # another episode, another unit
    finally:
        env.close()
    v1 = gym.make("ipbench/Sorting-v1")
    try:
        v1.reset(seed=3)
        assert v1.unwrapped._unit is None  # v1's sensor has no unit error
    finally:
        v1.close()
