"""The in-hand ablation: its rows, each factor's switch on a real capture, and its scoring."""

from __future__ import annotations

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from exports import assert_exports

import ipbench.envs  # noqa: F401  (registers the ids)
from ipbench.assets.objects import CATEGORIES, instances
from ipbench.eval.capture import hand_views
from ipbench.eval.capture.dataset import DatasetConfig, InHandAblationConfig
from ipbench.eval.capture.hand_factors import (
    IN_HAND_FACTORS,
    gripper_pixels,
    ideal_view,
    object_pixels,
    view_from_distance,
)
from ipbench.eval.perception.evaluate import PerceptionEvalConfig
from ipbench.eval.perception.in_hand_ablation import (
    IN_HAND_ABLATION_PROTOCOL,
    IN_HAND_ROWS,
    ablation_dataset,
)
from ipbench.perception.cloud import depth_to_points
from ipbench.perception.viewset import ViewSet
from ipbench.policies import EVAL_CAMERAS
from ipbench.policies.kinematics import HandKinematics

V2 = DatasetConfig(env_id="ipbench/Sorting-v2", in_hand_views=2, in_hand_placements=1)


@pytest.mark.parametrize(
    "name",
    [
        "ipbench.eval.capture.hand_factors",
        "ipbench.eval.perception.in_hand_ablation",
        "ipbench.eval.perception.in_hand_report",
    ],
)
def test_export_lists_name_the_public_definitions(name):
    assert_exports(name)


def test_the_ablation_lists_every_factor_and_captures_each_apart():
    assert IN_HAND_ROWS == ("baseline", "true_mask", "no_jaws", "ideal_depth", "table_distance")
    assert IN_HAND_ROWS[1:] == IN_HAND_FACTORS
    configs = {row: ablation_dataset(V2, row) for row in IN_HAND_ROWS}
    assert len({c.key() for c in configs.values()}) == len(IN_HAND_ROWS)
    for row, config in configs.items():
        assert config.in_hand_removed == (None if row == "baseline" else row)
        assert config.in_hand_views == IN_HAND_ABLATION_PROTOCOL["in_hand_views"] > 0
        assert config.per_category == IN_HAND_ABLATION_PROTOCOL["per_category"]
    # as captured, the ablation's baseline shares the cache of the plain capture
    plain = DatasetConfig(**{f: getattr(configs["baseline"], f) for f in V2.__dataclass_fields__})
    assert configs["baseline"].key() == plain.key()
    # a plain DatasetConfig (models, sorting fingerprints) has no new field
    assert "in_hand_removed" not in DatasetConfig.__dataclass_fields__
    with pytest.raises(ValueError, match="valid: baseline, true_mask"):
        ablation_dataset(V2, "no_gripper")
    with pytest.raises(ValueError, match="valid: None .*true_mask, no_jaws"):
        InHandAblationConfig(env_id="ipbench/Sorting-v2", in_hand_removed="jaws")


@pytest.fixture(scope="module")
def presented():
    """A v2 juice box held up to the wrist camera: (env, obs, info) after one presentation."""
    inst = instances(catalog="v2", family="brik_200")[0]
    env = gym.make(V2.env_id, depth_noise=V2.sensor, cameras=EVAL_CAMERAS)
    _, info = env.reset(seed=3, options={"layout": hand_views._layout(inst, "upright", 0.0)})
    quat, size = info["objects"][0]["pose"][3:], inst.size
    from ipbench.policies.grasping.boxes import grasp_point, grasp_yaws, jaw_span

    yaw = grasp_yaws(quat, size, round_=False)[0]
    action = {
        "command": 2,
        "position": grasp_point(info["objects"][0]["center"], quat, size).astype(np.float32),
        "yaw": np.array([yaw], np.float32),
        "bin": 0,
        "opening": np.array([jaw_span(quat, size, yaw)], np.float32),
    }
    obs, _, _, _, info = env.step(action)
    assert all(s["success"] for s in info["skills"])
    yield env, obs, info
    env.close()


def _cloud(obs):
    return depth_to_points(obs["wrist_depth"], obs["wrist_K"], obs["wrist_pose"])


