"""Exploration policies on ipbench/Exploration-v0: vergence, episodes to their end, reports.

A small head image (340x512) keeps rendering and features cheap; the database is captured at
the same size, once per module, into a temporary cache."""

from __future__ import annotations

from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest

import ipbench.envs  # noqa: F401
from ipbench.eval.capture.exploration_database import (
    DatabaseCaptureConfig,
    capture_views,
    load_or_build_database,
)
from ipbench.policies.exploration import (
    EXPLORATION_ABLATIONS,
    EXPLORATION_POLICIES,
    HALT_AFTER,
    READS_INFO,
    VERGENCE_GOAL_PX,
    ExplorationPolicyError,
    make_exploration_policy,
    same_object_m,
    verge,
)
from ipbench.policies.gaze import aim, pixel_on_table, verge_right
from ipbench.policies.stereo_look import Candidate, eye_features

SIZE = (340, 512)
CAPTURE = DatabaseCaptureConfig(head_size=SIZE, yaw_step_deg=90.0)


@pytest.fixture(scope="module")
def database(tmp_path_factory):
    return load_or_build_database("sift", tmp_path_factory.mktemp("cache"), CAPTURE, False)


def _env(**kw):
    return gym.make("ipbench/Exploration-v0", head_size=SIZE, **kw)


def test_database_views_show_each_object_with_its_mask_and_are_cached(tmp_path, database):
    views = capture_views("juice_box/2", CAPTURE)
    assert len(views) == 2 * 4 * 2  # two resting poses, four yaws, two cameras
    for v in views:
        assert v.class_name == "juice_box/2" and v.mask.shape == v.image.shape[:2]
        rows, cols = np.flatnonzero(v.mask.any(1)), np.flatnonzero(v.mask.any(0))
        m = CAPTURE.margin_px  # the crop is the mask's box and a margin on every side
        assert (rows[0], cols[0]) == (m, m)
        assert (len(v.mask) - 1 - rows[-1], v.mask.shape[1] - 1 - cols[-1]) == (m, m)
    assert len(database.classes) == len(CAPTURE.classes)
    files = sorted(p.name for p in tmp_path.parent.rglob("exploration-*.npz"))
    assert any(n.startswith("exploration-db-sift-") for n in files)


def test_vergence_brings_an_objects_disparity_under_two_pixels():
    env = _env(scene="simple")
    obs, info = env.reset(seed=0)
    target = next(o["position"] for o in info["objects"].values() if o["role"] == "database")
    gaze = verge_right(aim(target), np.radians(1.5))  # the right eye off the object
    obs, *_ = env.step({"gaze": gaze, "report": {"kind": 0, "label": 0, "position": [0, 0, 0]}})
    disparities = []
    for _ in range(4):
        left, _, size, _ = eye_features(obs, "left", "sift")
        right, K_right, _, _ = eye_features(obs, "right", "sift")  # noqa: N806
        rig = SimpleNamespace(K_right=K_right)
        seen = SimpleNamespace(left=left, right=right, size=size, rig=rig)
        gaze, disparity = verge(obs, seen)
        disparities.append(abs(disparity))
        if abs(disparity) < VERGENCE_GOAL_PX:
            break
        obs, *_ = env.step({"gaze": gaze, "report": {"kind": 0, "label": 0, "position": [0, 0, 0]}})
    env.close()
    assert disparities[0] > 10  # 1.5 deg at f ~ 760 px is ~20 px
    assert disparities[-1] < VERGENCE_GOAL_PX, disparities


def test_a_pixel_on_the_table_is_where_the_camera_sees_the_table():
    env = _env(scene="simple")
    obs, _ = env.reset(seed=1)
    K, pose = obs["head_left_K"], obs["head_left_pose"]
    point = pixel_on_table(K[:2, 2], K, pose)
    env.close()
    ray = point - pose[:3, 3]
    assert np.allclose(ray / np.linalg.norm(ray), pose[:3, 2], atol=1e-9)


@pytest.mark.parametrize("name", EXPLORATION_POLICIES)
def test_every_policy_runs_an_episode_to_its_end(name, database):
    env = _env(scene="simple", saccade_budget=8)
    policy = make_exploration_policy(name, database)
    policy.reset(2)
    obs, info = env.reset(seed=2)
    terminated = truncated = False
    steps = 0
    while not (terminated or truncated):
        action = policy.act(obs, info if name in READS_INFO else None)
        assert env.action_space.contains(action)
        obs, _, terminated, truncated, info = env.step(action)
        steps += 1
    env.close()
    score = info["score"]
    assert steps <= 8 + 1 and len(policy.fixations) == steps
    reported = score["true_positives"] + score["false_positives"]
    assert reported == len(policy.reported)
    if name == "raster-scan":
        assert terminated or steps == 8


