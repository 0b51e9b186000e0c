"""The robot calibrates its cameras in the simulated cell (eval/calibration/calibrate.py)."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import cv2  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from ipbench.assets.calibration_target import (  # noqa: E402
    TargetPlateError,
    add_target_plate,
)
from ipbench.assets.compose import build_workcell_spec  # noqa: E402
from ipbench.envs.cell.calibration_file import CalibrationFile  # noqa: E402
from ipbench.eval.calibration.calibrate import (  # noqa: E402
    CalibrationCaptureConfig,
    CalibrationRoutineError,
    build_calibration_model,
    calibrate_capture,
    calibration_truth,
    capture_views,
)
from ipbench.perception.calibration.hand_eye import HAND_EYE_METHODS  # noqa: E402
from ipbench.perception.calibration.poses import (  # noqa: E402
    invert,
    rotation_angle_deg,
    translation_error_mm,
)
from ipbench.perception.calibration.target import Checkerboard  # noqa: E402

# small but real: 8 views per camera group, head images at 800 x 532 (not 1024 x 680)
CONFIG = CalibrationCaptureConfig(poses_per_camera=8, head_size=(800, 532), seed=3)


@pytest.fixture(scope="module")
def run():
    capture = capture_views(CONFIG)
    return capture, calibrate_capture(capture), calibration_truth(capture)


def test_plate_face_maps_board_points_where_the_texture_prints_them():
    board = Checkerboard()
    texture = board.render_texture(16)
    spec = build_workcell_spec()
    origin = (board.texture_corners_px(16)[0] + 0.5) * board.size_m[0] / texture.shape[1]
    plate = add_target_plate(spec, texture, board.size_m, origin_m=tuple(origin))
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    site = np.eye(4)
    site[:3, :3] = data.site("left_gripper_tcp").xmat.reshape(3, 3)
    site[:3, 3] = data.site("left_gripper_tcp").xpos
    geom = model.geom("calibration_target_face")
    mesh = model.geom_dataid[geom.id]
    start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
    verts = model.mesh_vert[start : start + count] @ data.geom_xmat[geom.id].reshape(3, 3).T
    verts += data.geom_xpos[geom.id]
    # the face's corners, in board coordinates, are minus the origin and the size beyond it
    w, h = board.size_m
    corners_board = np.array([[0, 0], [w, 0], [w, h], [0, h]]) - origin
    expected = (site @ plate.site_from_board)[:3] @ np.c_[corners_board, np.zeros(4), np.ones(4)].T
    assert np.abs(np.sort(verts, axis=0) - np.sort(expected.T, axis=0)).max() < 1e-6
    # board z points into the plate, i.e. away from the face's viewer: opposite the TCP's +x
    assert np.allclose((site @ plate.site_from_board)[:3, 2], -site[:3, 0])


def test_plate_refuses_bad_arguments_with_the_valid_options():
    spec = build_workcell_spec()
    with pytest.raises(TargetPlateError, match="unknown parent_site 'nowhere'; valid"):
        add_target_plate(spec, np.zeros((8, 8), np.uint8), (0.1, 0.1), parent_site="nowhere")
    with pytest.raises(TargetPlateError, match="uint8"):
        add_target_plate(spec, np.zeros((8, 8)), (0.1, 0.1))
    with pytest.raises(TargetPlateError, match=r"size_m\[1\] must be a positive length"):
        add_target_plate(spec, np.zeros((8, 8), np.uint8), (0.1, -0.1))


def test_detected_corners_are_the_true_board_corners_projected(run):
    capture, _, truth = run
    _, plate = build_calibration_model(capture.board, CONFIG.px_per_square)
    points = capture.board.object_points()
    head = capture.head
    for name, corners in (("head_left", head.left_corners), ("head_right", head.right_corners)):
        for gripper, found in zip(head.gripper_to_base, corners, strict=True):
            board_to_camera = invert(truth.X[name]) @ gripper @ plate.site_from_board
            rvec = cv2.Rodrigues(board_to_camera[:3, :3])[0]
            projected = cv2.projectPoints(points, rvec, board_to_camera[:3, 3], truth.K[name], None)
            assert np.abs(projected[0].reshape(-1, 2) - found).max() < 0.5


def test_small_capture_recovers_the_simulator_cameras(run):
    capture, result, truth = run
    assert len(capture.head.gripper_to_base) == len(capture.wrist.flange_to_base) == 8
    for name in ("head_left", "head_right", "wrist"):
        K, K_true = result.intrinsics[name].K, truth.K[name]
        assert result.intrinsics[name].image_size == (
            CONFIG.head_size if name != "wrist" else CONFIG.wrist_size
        )
        # fx, fy, cx, cy each within 1 % of the true focal length (1 % of fx for the centre)
        for i, j in ((0, 0), (1, 1), (0, 2), (1, 2)):
            assert abs(K[i, j] - K_true[i, j]) < 0.01 * K_true[0, 0], (name, i, j)
    # the wrist's eye-in-hand X: every method, and the one kept in the file
    assert set(result.hand_eye["wrist"]) == set(HAND_EYE_METHODS)
    for method, he in result.hand_eye["wrist"].items():
        assert rotation_angle_deg(he.X, truth.X["wrist"]) < 1.0, method
        assert translation_error_mm(he.X, truth.X["wrist"]) < 5.0, method
    kept = result.file.hand_eye["wrist"]
    assert kept.setup == "eye_in_hand" and kept.method in HAND_EYE_METHODS
    scores = {m: r.translation_rms_mm + 1000 * np.radians(r.rotation_rms_deg)
              for m, r in result.hand_eye["wrist"].items()}  # fmt: skip
    assert kept.method == min(scores, key=scores.get)
    # the head's stereo baseline, and its eye-to-hand X (camera-to-base, looser: PnP at 1.6 m)
    baseline = np.linalg.norm(result.file.stereo.left_to_right[:3, 3])
    assert abs(baseline - np.linalg.norm(truth.left_to_right[:3, 3])) < 0.005
    assert rotation_angle_deg(result.file.stereo.left_to_right, truth.left_to_right) < 1.0
    for name in ("head_left", "head_right"):
        X = result.file.hand_eye[name].X
        assert result.file.hand_eye[name].setup == "eye_to_hand"
        assert rotation_angle_deg(X, truth.X[name]) < 1.0
        assert translation_error_mm(X, truth.X[name]) < 10.0


def test_calibration_file_round_trips(run, tmp_path):
    _, result, _ = run
    path = result.file.save(tmp_path / "calib.json")
    loaded = CalibrationFile.load(path, expect_cameras=["head_left", "head_right", "wrist"])
    assert loaded.to_dict() == result.file.to_dict()
    assert np.array_equal(loaded.camera("wrist").K, result.intrinsics["wrist"].K)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"cameras": ("head", "kinect")}, r"not a non-empty subset of \('head', 'wrist'\)"),
        ({"cameras": ()}, "not a non-empty subset"),
        ({"poses_per_camera": 2}, "poses_per_camera must be an int >= 3"),
        ({"head_size": (2000, 680)}, "head_size must be whole"),
        ({"seed": -1}, "seed must be an int >= 0"),
        ({"robot_seed": -2}, "robot_seed must be None or an int >= 0"),
        ({"wrist_distance_m": (0.7, 0.4)}, "wrist_distance_m must be"),
    ],
)
def test_bad_config_is_refused_with_a_clear_message(kwargs, message):
    with pytest.raises(CalibrationRoutineError, match=message):
        CalibrationCaptureConfig(**kwargs)


def test_cameras_may_be_given_as_a_comma_list_and_a_bad_config_object_is_refused():
    assert CalibrationCaptureConfig(cameras="wrist,head").cameras == ("head", "wrist")
    with pytest.raises(CalibrationRoutineError, match="CalibrationCaptureConfig"):
        capture_views({"cameras": "head"})


def test_a_cell_with_model_errors_is_calibrated_far_closer_than_its_nominal_model():
    """With the true cell off its nominal model (envs.cell.model_errors: camera mounts, PTU bases,
    lenses), the calibrated hand-eye X is much nearer the truth than the nominal model's."""
    config = CalibrationCaptureConfig(cameras=("wrist",), poses_per_camera=8, seed=3, robot_seed=1)
    capture = capture_views(config)
    result = calibrate_capture(capture)
    truth = calibration_truth(capture)
    nominal = calibration_truth(capture_views(CalibrationCaptureConfig(
        cameras=("wrist",), poses_per_camera=3, seed=3)))  # fmt: skip
    X = result.file.hand_eye["wrist"].X
    calibrated_deg = float(rotation_angle_deg(X, truth.X["wrist"]))
    nominal_deg = float(rotation_angle_deg(nominal.X["wrist"], truth.X["wrist"]))
    calibrated_mm = float(translation_error_mm(X, truth.X["wrist"]))
    nominal_mm = float(translation_error_mm(nominal.X["wrist"], truth.X["wrist"]))
    assert nominal_deg > 0.1 and nominal_mm > 1.0  # the errors are there
    assert calibrated_deg < nominal_deg / 3 and calibrated_mm < nominal_mm / 2
    # the true lens is distorted (the Xtion's own coefficients) and the routine recovers k1
    assert abs(result.file.camera("wrist").dist[0]) > 0.005
