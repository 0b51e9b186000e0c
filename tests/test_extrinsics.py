"""The envs' ``extrinsics`` option: what the robot knows of its cameras."""

from __future__ import annotations

import json

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import ipbench.envs  # noqa: F401  (registers the ids)
from ipbench.assets.compose import build_workcell_spec
from ipbench.envs.cell.extrinsics import (
    EXTRINSICS,
    CameraKnowledge,
    ExtrinsicsError,
    _scaled_K,
    distort_labels,
)
from ipbench.envs.cell.model_errors import ModelErrors, sample_model_errors
from ipbench.envs.exploration import ExplorationEnv
from ipbench.envs.exploration_scene import build_model, sample_scene
from ipbench.envs.sensors import camera_pose, intrinsics
from ipbench.envs.sensors.lens_distortion import D5100_35MM
from ipbench.eval.calibration.calibrate import CalibrationCaptureConfig, calibrate_cell

ROBOT_SEED = 3
HEAD = (34, 51)  # (height, width): tiny head images keep the tests fast
CAMS = {"wrist": "right_wrist_camera", "head_left": "head_left_camera",
        "head_right": "head_right_camera"}  # fmt: skip
NO_REPORT = {"kind": 0, "label": 0, "position": np.zeros(3)}


@pytest.fixture(scope="module")
def calibration(tmp_path_factory) -> str:
    """A calibration of the true cell of ROBOT_SEED by ``ipbench calibrate``'s routine (8 poses
    per camera group, about 3 s)."""
    config = CalibrationCaptureConfig(poses_per_camera=8, robot_seed=ROBOT_SEED)
    path = tmp_path_factory.mktemp("cal") / "cal.json"
    calibrate_cell(config).save(path)
    return str(path)


def _error(belief: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """(translation mm, rotation deg) between two poses."""
    d = np.linalg.inv(belief) @ truth
    angle = np.degrees(np.arccos(np.clip((np.trace(d[:3, :3]) - 1) / 2, -1, 1)))
    return float(np.linalg.norm(d[:3, 3]) * 1000), float(angle)


def _sorting(**kw):
    return gym.make("ipbench/Sorting-v2", head_size=HEAD, robot_seed=ROBOT_SEED, **kw).unwrapped


def _nominal_fk(readings: dict[str, float]) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The nominal robot (no errors) at joint ``readings``, by name (the test's own FK)."""
    m = build_workcell_spec().compile()
    d = mujoco.MjData(m)
    for name, q in readings.items():
        d.qpos[m.jnt_qposadr[m.joint(name).id]] = q
    mujoco.mj_kinematics(m, d)
    mujoco.mj_comPos(m, d)
    mujoco.mj_camlight(m, d)
    return m, d


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"extrinsics": "perfect"}, r"unknown extrinsics 'perfect'; valid: 'true', 'nominal'"),
        ({"extrinsics": "calibrated"}, r"needs calibration=FILE"),
        ({"extrinsics": "nominal", "calibration": "x.json"}, r"only read with extrinsics="),
        ({"extrinsics": "nominal", "robot_seed": -1}, r"robot_seed must be an int >= 0"),
        ({"extrinsics": "calibrated", "calibration": "/nonexistent.json"}, r"does not exist"),
    ],
)
def test_the_option_is_validated_with_the_valid_options_listed(kw, match):
    with pytest.raises(ExtrinsicsError, match=match):
        gym.make("ipbench/Sorting-v2", **kw)
    with pytest.raises(ExtrinsicsError, match=match):
        ExplorationEnv(**kw)
    assert EXTRINSICS == ("true", "nominal", "calibrated")


