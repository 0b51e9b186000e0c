"""The ``pile`` scene of Sorting-v2: twenty objects of every family, piled.

Layout only (no world built) but for the settling tests, which reset the environment; the
invariant battery of ``test_envs.py`` runs over ``ipbench/SortingPile-v2`` too (it is a
registered id)."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils import seeding

import ipbench.envs
from ipbench.assets.objects import CATEGORIES, FAMILIES
from ipbench.envs import UNDER_DEVELOPMENT, V2_IDS, env_config
from ipbench.envs.layout import (
    PILE_CLEARANCE,
    PILE_MAX_LIFT,
    LayoutError,
    _footprint,
    _overlaps,
    _top,
    sample_layout,
)
from ipbench.envs.sorting import workcell_places
from ipbench.envs.sorting_scenes import SCENES, STANDARD_SCENES, scenes_for

PLACES = workcell_places()
AREA = PLACES.spawn_area
PILE_ID = "ipbench/SortingPile-v2"
SETTLE_SEEDS = range(6)
"""Episode seeds whose reset is simulated (about 1 s each)."""
CHUNK, SEEDS = 500, 3000
"""Episode seeds 0 .. SEEDS - 1 are laid out, CHUNK per test case (about 10 ms a seed)."""
ON_OTHERS = 0.005
"""An object rests on others when none of its collision geoms comes closer to the table top
than this (m): it lies or leans on other objects only."""


def layout_seed(episode_seed: int) -> int:
    """The layout seed ``SortingEnv.reset(seed=episode_seed)`` passes to ``sample_layout``."""
    rng, _ = seeding.np_random(episode_seed)
    return int(rng.integers(2**31 - 1))


def _pile(seed: int, catalog: str = "v2"):
    return sample_layout("pile", seed, AREA.center, AREA.half, PLACES.table_height, catalog=catalog)


def _rect(obj) -> tuple[float, float, float, float, float]:
    """(x, y, hx, hy, yaw) of ``obj``'s footprint on the table (m, rad)."""
    offset, (hx, hy) = _footprint(obj.instance, obj.resting)
    c, s = np.cos(obj.yaw), np.sin(obj.yaw)
    mid = np.array(obj.position[:2]) + [
        c * offset[0] - s * offset[1],
        s * offset[0] + c * offset[1],
    ]
    return (float(mid[0]), float(mid[1]), float(hx), float(hy), obj.yaw)


def _lift(obj) -> float:
    """Height (m) of ``obj``'s lowest point above the table in the layout."""
    return obj.position[2] - obj.resting.height - PLACES.table_height


# -- the scene and where it exists ----------------------------------------------------------------
def test_pile_is_a_v2_scene_of_its_own_id():
    assert "pile" in SCENES and "pile" not in STANDARD_SCENES
    assert STANDARD_SCENES == ("uncluttered", "cluttered")
    assert scenes_for("v1") == STANDARD_SCENES
    assert scenes_for("v2") == (*STANDARD_SCENES, "pile")
    assert PILE_ID in ipbench.envs.ENV_IDS and PILE_ID in gym.registry
    assert PILE_ID in V2_IDS and PILE_ID not in UNDER_DEVELOPMENT
    config = env_config(PILE_ID)
    assert config.scene == "pile" and config.catalog == "v2"
    assert env_config("ipbench/Sorting-v2", scene="pile") == config


@pytest.mark.parametrize("env_id", ["ipbench/Sorting-v0", "ipbench/Sorting-v1"])
def test_released_ids_refuse_the_pile_and_list_their_scenes(env_id):
    with pytest.raises(
        ValueError, match="needs the v2 catalogue.*valid scenes: uncluttered, cluttered$"
    ):
        gym.make(env_id, scene="pile")
    with pytest.raises(LayoutError, match="valid scenes of catalog 'v1': uncluttered, cluttered$"):
        _pile(0, catalog="v1")
    with pytest.raises(ValueError, match="valid scenes: uncluttered, cluttered, pile$"):
        gym.make("ipbench/Sorting-v2", scene="heap")