def test_the_oracle_reads_info_and_says_so_without_it(database):
    policy = make_exploration_policy("oracle-gaze", database)
    env = _env(scene="simple")
    obs, _ = env.reset(seed=0)
    with pytest.raises(ExplorationPolicyError, match="reads info"):
        policy.act(obs)
    env.close()


def test_an_unknown_policy_lists_the_valid_ones(database):
    valid = ", ".join((*EXPLORATION_POLICIES, *EXPLORATION_ABLATIONS))
    with pytest.raises(ExplorationPolicyError, match="valid: " + valid):
        make_exploration_policy("saccadic", database)


def test_ablations_are_not_benchmark_policies():
    from ipbench.eval.exploration.evaluate import ExplorationEvalConfig

    assert not set(EXPLORATION_ABLATIONS) & set(EXPLORATION_POLICIES)
    assert not set(EXPLORATION_ABLATIONS) & set(ExplorationEvalConfig().policies)  # by name only
    assert ExplorationEvalConfig(policies=EXPLORATION_ABLATIONS).policies == EXPLORATION_ABLATIONS


def test_an_object_is_reported_once(database):
    policy = make_exploration_policy("random-gaze", database)
    label = "juice_box/2"
    seen = Candidate(label, np.array([1.0, 0.0, 0.8]), np.zeros(2), 20)
    again = Candidate(label, seen.position + [0.5 * same_object_m(label), 0, 0], np.zeros(2), 15)
    other = Candidate(label, seen.position + [2 * same_object_m(label), 0, 0], np.zeros(2), 15)
    assert policy.enqueue([seen]) == 1 and policy.enqueue([again]) == 0
    assert policy.enqueue([other]) == 1
    first = policy._action(np.zeros(4))
    assert first["report"]["kind"] == 1 and np.allclose(first["report"]["position"], seen.position)
    assert policy.enqueue([again]) == 0  # reported already


def test_active_vision_halts_after_saccades_without_an_object(database):
    env = _env(scene="simple", saccade_budget=30)
    policy = make_exploration_policy("active-vision", database)
    policy.reset(0)
    obs, _ = env.reset(seed=0)
    policy.database = type(database)(database.feature_type, database.views[:1])  # finds ~nothing
    kinds = []
    for _ in range(30):
        action = policy.act(obs)
        kinds.append(action["report"]["kind"])
        if kinds[-1] == 2:
            break
        obs, *_ = env.step(action)
    env.close()
    assert kinds[-1] == 2, "never halted"
    misses = [f for f in policy.fixations if f.kind in ("salient", "random")]
    assert len(misses) >= HALT_AFTER - 1


def test_a_point_off_the_work_table_is_no_object_there():
    from ipbench.envs.exploration_scene import table_top
    from ipbench.policies.gaze import OBJECT_HEIGHT_M, on_table

    centre, half = table_top()
    assert on_table(centre + [0, 0, 0.1]) and on_table(centre + [half[0], -half[1], 0.0])
    assert not on_table(centre + [0, 0, OBJECT_HEIGHT_M + 0.01])  # above anything on it
    assert not on_table(centre + [half[0] + 0.1, 0, 0.1])  # beside the table
    assert not on_table([10.47, -1.51, -8.11])  # a false correspondence seen in a run


def _explore(name: str, database, steps: int) -> tuple[list[int], list]:
    """The report kinds and fixations of ``name`` on simple seed 0, up to its halt."""
    env = _env(scene="simple", saccade_budget=steps)
    policy = make_exploration_policy(name, database)
    policy.reset(0)
    obs, _ = env.reset(seed=0)
    kinds = []
    for _ in range(steps):
        action = policy.act(obs)
        kinds.append(action["report"]["kind"])
        if kinds[-1] == 2:
            break
        obs, *_ = env.step(action)
    env.close()
    return kinds, policy.fixations


def test_without_its_halting_rule_active_vision_fixates_the_same_and_goes_on(database):
    few = type(database)(database.feature_type, database.views[:1])  # finds ~nothing
    kinds, fixations = _explore("active-vision", few, 14)
    assert kinds[-1] == 2, "active-vision never halted"
    going, going_fixations = _explore("active-vision-no-halt", few, 14)
    assert 2 not in going and len(going) == 14  # explores to the budget
    halt = len(kinds) - 1
    assert [f.axis for f in going_fixations[: halt + 1]] == [f.axis for f in fixations]
    assert [f.kind for f in going_fixations[:halt]] == [f.kind for f in fixations[:halt]]
    assert fixations[halt].kind == "halt" != going_fixations[halt].kind