def test_true_mask_takes_the_simulator_mask(presented):
    env, obs, info = presented
    mask = info["wrist_mask"].reshape(-1)
    cloud = _cloud(obs)
    held = object_pixels(cloud, info["wrist_mask"], 0)
    assert len(held) > 500 and (mask[held.pixels] == 0).all()
    assert len(held) == int((mask[cloud.pixels] == 0).sum())  # every object pixel with depth
    view = hand_views._view(env, obs, info, HandKinematics(), V2, "true_mask")
    np.testing.assert_array_equal(view[1], held.points)
    baseline = hand_views._view(env, obs, info, HandKinematics(), V2, None)
    assert len(baseline[1]) != len(view[1])  # the in-hand segmentation gives another set


def test_no_jaws_drops_every_gripper_point(presented):
    env, obs, info = presented
    grip = gripper_pixels(env)
    assert grip.shape == (obs["wrist_depth"].size,)
    cloud = _cloud(obs)
    assert grip[cloud.pixels].sum() > 1000  # the jaws are in view, with depth
    # the gripper pixels are those the simulator draws with a gripper geom, nothing else
    assert not grip[info["wrist_mask"].reshape(-1) == 0].any()
    captured = []
    real = hand_views.segment_in_hand

    def spy(c, *args, **kwargs):
        captured.append(c)
        return real(c, *args, **kwargs)

    mp = pytest.MonkeyPatch()
    mp.setattr(hand_views, "segment_in_hand", spy)
    try:
        view = hand_views._view(env, obs, info, HandKinematics(), V2, "no_jaws")
    finally:
        mp.undo()
    assert view is not None and len(captured) == 1
    assert len(captured[0]) == len(cloud) - grip[cloud.pixels].sum()
    assert not grip[captured[0].pixels].any()  # no point of the jaws reaches the segmentation


def test_ideal_depth_has_no_sensor_noise(presented):
    env, obs, _ = presented
    base = env.unwrapped
    ideal = ideal_view(env, obs)["wrist_depth"]
    h, w = ideal.shape
    raw = base.renderer.render_rgbd(base.data, "right_wrist_camera", w, h)[1]
    lo, hi = base.config.depth_noise.min_range_m, base.config.depth_noise.max_range_m
    inside = (raw >= lo) & (raw <= hi)
    np.testing.assert_array_equal(ideal[inside], raw[inside].astype(np.float32))
    assert (ideal[~inside] == 0).all()
    seen = (obs["wrist_depth"] > 0) & inside
    assert np.abs(obs["wrist_depth"][seen] - ideal[seen]).max() > 1e-3  # the sensor is noisy


def test_table_distance_moves_the_camera_and_puts_the_state_back(presented):
    env, obs, info = presented
    base = env.unwrapped
    center = info["objects"][0]["center"]
    qpos, stream = base.data.qpos.copy(), base.np_random.bit_generator.state
    moved = view_from_distance(env, center, 0.75)
    assert moved is not None
    assert np.linalg.norm(moved["wrist_pose"][:3, 3] - center) == pytest.approx(0.75, abs=0.005)
    before = np.linalg.norm(obs["wrist_pose"][:3, 3] - center)
    assert before < 0.7  # held closer than the table-top views are taken
    forward = moved["wrist_pose"][:3, 2]  # the optical axis still points at the object
    ray = center - moved["wrist_pose"][:3, 3]
    assert forward @ ray / np.linalg.norm(ray) > 0.99
    np.testing.assert_array_equal(base.data.qpos, qpos)
    assert base.np_random.bit_generator.state == stream
    seg = hand_views._view(env, obs, info, HandKinematics(), V2, "table_distance")
    near = hand_views._view(env, obs, info, HandKinematics(), V2, None)
    assert 0 < len(seg[1]) < len(near[1])  # farther away: fewer points on the object


def test_one_pass_gives_every_row_and_the_plain_capture():
    inst = instances(catalog="v2", family="gable_1l")[0]
    rows = hand_views.render_in_hand_factors(inst, V2, (None, *IN_HAND_FACTORS))
    assert set(rows) == {None, *IN_HAND_FACTORS}
    plain = hand_views.render_in_hand_views(inst, V2)
    np.testing.assert_array_equal(rows[None].descriptors, plain.descriptors)
    for factor in IN_HAND_FACTORS:
        assert len(rows[factor]) > 0 and set(rows[factor].instance) == {inst.name}
        assert not np.array_equal(rows[factor].descriptors, plain.descriptors)
    one = InHandAblationConfig(**{**V2.__dict__, "in_hand_removed": "true_mask"})
    alone = hand_views.render_in_hand_views(inst, one)
    np.testing.assert_array_equal(alone.descriptors, rows["true_mask"].descriptors)


