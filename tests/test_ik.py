"""mink IK reaches poses over the table and the bins to < 5 mm (checked by forward kinematics)."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from ipbench.envs.ik import ArmIK, look_at_rotation, tool_down_rotation
from ipbench.envs.robot import PlanningError, RobotController, ik_model
from ipbench.envs.skills import Skills
from ipbench.envs.world import Places


@pytest.fixture(scope="module")
def planner():
    """The skills' planner on the kinematic work cell, starting at CloPeMa home."""
    model = ik_model()
    data = mujoco.MjData(model)
    robot = RobotController(model, data, step=lambda: mujoco.mj_step(model, data))
    places = Places.from_model(model)
    return Skills(robot, places), places


def _fk(model, q, site):
    data = mujoco.MjData(model)
    data.qpos[:] = q
    mujoco.mj_kinematics(model, data)
    return data.site(site).xpos.copy(), data.site(site).xmat.reshape(3, 3).copy()


def _targets(places: Places, skills: Skills):
    """Grasp and transit heights over the spawn area (whose objects' centres lie at least
    3.5 cm inside its edge), over the inspection area, and release points over every bin."""
    table, area = places.spawn_area, places.inspection_area
    half = table.half - np.array([0.035, 0.035, 0.0])
    pts = [
        table.center + np.array([dx * half[0], dy * half[1], dz])
        for dx in (-1, 0, 1)
        for dy in (-1, 0, 1)
        for dz in (0.05, skills.config.transit_height)
    ]
    pts.append(area.center + np.array([0, 0, 0.1]))
    for box in places.bins.values():
        pts.append(box.center + np.array([0, 0, box.half[2] + 0.2]))
    return pts


def test_gripper_reaches_table_and_bins(planner):
    skills, places = planner
    model = ik_model()
    for k, p in enumerate(_targets(places, skills)):
        yaw = -1.2 + 0.3 * (k % 8)
        result = skills.tool_pose(p[:2], p[2], yaw)
        pos, rot = _fk(model, result.q, "left_gripper_tcp")
        assert np.linalg.norm(pos - p) < 5e-3, (p, pos)
        # the tool points down with the jaws along the yaw (mod 180 deg)
        assert rot[2, 2] < -0.999
        assert abs(abs(rot[:, 0] @ [np.cos(yaw), np.sin(yaw), 0]) - 1) < 1e-3
        for j, q in zip(result.joints, result.qpos, strict=True):
            lo, hi = model.jnt_range[model.joint(j).id]
            assert lo - 1e-6 <= q <= hi + 1e-6


def test_camera_looks_at_the_scene_and_the_hand(planner):
    skills, places = planner
    robot = skills.robot
    model = ik_model()
    for eye, target in (
        (places.scene_view, places.scene_target),
        (places.present_view, places.present_point),
        (places.inspection_view, places.inspection_area.center),
    ):
        result = robot.solve(
            robot.camera_ik, eye, look_at_rotation(eye, target), seeds=(skills.camera_ready,)
        )
        pos, rot = _fk(model, result.q, "right_wrist_optical")
        assert np.linalg.norm(pos - eye) < 5e-3
        forward = -rot[:, 2]
        want = (target - eye) / np.linalg.norm(target - eye)
        assert np.degrees(np.arccos(np.clip(forward @ want, -1, 1))) < 1.0


def test_unreachable_pose_is_reported(planner):
    skills, _ = planner
    with pytest.raises(PlanningError, match="cannot reach"):
        skills.tool_pose((3.0, 0.0), 0.8, 0.0)


def test_look_at_rotation_is_a_rotation():
    r = look_at_rotation(np.zeros(3), np.array([1.0, 0.5, -0.7]))
    np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
    assert np.isclose(np.linalg.det(r), 1.0)
    r = look_at_rotation(np.zeros(3), np.array([0, 0, -1.0]))  # straight down
    np.testing.assert_allclose(-r[:, 2], [0, 0, -1], atol=1e-12)


def test_arm_ik_freezes_other_joints():
    model = ik_model()
    ik = ArmIK(
        model,
        "left_gripper_tcp",
        [
            "left_joint_s",
            "left_joint_l",
            "left_joint_u",
            "left_joint_r",
            "left_joint_b",
            "left_joint_t",
        ],
    )
    q0 = model.qpos0.copy()
    result = ik.solve(q0, np.array([0.9, 0.0, 0.9]), tool_down_rotation(0.2))
    moved = np.flatnonzero(np.abs(result.q - q0) > 1e-9)
    allowed = {model.jnt_qposadr[model.joint(j).id] for j in result.joints}
    assert set(moved) <= allowed and result.converged