def test_a_file_lacking_a_camera_or_the_head_gaze_is_refused(calibration, tmp_path):
    data = json.loads(open(calibration).read())
    wrist_only = dict(data, cameras={"wrist": data["cameras"]["wrist"]},
                      hand_eye={"wrist": data["hand_eye"]["wrist"]}, stereo=None)  # fmt: skip
    del wrist_only["head_gaze"]
    path = tmp_path / "wrist.json"
    path.write_text(json.dumps(wrist_only))
    with pytest.raises(ExtrinsicsError, match=r"camera\(s\) \['head_left', 'head_right'\]"):
        _sorting(extrinsics="calibrated", calibration=str(path))
    assert _sorting(extrinsics="calibrated", calibration=str(path), cameras=("wrist",))
    no_gaze = dict(data)
    del no_gaze["head_gaze"]
    path = tmp_path / "old.json"
    path.write_text(json.dumps(no_gaze))
    with pytest.raises(ExtrinsicsError, match=r"has no head_gaze"):
        ExplorationEnv(extrinsics="calibrated", calibration=str(path))
    with pytest.raises(ExtrinsicsError, match=r"valid modes here: 'nominal', 'calibrated'"):
        CameraKnowledge.build("true", ("wrist",))


def test_true_is_the_default_and_adds_nothing():
    default, explicit = _sorting(), _sorting(extrinsics="true")
    assert default.observation_space == explicit.observation_space
    assert not any(k.endswith("_dist") for k in default.observation_space.spaces)
    a, _ = default.reset(seed=4)
    b, _ = explicit.reset(seed=4)
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    # the world is the nominal one: the poses are the simulator's
    for c, cam in CAMS.items():
        assert np.array_equal(a[f"{c}_pose"], camera_pose(default.model, default.data, cam))


def test_nominal_is_the_nominal_fk_and_differs_from_the_truth_by_the_seeded_errors():
    env = _sorting(extrinsics="nominal")
    obs, _ = env.reset(seed=0)
    names = env._knowledge.joint_names
    _, fk = _nominal_fk({j: env.data.qpos[env.model.jnt_qposadr[env.model.joint(j).id]]
                         for j in names})  # fmt: skip
    errors = sample_model_errors(ROBOT_SEED)
    for c, cam in CAMS.items():
        nominal_model = env._knowledge.model
        np.testing.assert_allclose(
            obs[f"{c}_pose"], camera_pose(nominal_model, fk, cam), atol=1e-12
        )
        assert np.array_equal(obs[f"{c}_dist"], np.zeros(5))
        w, h = (640, 480) if c == "wrist" else HEAD[::-1]
        np.testing.assert_array_equal(obs[f"{c}_K"], intrinsics(nominal_model, cam, w, h).K)
        truth = camera_pose(env.model, env.data, cam)
        assert _error(obs[f"{c}_pose"], truth)[0] > 1.0  # mm
    # the arm chains carry no error: the wrist's truth is the nominal pose @ E (the mount error)
    np.testing.assert_allclose(
        np.linalg.inv(obs["wrist_pose"]) @ camera_pose(env.model, env.data, CAMS["wrist"]),
        errors.wrist_camera.matrix,
        atol=1e-9,
    )


def test_the_true_world_shows_the_lens_distortion():
    base = dict(scene="simple", head_size=HEAD)
    ideal = ExplorationEnv(**base)
    real = ExplorationEnv(**base, extrinsics="nominal", robot_seed=ROBOT_SEED)
    o1, _ = ideal.reset(seed=2)
    o2, info = real.reset(seed=2)
    assert not np.array_equal(o1["head_left"], o2["head_left"])
    assert o2["head_left"].shape == o1["head_left"].shape
    assert set(np.unique(info["head_left_mask"])) <= set(range(-1, len(info["objects"])))


def test_calibrated_poses_are_much_closer_to_the_truth_than_nominal(calibration):
    errors = {}
    for mode, cal in (("nominal", None), ("calibrated", calibration)):
        env = _sorting(extrinsics=mode, calibration=cal)
        obs, _ = env.reset(seed=0)
        errors[mode] = {c: _error(obs[f"{c}_pose"], camera_pose(env.model, env.data, cam))
                        for c, cam in CAMS.items()}  # fmt: skip
    for c in CAMS:
        (tn, rn), (tc, rc) = errors["nominal"][c], errors["calibrated"][c]
        assert tc < 0.5 * tn and rc < 0.5 * rn, (c, errors)
    assert max(e[0] for e in errors["calibrated"].values()) < 10.0  # mm