def test_evaluation_takes_the_pile_and_keeps_its_validation_scenes(monkeypatch):
    """``--scenes uncluttered,cluttered,pile`` passes the evaluation's check; the validation
    scenes that choose the thresholds stay the standard ones."""
    import ipbench.eval.sorting.evaluate as sorting

    config = sorting.SortingEvalConfig(
        scenes=("uncluttered", "cluttered", "pile"), validation_seeds=(1000, 1001)
    )
    seen = []

    def run_episodes(fn, tasks, context, **kwargs):
        seen.extend(tasks)
        return iter(())

    monkeypatch.setattr(sorting, "run_episodes", run_episodes)
    sorting._validation_evidence(None, config)
    assert [(t.scene, t.seed) for t in seen] == [
        (scene, seed) for scene in STANDARD_SCENES for seed in (1000, 1001)
    ]


# -- the layout -----------------------------------------------------------------------------------
def test_layout_is_deterministic_and_seeds_differ():
    a, b, c = _pile(7), _pile(7), _pile(8)
    assert a == b
    assert [o.position for o in a.objects] != [o.position for o in c.objects]
    assert [o.instance.name for o in a.objects] != [o.instance.name for o in c.objects]


@pytest.mark.parametrize("seed", range(12))
def test_composition_every_family_some_lying_some_on_others(seed):
    layout = _pile(layout_seed(seed))
    objects = layout.objects
    assert [o.object_id for o in objects] == list(range(20))
    counts = [sum(o.instance.category == c for o in objects) for c in CATEGORIES]
    assert counts == [4, 4, 4, 4, 4]  # every bin equally often the right one
    families = {(o.instance.category, o.instance.family) for o in objects}
    assert families == {(c, f) for c in CATEGORIES for f in FAMILIES[c]}  # in every pile
    assert len({o.instance.name for o in objects}) == 20
    assert {o.instance.split for o in objects} == {"train", "similar", "novel"}
    assert sum(o.resting.name == "side" for o in objects) >= 3
    lifted = [o for o in objects if _lift(o) > 0]
    assert len(lifted) >= SCENES["pile"].on_top
    assert all(_lift(o) <= PILE_MAX_LIFT + PILE_CLEARANCE + 1e-9 for o in objects)


@pytest.mark.parametrize("seed", range(12))
def test_layout_stays_in_the_spawn_area_and_no_object_starts_inside_another(seed):
    objects = _pile(layout_seed(seed)).objects
    rects = [_rect(o) for o in objects]
    for x, y, hx, hy, yaw in rects:
        c, s = abs(np.cos(yaw)), abs(np.sin(yaw))
        extent = np.array([c * hx + s * hy, s * hx + c * hy])
        assert np.all(np.abs(np.array([x, y]) - AREA.center[:2]) <= AREA.half[:2] - extent + 1e-9)
    for i, a in enumerate(objects):
        for j in range(i):
            b = objects[j]
            if not _overlaps(rects[i], np.array([rects[j]]), 0.0):
                continue
            # footprints overlap: one lies above the other's top (bounding boxes)
            a_low, b_low = _lift(a), _lift(b)
            a_top, b_top = a_low + _top(a.instance, a.resting), b_low + _top(b.instance, b.resting)
            assert a_low >= b_top - 1e-9 or b_low >= a_top - 1e-9, (a.body, b.body)


def test_no_object_starts_inside_another_in_the_simulation():
    """The layout's bounding boxes hold the collision geometry: at the ``home`` keyframe no
    contact of an object penetrates (before any physics step)."""
    from ipbench.assets.compose import build_workcell_spec
    from ipbench.envs.world import FAST_PHYSICS, build_world

    for seed in range(3):
        world = build_world(_pile(layout_seed(seed)), build_workcell_spec(), FAST_PHYSICS)
        m = world.model
        d = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, d, m.key("home").id)
        mujoco.mj_forward(m, d)
        for c in d.contact[: d.ncon]:
            if c.geom1 in world.object_geoms or c.geom2 in world.object_geoms:
                assert c.dist > -1e-4, (seed, m.geom(c.geom1).name, m.geom(c.geom2).name, c.dist)


