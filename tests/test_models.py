"""Every model file compiles, steps without MuJoCo warnings, and every joint moves in its limits."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from ipbench.assets import ASSETS_DIR, compose

MODEL_FILES = [
    "motoman/ma1400.xml",
    "motoman/gripper.xml",
    "motoman/xtion.xml",
    "motoman/motoman.xml",
    "head/ptu_d46.xml",
]


def _step_clean(model: mujoco.MjModel, seconds: float = 0.5) -> mujoco.MjData:
    data = mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    for _ in range(int(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)
    assert np.all(np.isfinite(data.qpos))
    assert not [w for w in data.warning if w.number], "MuJoCo warnings while stepping"
    return data


@pytest.mark.parametrize("path", MODEL_FILES)
def test_model_file_compiles_and_steps(path):
    model = mujoco.MjModel.from_xml_path(str(ASSETS_DIR / path))
    _step_clean(model)


def test_every_model_file_is_tested():
    shipped = {str(p.relative_to(ASSETS_DIR)) for p in ASSETS_DIR.glob("*/*.xml")}
    assert shipped == set(MODEL_FILES) | {"scenes/workcell.xml"}


def test_workcell_compiles_with_named_parts():
    model = compose.build_workcell_spec().compile()
    _step_clean(model)
    for name in (
        "left_joint_s",
        "right_joint_t",
        "turntable_joint",
        "head_left_pan",
        "head_right_tilt",
        "left_gripper_finger_a",
    ):
        model.joint(name)
    for cam in ("right_wrist_camera", "head_left_camera", "head_right_camera", "overview"):
        model.camera(cam)
    for site in ("left_gripper_tcp", "right_wrist_optical", "inspection_area", "bin_mug"):
        model.site(site)


def test_visual_and_collision_classes_are_separate():
    model = compose.build_workcell_spec().compile()
    for g in range(model.ngeom):
        if model.geom_group[g] == 2:  # visual
            assert model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0
        if model.geom_group[g] == 3:  # collision: hidden from cameras
            assert model.geom_contype[g] or model.geom_conaffinity[g]


def test_flange_matches_clopema_forward_kinematics():
    """At q = 0 the left flange is where CloPeMa's URDF puts r2's (``clopema_UG.urdf.xacro``)."""
    model = compose.build_robot_spec().compile()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    # r2 flange in CloPeMa's base frame (0.525, -0.82, 1.709) -> ours: x forward, y left.
    np.testing.assert_allclose(data.site("left_flange").xpos, [0.82, 0.525, 1.709], atol=2e-3)
    np.testing.assert_allclose(data.site("right_flange").xpos, [0.82, -0.525, 1.709], atol=2e-3)


def test_every_actuated_joint_moves_within_its_limits():
    model = compose.build_robot_spec().compile()
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT  # joint travel, not collisions
    data = mujoco.MjData(model)
    dt = model.opt.timestep
    for a in range(model.nu):
        j = model.actuator_trnid[a, 0]
        adr = model.jnt_qposadr[j]
        lo, hi = model.jnt_range[j]
        for goal in (lo + 0.1 * (hi - lo), hi - 0.1 * (hi - lo)):
            mujoco.mj_resetData(model, data)
            start = data.qpos[adr]
            for k in range(1, 751):  # 1.5 s quintic-free ramp, then 0.5 s hold
                s = min(1.0, k / 500)
                data.ctrl[a] = start + (goal - start) * s
                mujoco.mj_step(model, data)
                assert lo - 1e-3 <= data.qpos[adr] <= hi + 1e-3, model.joint(j).name
            assert abs(data.qpos[adr] - goal) < 0.01, (model.joint(j).name, data.qpos[adr], goal)
    assert dt > 0