def _fake_views(dataset, seed: int) -> ViewSet:
    """Separable in-hand views of every chosen instance (3 per instance)."""
    rng = np.random.default_rng(seed)
    sets = []
    for inst in dataset.chosen_instances():
        label = CATEGORIES.index(inst.category)
        for _ in range(3):
            desc = rng.normal(label, 0.2, (20, 33)).astype(np.float32)
            sets.append(ViewSet.from_views([desc], [label], [inst.name], [inst.known], "in_hand"))
    return ViewSet.concat(sets)


def test_capture_renders_each_instance_once_for_every_row(tmp_path, monkeypatch):
    import ipbench.eval.perception.in_hand_ablation as ablation

    small = DatasetConfig(env_id="ipbench/Sorting-v2")
    calls = []

    def fake_rows(inst, config, factors):
        calls.append((inst.name, factors))
        out = {}
        for k, f in enumerate(factors):
            label = CATEGORIES.index(inst.category)
            desc = np.full((5, 33), k, np.float32)
            out[f] = ViewSet.from_views([desc], [label], [inst.name], [inst.known], "in_hand")
        return out

    monkeypatch.setattr(ablation, "render_in_hand_rows", fake_rows)
    rows = ablation.capture_rows(tmp_path, small, workers=1, progress=False)
    n = len(ablation_dataset(small, "baseline").chosen_instances())
    assert len(calls) == n and all(f == (None, *IN_HAND_FACTORS) for _, f in calls)
    assert list(rows) == list(IN_HAND_ROWS)
    for k, row in enumerate(IN_HAND_ROWS):  # each row's views are its own
        assert len(rows[row]) == n and (rows[row].descriptors == k).all()
    ablation.capture_rows(tmp_path, small, workers=1, progress=False)
    assert len(calls) == n  # cached: nothing captured again


def test_ablation_scores_every_row_per_split(tmp_path, monkeypatch):
    import ipbench.eval.perception.in_hand_ablation as ablation

    config = PerceptionEvalConfig.for_env("ipbench/Sorting-v2", codebook_size=8)
    assert config.ablation  # the benchmark runs it on v2

    def fake_capture(cache, dataset, workers=2, progress=True):
        return {r: _fake_views(ablation_dataset(dataset, r), k) for k, r in enumerate(IN_HAND_ROWS)}

    def fake_build(cache, dataset, **_):  # the table-top views the codebook is fitted on
        views = _fake_views(dataset, 99)
        return ViewSet(**{**views.__dict__, "source": np.full(len(views), "isolated", "U16")})

    monkeypatch.setattr(ablation, "capture_rows", fake_capture)
    monkeypatch.setattr(ablation, "load_or_build", fake_build)
    result = ablation.in_hand_ablation(tmp_path, config, progress=False)
    assert list(result) == list(IN_HAND_ROWS)
    for row in IN_HAND_ROWS:
        assert "pointnet_ensemble" not in result[row]  # too few views for a network
        m = result[row]["gp"]
        assert m["train_n"] == 3 * 15 and m["n"] == 3 * 30
        assert m["similar_n"] == m["novel_n"] == 3 * 15
        for key in ("accuracy", "similar_accuracy", "novel_accuracy"):
            assert 0 <= m[key] <= 1
        assert m["accuracy"] == pytest.approx((m["similar_accuracy"] + m["novel_accuracy"]) / 2)


def test_gripper_geoms_are_the_palm_and_fingers():
    from ipbench.eval.capture.hand_factors import gripper_geoms

    env = gym.make(V2.env_id, cameras=EVAL_CAMERAS)
    env.reset(seed=0)
    model = env.unwrapped.model
    geoms = gripper_geoms(model)
    assert geoms.shape == (model.ngeom + 1,) and not geoms[-1]
    bodies = {model.body(b).name for b in model.geom_bodyid[geoms[:-1]]}
    assert bodies == {"left_gripper_palm", "left_gripper_finger_a", "left_gripper_finger_b"}
    pads = [
        mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"left_gripper_pad_{s}") for s in "ab"
    ]
    assert all(geoms[p] for p in pads)
    env.close()