@pytest.mark.parametrize("start", range(0, SEEDS, CHUNK))
def test_every_seed_lays_out(start):
    """Episode seeds 0-2999, as the standard scenes' (``test_layout_seeds.py``)."""
    for seed in range(start, start + CHUNK):
        try:
            layout = _pile(layout_seed(seed))
        except LayoutError as err:
            pytest.fail(f"pile episode seed {seed}: {err}")
        assert len(layout.objects) == 20


# -- settling -------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def settled():
    """(seed, env after reset(seed), info) for each of SETTLE_SEEDS."""
    env = gym.make(PILE_ID, cameras=("wrist",))
    out = []
    try:
        for seed in SETTLE_SEEDS:
            _, info = env.reset(seed=seed)
            out.append(_state(env.unwrapped, info))
    finally:
        env.close()
    return out


def _state(base, info) -> dict:
    """What the settling tests check, measured from the simulation after a reset (and 0.5 s
    more of physics)."""
    m, d = base.model, base.data
    bodies = base.world.object_bodies
    dofs = np.concatenate([m.jnt_dofadr[m.body_jntadr[b]] + np.arange(6) for b in bodies])
    speed = np.abs(d.qvel[dofs]).reshape(-1, 6)
    table = m.geom("work_table_top").id
    clearance = np.full(len(bodies), np.inf)  # of each object above the table top (m)
    for g, k in base.world.object_geoms.items():
        if m.geom_contype[g] or m.geom_conaffinity[g]:
            dist = mujoco.mj_geomDistance(m, d, g, table, 0.5, None)
            clearance[k] = min(clearance[k], dist)
    state = {
        "statuses": [o["status"] for o in info["objects"].values()],
        "unstable": info["physics_unstable"] or info["physics_undone"],
        "warnings": sum(w.number for w in d.warning),
        "finite": bool(np.all(np.isfinite(d.qpos)) and np.all(np.isfinite(d.qvel))),
        "speed": float(speed[:, :3].max()),
        "spin": float(speed[:, 3:].max()),
        "on_others": int(np.sum(clearance > ON_OTHERS)),
        "sim_time": float(d.time),
    }
    before = d.xpos[bodies].copy()
    base.robot.hold(0.5)
    state["drift"] = float(np.linalg.norm(d.xpos[bodies] - before, axis=1).max())
    return state


def test_pile_settles_without_blow_ups(settled):
    for seed, s in zip(SETTLE_SEEDS, settled, strict=True):
        assert s["statuses"] == ["on_table"] * 20, (seed, s["statuses"])  # none dropped
        assert not s["unstable"] and s["warnings"] == 0 and s["finite"], seed
        assert s["speed"] < 0.02 and s["spin"] < 0.3, (seed, s["speed"], s["spin"])  # at rest
        assert s["drift"] < 0.01, (seed, s["drift"])  # and stays there
        # the gentle settling ran (the other scenes hold 0.3 s) and ended in time
        assert 0.3 < s["sim_time"] <= 0.3 + SCENES["pile"].gentle_settle + 1.5, seed


def test_some_objects_rest_on_others_after_settling(settled):
    """Measured from the simulation: objects none of whose collision geoms comes within
    ON_OTHERS of the table top lie or lean on other objects only."""
    for seed, s in zip(SETTLE_SEEDS, settled, strict=True):
        assert s["on_others"] >= 3, (seed, s["on_others"])


def test_standard_scenes_keep_their_settling():
    """Only a pile settles gently: the standard scenes' resets hold 0.3 s, as released."""
    for name in STANDARD_SCENES:
        assert SCENES[name].gentle_settle == 0.0
    env = gym.make("ipbench/SortingCluttered-v2", cameras=("wrist",))
    try:
        env.reset(seed=0)
        assert env.unwrapped.data.time == pytest.approx(0.3)
    finally:
        env.close()