def test_calibrated_k_and_dist_come_from_the_file_scaled_to_the_image(calibration):
    data = json.loads(open(calibration).read())
    env = ExplorationEnv(head_size=HEAD, extrinsics="calibrated", robot_seed=ROBOT_SEED,
                         calibration=calibration)  # fmt: skip
    obs, _ = env.reset(seed=1)
    cam = data["cameras"]["head_left"]
    np.testing.assert_allclose(obs["head_left_dist"], cam["dist"])
    m = env._knowledge.model
    K = np.array(cam["K"])  # noqa: N806
    want = _scaled_K(m, "head_left_camera", K, cam["image_size"], HEAD[::-1])
    np.testing.assert_allclose(obs["head_left_K"], want)
    assert np.allclose(_scaled_K(m, "head_left_camera", K, (1024, 680), (1024, 680)), K)
    # the scaling is the camera's own: nominal K at 1024 x 680 -> its K at 51 x 34, 64 x 48
    full = intrinsics(m, "head_left_camera", 1024, 680).K
    for size in ((51, 34), (64, 48)):
        np.testing.assert_allclose(
            _scaled_K(m, "head_left_camera", full, (1024, 680), size),
            intrinsics(m, "head_left_camera", *size).K,
        )
    assert abs(want[0, 0] / K[0, 0] - 34 / 680) < 1e-9  # the fovy camera: f scales by height


def test_the_calibrated_head_pose_follows_the_encoders_after_a_gaze_change(calibration):
    env = ExplorationEnv(head_size=HEAD, extrinsics="calibrated", robot_seed=ROBOT_SEED,
                         calibration=calibration)  # fmt: skip
    obs0, _ = env.reset(seed=1)
    gaze = obs0["head_qpos"] + np.array([0.2, -0.1, -0.15, 0.1])
    obs, *_ = env.step({"gaze": gaze, "report": NO_REPORT})
    g0 = np.array(json.loads(open(calibration).read())["head_gaze"])
    joints = ("head_left_pan", "head_left_tilt", "head_right_pan", "head_right_tilt")
    for side, X in (("left", None), ("right", None)):  # noqa: N806
        X = env._knowledge.calibration.hand_eye[f"head_{side}"].X  # noqa: N806
        m, at_cal = _nominal_fk(dict(zip(joints, g0, strict=True)))
        m_true, d_true = env.model, env.data  # the other joints' encoders: the true qpos
        readings = {j: d_true.qpos[m_true.jnt_qposadr[m_true.joint(j).id]]
                    for j in env._knowledge.joint_names}  # fmt: skip
        _, now = _nominal_fk(readings | dict(zip(joints, obs["head_qpos"], strict=True)))

        def body(d, name, m=m):
            T = np.eye(4)  # noqa: N806
            T[:3, :3], T[:3, 3] = d.body(name).xmat.reshape(3, 3), d.body(name).xpos
            return T

        tilt = m.body(m.jnt_bodyid[m.joint(f"head_{side}_tilt").id]).name
        want = body(now, tilt) @ np.linalg.inv(body(at_cal, tilt)) @ body(at_cal, "base") @ X
        np.testing.assert_allclose(obs[f"head_{side}_pose"], want, atol=1e-9)
        assert _error(obs0[f"head_{side}_pose"], obs[f"head_{side}_pose"])[1] > 3.0  # it moved
        truth = camera_pose(env.model, env.data, f"head_{side}_camera")
        assert _error(obs[f"head_{side}_pose"], truth)[0] < 10.0  # mm, still close


def test_build_model_with_no_errors_is_the_nominal_model():
    scene = sample_scene("simple", 5)
    a, b = build_model(scene), build_model(scene, ModelErrors.none())
    for name in ("body_pos", "body_quat", "cam_pos", "cam_quat", "key_qpos", "key_ctrl",
                 "geom_size", "jnt_range"):  # fmt: skip
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


def test_distort_labels_keeps_labels_and_marks_lost_pixels():
    labels = np.full((34, 51), -1, np.int32)
    labels[10:20, 15:30] = 7
    K = intrinsics(build_workcell_spec().compile(), "head_left_camera", 51, 34).K  # noqa: N806
    out = distort_labels(labels, K, D5100_35MM)
    assert out.dtype == np.int32 and out.shape == labels.shape
    assert set(np.unique(out)) <= {-1, 7} and (out == 7).sum() > 100


