"""The true model differs from the nominal one (envs/cell/model_errors.py): exact kinematics of
every error, the sampler against ERROR_SCALES, the scales against their sources, bad input."""

from __future__ import annotations

import json
import math
import warnings

import mujoco
import numpy as np
import pytest

from ipbench.assets.compose import build_workcell_spec
from ipbench.envs.cell.model_errors import (
    CAMERA_MOUNTS,
    ERROR_SCALES,
    MARKER_TEXT,
    MOUNTS,
    PTU_BASE_MOUNTS,
    ModelErrors,
    ModelErrorsError,
    MountError,
    PtuErrors,
    apply_model_errors,
    sample_model_errors,
)
from ipbench.envs.sensors import camera_pose
from ipbench.envs.sensors.lens_distortion import D5100_35MM, XTION_RGB, LensDistortion

CAMERAS = {"wrist_camera": "right_wrist_camera"} | {
    f"head_{s}_camera": f"head_{s}_camera" for s in ("left", "right")
}
PTU_JOINTS = [f"head_{s}_{a}" for s in ("left", "right") for a in ("pan", "tilt")]


@pytest.fixture(scope="module")
def nominal() -> mujoco.MjModel:
    return build_workcell_spec().compile()


def true_model(errors: ModelErrors) -> mujoco.MjModel:
    spec = build_workcell_spec()
    apply_model_errors(spec, errors)
    return spec.compile()


def random_qpos(model: mujoco.MjModel, rng: np.random.Generator) -> np.ndarray:
    """Every joint uniform within its range (all joints of the work cell are limited)."""
    return np.array([rng.uniform(*model.jnt_range[j]) for j in range(model.njnt)])


def forward(model: mujoco.MjModel, qpos: np.ndarray) -> mujoco.MjData:
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    return data


