"""Object status (ground truth for info) follows where objects physically are."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from ipbench.envs.layout import sample_layout
from ipbench.envs.robot import ik_model
from ipbench.envs.world import STATUSES, Places, build_world, object_status


@pytest.fixture(scope="module")
def world():
    places = Places.from_model(ik_model())
    area = places.spawn_area
    lay = sample_layout("uncluttered", 0, area.center, area.half, places.table_height)
    return build_world(lay)


def _pads(model):
    return model.geom("left_gripper_pad_a").id, model.geom("left_gripper_pad_b").id


def _move(world, data, k, pos):
    adr = world.model.jnt_qposadr[world.model.body_jntadr[world.object_bodies[k]]]
    data.qpos[adr : adr + 3] = pos
    mujoco.mj_forward(world.model, data)


def test_home_keyframe_points_the_head_at_the_table(world):
    model = world.model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    for side in ("left", "right"):
        cam = data.cam(f"head_{side}_camera")
        forward = -cam.xmat.reshape(3, 3)[:, 2]
        want = world.places.head_target - cam.xpos
        angle = np.degrees(np.arccos(forward @ want / np.linalg.norm(want)))
        assert angle < 3.0, (side, angle)
    np.testing.assert_allclose(
        data.ctrl,
        [data.qpos[model.jnt_qposadr[model.actuator_trnid[a, 0]]] for a in range(model.nu)],
    )


def test_statuses_follow_positions(world):
    model = world.model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    mujoco.mj_forward(model, data)
    pads = _pads(model)
    assert all(object_status(world, data, k, pads) == "on_table" for k in range(10))
    bins = world.places.bins
    _move(world, data, 0, bins["mug"].center)
    assert object_status(world, data, 0, pads) == "in_bin:mug"
    area = world.places.inspection_area.center
    _move(world, data, 1, area + [0, 0, 0.01])
    assert object_status(world, data, 1, pads) == "in_inspection_area"
    _move(world, data, 2, [2.0, 2.0, 0.05])
    assert object_status(world, data, 2, pads) == "dropped"
    for k in range(10):
        assert object_status(world, data, k, pads) in STATUSES


def test_object_geoms_map_to_their_objects(world):
    model = world.model
    for g, k in world.object_geoms.items():
        assert model.body_rootid[model.geom_bodyid[g]] == world.object_bodies[k]
    assert set(world.object_geoms.values()) == set(range(len(world.layout.objects)))