@pytest.mark.parametrize("mode", EXTRINSICS)
@pytest.mark.parametrize("env_id", ["ipbench/Exploration-v0", "ipbench/Sorting-v2"])
def test_check_env_passes(env_id, mode, calibration):
    cal = calibration if mode == "calibrated" else None
    kw = {} if mode == "true" else {"robot_seed": ROBOT_SEED}
    env = gym.make(env_id, head_size=HEAD, extrinsics=mode, calibration=cal, **kw)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_the_true_xtion_depth_is_shifted_by_the_robots_registration_error():
    """Under ``nominal``/``calibrated`` the wrist depth image is the registered depth moved by
    the robot's ``depth_registration_px`` (rounded), uncovered pixels missing; the RGB image
    does not move; ``true`` keeps no shift."""
    from ipbench.envs.sensors.depth_noise import DepthNoiseConfig

    seed = 0  # registration (2.50, -1.79) px: (3, -2) whole pixels
    du, dv = sample_model_errors(seed).depth_registration_px
    dx, dy = round(du), round(dv)
    assert (dx, dy) == (3, -2)
    env = gym.make(
        "ipbench/Sorting-v2", head_size=HEAD, cameras=("wrist",), extrinsics="nominal",
        robot_seed=seed, depth_noise=DepthNoiseConfig(enabled=False),
    ).unwrapped  # fmt: skip
    obs, _ = env.reset(seed=4)
    assert env._registration == (dx, dy)
    env._registration = (0, 0)  # the same view, unshifted
    ideal = env._observation()
    h, w = ideal["wrist_depth"].shape
    got = obs["wrist_depth"]
    np.testing.assert_array_equal(
        got[max(dy, 0) : h + min(dy, 0), max(dx, 0) : w + min(dx, 0)],
        ideal["wrist_depth"][max(-dy, 0) : h + min(-dy, 0), max(-dx, 0) : w + min(-dx, 0)],
    )
    assert not got[:, :dx].any() and not got[h + dy :, :].any()  # uncovered: missing
    np.testing.assert_array_equal(obs["wrist_rgb"], ideal["wrist_rgb"])
    default = gym.make("ipbench/Sorting-v2", head_size=HEAD, cameras=("wrist",)).unwrapped
    default.reset(seed=4)
    assert default._registration == (0, 0)


def test_ptu_backlash_lags_the_true_joints_behind_the_encoders():
    """In the true cell each PTU axis' output trails its motor (what the encoder counts) by
    half the robot's backlash, on the side it came from: behind after a move up, ahead after
    a reversal (within the settle tolerance)."""
    seed = 0  # left pan backlash 0.00165 rad (1.8 steps)
    env = ExplorationEnv(head_size=HEAD, extrinsics="nominal", robot_seed=seed)
    obs, _ = env.reset(seed=1)
    half = 0.5 * np.concatenate(
        [sample_model_errors(seed).ptu(s).backlash for s in ("left", "right")]
    )
    tol = env.config.settle_tolerance * env.ptus[0].step
    joints = env._qadr
    assert np.abs(env.data.qpos[joints] - obs["head_qpos"]).max() <= tol  # centred at home
    for direction in (1.0, -1.0):
        gaze = obs["head_qpos"] + direction * np.array([0.1, 0.05, 0.1, 0.05])
        obs, *_ = env.step({"gaze": gaze, "report": NO_REPORT})
        lag = obs["head_qpos"] - env.data.qpos[joints]
        assert np.all(np.abs(lag - direction * half) <= tol + 1e-9), (direction, lag, half)
    assert half.max() > 1.5 * tol  # without the lag, that axis would fail the check above


def test_a_calibration_of_another_cell_is_refused(calibration):
    """The fixture's file records robot_seed=ROBOT_SEED: an env of another true cell refuses it
    and says how to make the right one."""
    assert dict(json.loads(open(calibration).read())["cell"]) == {"robot_seed": ROBOT_SEED}
    with pytest.raises(ExtrinsicsError, match=r"measured in robot_seed=3.*--robot-seed 5"):
        gym.make("ipbench/Sorting-v2", extrinsics="calibrated", calibration=calibration,
                 robot_seed=5)  # fmt: skip