def body_pose(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> np.ndarray:
    pose = np.eye(4)
    bid = model.body(name).id
    pose[:3, :3], pose[:3, 3] = data.xmat[bid].reshape(3, 3), data.xpos[bid]
    return pose


def site_pose_cv(model: mujoco.MjModel, data: mujoco.MjData, name: str) -> np.ndarray:
    """A site's world pose with its axes flipped as camera_pose flips a camera's."""
    pose = np.eye(4)
    sid = model.site(name).id
    pose[:3, :3] = data.site_xmat[sid].reshape(3, 3) * [1.0, -1.0, -1.0]
    pose[:3, 3] = data.site_xpos[sid]
    return pose


def with_ptu_offsets(model: mujoco.MjModel, qpos: np.ndarray, errors: ModelErrors) -> np.ndarray:
    """qpos with each PTU joint moved by its zero offset (the true angle for encoder qpos)."""
    out = qpos.copy()
    for name in PTU_JOINTS:
        side, axis = name.split("_")[1:]
        out[model.joint(name).qposadr[0]] += errors.ptu(side).zero_offset[
            ("pan", "tilt").index(axis)
        ]
    return out


ERROR = MountError(translation=(0.003, -0.002, 0.004), rotation=(0.004, -0.003, 0.005))


def test_zero_errors_give_exactly_the_nominal_model(nominal):
    true = true_model(ModelErrors.none())
    rng = np.random.default_rng(0)
    for _ in range(5):
        q = random_qpos(nominal, rng)
        dn, dt = forward(nominal, q), forward(true, q)
        for cam in range(nominal.ncam):
            np.testing.assert_array_equal(camera_pose(true, dt, cam), camera_pose(nominal, dn, cam))
        np.testing.assert_array_equal(dt.xpos, dn.xpos)
        np.testing.assert_array_equal(dt.xquat, dn.xquat)
    assert ModelErrors() == ModelErrors.none()
    assert all(m.is_zero for m in ModelErrors.none().mounts.values())


@pytest.mark.parametrize("mount", CAMERA_MOUNTS)
def test_a_camera_mount_error_moves_its_camera_by_exactly_that_transform(nominal, mount):
    true = true_model(ModelErrors(**{mount: ERROR}))
    rng = np.random.default_rng(1)
    for _ in range(5):
        q = random_qpos(nominal, rng)
        dn, dt = forward(nominal, q), forward(true, q)
        expected = camera_pose(nominal, dn, CAMERAS[mount]) @ ERROR.matrix
        np.testing.assert_allclose(camera_pose(true, dt, CAMERAS[mount]), expected, atol=1e-9)
        for other in set(CAMERAS) - {mount}:  # the other cameras do not move at all
            np.testing.assert_array_equal(
                camera_pose(true, dt, CAMERAS[other]), camera_pose(nominal, dn, CAMERAS[other])
            )
        if mount == "wrist_camera":  # the whole Xtion moves: its optical site went along
            expected = site_pose_cv(nominal, dn, "right_wrist_optical") @ ERROR.matrix
            np.testing.assert_allclose(
                site_pose_cv(true, dt, "right_wrist_optical"), expected, atol=1e-9
            )
            assert (
                np.abs(
                    dt.xpos[true.body("right_wrist_body").id]
                    - dn.xpos[nominal.body("right_wrist_body").id]
                ).max()
                > 1e-3
            )


@pytest.mark.parametrize("side", ["left", "right"])
def test_a_ptu_base_error_moves_the_unit_by_exactly_that_transform(nominal, side):
    base = f"head_{side}_base"
    true = true_model(ModelErrors(**{base: ERROR}))
    other = "right" if side == "left" else "left"
    rng = np.random.default_rng(2)
    for _ in range(5):
        q = random_qpos(nominal, rng)
        dn, dt = forward(nominal, q), forward(true, q)
        b_nom = body_pose(nominal, dn, base)
        np.testing.assert_allclose(body_pose(true, dt, base), b_nom @ ERROR.matrix, atol=1e-9)
        # the camera keeps its pose in the base frame: world = base_true @ base_nom^-1 @ cam_nom
        cam = f"head_{side}_camera"
        expected = b_nom @ ERROR.matrix @ np.linalg.inv(b_nom) @ camera_pose(nominal, dn, cam)
        np.testing.assert_allclose(camera_pose(true, dt, cam), expected, atol=1e-9)
        np.testing.assert_array_equal(
            camera_pose(true, dt, f"head_{other}_camera"),
            camera_pose(nominal, dn, f"head_{other}_camera"),
        )


def test_ptu_zero_offsets_act_as_pan_and_tilt_rotations(nominal):
    errors = ModelErrors(
        head_left_ptu=PtuErrors(zero_offset=(0.01, -0.02)),
        head_right_ptu=PtuErrors(zero_offset=(-0.015, 0.005)),
    )
    true = true_model(errors)
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = random_qpos(nominal, rng)  # the true model's qpos is what the encoders read
        dn, dt = forward(nominal, with_ptu_offsets(nominal, q, errors)), forward(true, q)
        for side in ("left", "right"):
            cam = f"head_{side}_camera"
            np.testing.assert_allclose(
                camera_pose(true, dt, cam), camera_pose(nominal, dn, cam), atol=1e-9
            )
    # encoder units are kept: limits, qpos0 and actuators act on the encoder reading
    for name in PTU_JOINTS:
        np.testing.assert_array_equal(true.joint(name).range, nominal.joint(name).range)
    np.testing.assert_array_equal(true.qpos0, nominal.qpos0)
    # the offset is a real rotation: at encoder zero the camera looks elsewhere than nominal
    d0n, d0t = forward(nominal, nominal.qpos0), forward(true, true.qpos0)
    r = (
        camera_pose(true, d0t, "head_left_camera")[:3, :3].T
        @ camera_pose(nominal, d0n, "head_left_camera")[:3, :3]
    )
    angle = math.acos(np.clip((np.trace(r) - 1) / 2, -1, 1))
    assert angle == pytest.approx(math.hypot(0.01, 0.02), rel=0.01)


def test_all_errors_compose(nominal):
    errors = sample_model_errors(11)
    true = true_model(errors)
    rng = np.random.default_rng(4)
    for _ in range(5):
        q = random_qpos(nominal, rng)
        dn, dt = forward(nominal, with_ptu_offsets(nominal, q, errors)), forward(true, q)
        expected = camera_pose(nominal, dn, "right_wrist_camera") @ errors.wrist_camera.matrix
        np.testing.assert_allclose(camera_pose(true, dt, "right_wrist_camera"), expected, atol=1e-9)
        for side in ("left", "right"):
            b = body_pose(nominal, dn, f"head_{side}_base")
            cam = f"head_{side}_camera"
            e_base, e_cam = errors.mounts[f"head_{side}_base"].matrix, errors.mounts[cam].matrix
            expected = b @ e_base @ np.linalg.inv(b) @ camera_pose(nominal, dn, cam) @ e_cam
            np.testing.assert_allclose(camera_pose(true, dt, cam), expected, atol=1e-9)


def test_the_errored_model_compiles_and_steps_without_warnings():
    for seed in (0, 1):
        spec = build_workcell_spec()
        apply_model_errors(spec, sample_model_errors(seed))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            model = spec.compile()
            data = mujoco.MjData(model)
            mujoco.mj_forward(model, data)
            data.ctrl[:] = 0.0
            for _ in range(250):
                mujoco.mj_step(model, data)
        assert all(int(w.number) == 0 for w in data.warning), list(data.warning.number)
        assert np.isfinite(data.qpos).all() and np.abs(data.qvel).max() < 1.0
        stored = json.loads(spec.text(MARKER_TEXT).data)
        assert stored == sample_model_errors(seed).as_dict()


def test_sampling_is_deterministic_and_uses_its_own_stream():
    state = np.random.get_state()[1].copy()  # noqa: NPY002 (the global legacy stream)
    a, b, c = sample_model_errors(5), sample_model_errors(5), sample_model_errors(6)
    np.testing.assert_array_equal(np.random.get_state()[1], state)  # noqa: NPY002
    assert a == b and a != c
    assert sample_model_errors(np.int64(5)) == a
    # lenses are the documented presets, not drawn
    assert a.distortion == {
        "right_wrist_camera": XTION_RGB,
        "head_left_camera": D5100_35MM,
        "head_right_camera": D5100_35MM,
    }


def test_sampled_spread_matches_error_scales():
    draws = [sample_model_errors(seed) for seed in range(300)]

    def spread(values, key):
        values = np.asarray(values, float).ravel()
        sigma = ERROR_SCALES[key].value
        assert ERROR_SCALES[key].kind == "sigma"
        assert np.std(values) == pytest.approx(sigma, rel=0.1), key
        assert abs(np.mean(values)) < 4 * sigma / math.sqrt(values.size), key

    spread(
        [[d.mounts[m].translation for m in CAMERA_MOUNTS] for d in draws],
        "camera_mount_translation",
    )
    spread([[d.mounts[m].rotation for m in CAMERA_MOUNTS] for d in draws], "camera_mount_rotation")
    spread(
        [[d.mounts[m].translation for m in PTU_BASE_MOUNTS] for d in draws], "ptu_base_translation"
    )
    spread([[d.mounts[m].rotation for m in PTU_BASE_MOUNTS] for d in draws], "ptu_base_rotation")
    spread([[d.ptu(s).zero_offset for s in ("left", "right")] for d in draws], "ptu_zero_offset")
    spread([d.depth_registration_px for d in draws], "depth_registration")
    backlash = np.array([[d.ptu(s).backlash for s in ("left", "right")] for d in draws]).ravel()
    top = ERROR_SCALES["ptu_backlash"].value
    assert ERROR_SCALES["ptu_backlash"].kind == "max"
    assert backlash.min() >= 0 and backlash.max() <= top
    assert backlash.mean() == pytest.approx(top / 2, rel=0.1)
    assert set(ModelErrors.none().mounts) == set(MOUNTS) == set(draws[0].mounts)


def test_error_scales_follow_their_sources():
    for key, scale in ERROR_SCALES.items():
        assert scale.value > 0 and scale.unit in ("m", "rad", "px") and scale.source, key
    # chosen hand-eye mounting error: "a few mm and tenths of a degree" (mean magnitude of a
    # 3-D normal vector = 2 sqrt(2 / pi) sigma)
    mean_norm = 2.0 * math.sqrt(2.0 / math.pi)
    assert 2e-3 <= mean_norm * ERROR_SCALES["camera_mount_translation"].value <= 5e-3
    assert 0.1 <= math.degrees(mean_norm * ERROR_SCALES["camera_mount_rotation"].value) < 1.0
    # CloPeMa description (gerac83/ug_bluerobot): Glasgow right PTU vs left, nominal
    # (0, -0.30, 0) m, rpy 0; calibrated (0.041, -0.285, 0.004) m, rpy (-2.7, 0.3, -1.7) deg:
    # per-axis RMS of the relative error, shared by two independent bases
    rms_m = math.sqrt((0.041**2 + 0.015**2 + 0.004**2) / 3)
    rms_deg = math.sqrt((2.7**2 + 0.3**2 + 1.7**2) / 3)
    assert ERROR_SCALES["ptu_base_translation"].value == pytest.approx(rms_m / math.sqrt(2))
    assert math.degrees(ERROR_SCALES["ptu_base_rotation"].value) == pytest.approx(
        rms_deg / math.sqrt(2)
    )
    assert ERROR_SCALES["ptu_base_translation"].value == pytest.approx(0.0179, abs=1e-4)
    # PTU-D46: 185.1428 arc-sec per position (manual §4.3.3); chosen two positions
    for key in ("ptu_zero_offset", "ptu_backlash"):
        assert ERROR_SCALES[key].value == pytest.approx(2 * math.radians(185.1428 / 3600))
    # depth registration: "a few pixels", below the uncorrected (5, 4) px depth/IR shift
    sigma_px = ERROR_SCALES["depth_registration"].value
    assert 1.0 <= sigma_px * math.sqrt(math.pi / 2) <= 4.0 and 2 * sigma_px < 5.0


def test_applying_twice_or_to_another_spec_is_refused():
    spec = build_workcell_spec()
    apply_model_errors(spec, ModelErrors.none())
    with pytest.raises(ModelErrorsError, match="already applied"):
        apply_model_errors(spec, ModelErrors.none())
    bare = mujoco.MjSpec.from_string("<mujoco><worldbody/></mujoco>")
    with pytest.raises(ModelErrorsError, match="not the composed work cell.*build_workcell_spec"):
        apply_model_errors(bare, sample_model_errors(0))
    assert bare.text(MARKER_TEXT) is None  # nothing was changed
    with pytest.raises(ModelErrorsError, match="mujoco.MjSpec"):
        apply_model_errors(None, ModelErrors.none())
    with pytest.raises(ModelErrorsError, match="ModelErrors"):
        apply_model_errors(build_workcell_spec(), {})


def test_bad_errors_are_refused_with_what_was_wrong():
    with pytest.raises(ModelErrorsError, match="translation .* 3 finite numbers"):
        MountError(translation=(0.0, 0.0))
    with pytest.raises(ModelErrorsError, match="rotation .* 3 finite numbers"):
        MountError(rotation=(0.0, np.nan, 0.0))
    with pytest.raises(ModelErrorsError, match="dead band"):
        PtuErrors(backlash=(-1e-3, 0.0))
    with pytest.raises(ModelErrorsError, match="wrist_camera must be a MountError"):
        ModelErrors(wrist_camera=(0.0, 0.0, 0.0))
    with pytest.raises(ModelErrorsError, match="head_left_distortion must be a LensDistortion"):
        ModelErrors(head_left_distortion=(0.1, 0.0, 0.0, 0.0, 0.0))
    with pytest.raises(ModelErrorsError, match="depth_registration_px"):
        ModelErrors(depth_registration_px=(1.0, "x"))
    with pytest.raises(ModelErrorsError, match=r"valid: \['left', 'right'\]"):
        ModelErrors.none().ptu("middle")
    for seed in (-1, True, 1.5, "3"):
        with pytest.raises(ModelErrorsError, match="non-negative int"):
            sample_model_errors(seed)
    assert ModelErrors(head_left_distortion=LensDistortion(k1=0.1)).distortion[
        "head_left_camera"
    ] == LensDistortion(k1=0.1)
