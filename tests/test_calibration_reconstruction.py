"""Reconstruction accuracy of the calibrated cameras (thesis Tables 4.2-4.5)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ipbench.eval.calibration.calibrate import (
    CalibrationCaptureConfig,
    calibrate_capture,
    capture_views,
)
from ipbench.eval.calibration.evaluate import reconstruction_metrics
from ipbench.eval.calibration.reconstruction import (
    HEAD_METHODS,
    THESIS,
    ReconstructionError,
    board_errors,
    reconstruct_head,
)
from ipbench.eval.calibration.wrist_reconstruction import reconstruct_wrist
from ipbench.perception.calibration.errors import CalibrationError
from ipbench.perception.calibration.target import Checkerboard

ROBOT_SEED = 3


@pytest.fixture(scope="module")
def with_errors():
    config = CalibrationCaptureConfig(robot_seed=ROBOT_SEED, poses_per_camera=10)
    calibration = calibrate_capture(capture_views(config))
    return calibration, reconstruction_metrics(calibration, ROBOT_SEED, seed=0, poses=3)


@pytest.fixture(scope="module")
def exact_cell():
    config = CalibrationCaptureConfig(cameras=("head",), poses_per_camera=8)
    return calibrate_capture(capture_views(config))


def test_board_errors_of_the_exact_board_are_zero_and_see_a_scale_error():
    board = Checkerboard()
    pts = board.object_points().reshape(-1, 3)
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    moved = pts @ rot.T + [0.3, -0.2, 1.1]
    exact = board_errors(moved, board, np.eye(3))
    assert len(exact["distance_errors_mm"]) == board.rows * (board.cols - 1) + board.cols * (
        board.rows - 1
    )
    assert np.abs(exact["distance_errors_mm"]).max() < 1e-9
    assert np.abs(exact["residuals_mm"]).max() < 1e-9
    scaled = board_errors(moved * 1.01, board, np.eye(3))  # 1 % too large: +0.24 mm a square
    assert np.allclose(scaled["distance_errors_mm"], 0.24, atol=1e-9)
    with pytest.raises(ReconstructionError, match="corners of the board"):
        board_errors(pts[:5], board, np.eye(3))


def test_metrics_structure_and_thesis_figures(with_errors):
    _, metrics = with_errors
    for key in ("head_dynamic_rmse_mm", "head_encoders_rmse_mm", "wrist_rmse_mm",
                "wrist_robot_rmse_mm", "wrist_robot_nominal_rmse_mm"):  # fmt: skip
        assert math.isfinite(metrics[key]) and metrics[key] > 0
    tables = metrics["tables"]
    assert tables["table_4_3_head_rmse_mm"]["thesis"] == THESIS["head_rmse_mm"] == 0.16
    assert tables["table_4_2_head_axis_residual_mm"]["thesis_max"] == 0.3
    assert tables["table_4_4_xtion_rmse_mm"]["thesis"] == 12.5
    assert tables["table_4_5_kinect_v2_rmse_mm"]["thesis"] == 11.6
    robot = tables["table_4_4_xtion_robot_frame_rmse_mm"]
    assert robot["thesis"] == 12.5
    assert robot["ours"] == {
        "calibrated": metrics["wrist_robot_rmse_mm"],
        "nominal": metrics["wrist_robot_nominal_rmse_mm"],
    }
    assert metrics["wrist"]["robot_frame"]["calibrated"]["rmse_mm"] == robot["ours"]["calibrated"]
    head = metrics["head"]
    assert head["trials"] == 3 and set(head["methods"]) == set(HEAD_METHODS)
    for summary in head["methods"].values():
        assert len(summary["axis_mean_abs_residual_mm"]) == 3
        assert len(summary["per_trial_rmse_mm"]) == 3


def test_head_with_robot_errors_dynamic_update_beats_encoders(with_errors):
    methods = with_errors[1]["head"]["methods"]
    # updating each camera by PnP removes most of the encoder-carried error
    assert methods["dynamic_both"]["rmse_mm"] < 0.7 * methods["encoders"]["rmse_mm"]
    # the right camera by the chain keeps the encoders' relative pose: same distances
    assert methods["dynamic"]["rmse_mm"] == pytest.approx(methods["encoders"]["rmse_mm"], abs=1e-3)
    assert methods["true"]["rmse_mm"] < methods["encoders"]["rmse_mm"]


def test_wrist_from_noisy_depth_is_worse_than_the_head(with_errors):
    metrics = with_errors[1]
    assert metrics["wrist"]["trials"] == 3
    assert metrics["wrist_rmse_mm"] > metrics["head"]["methods"]["true"]["rmse_mm"]


def test_exact_cell_reconstructs_the_board_within_the_thesis_figure(exact_cell):
    # no model errors, exact extrinsics: only corner detection on the rendered images is left
    # (over 200 trials of 20 seeds a median trial is 0.1 mm RMSE and the worst 0.4 mm; a view
    # with a corner found off the board, which the plane check rejects, gave 1.4 and 4.0 mm)
    head = reconstruct_head(exact_cell, None, seed=1, poses=3)
    errors = head["methods"]["true"]
    assert np.median(errors["per_trial_rmse_mm"]) < 0.2
    assert max(errors["per_trial_rmse_mm"]) < 0.5
    x, y, z = errors["axis_mean_abs_residual_mm"]
    assert max(x, y) < THESIS["head_axis_residual_max_mm"]  # across the view: well measured
    # along the view depth comes from disparity: 0.1 px of corner noise at 1.5 m, baseline
    # 0.288 m and f = 1519 px is z^2 * 0.1 / (f b) = 0.51 mm, beyond the thesis' 0.3 mm bound
    assert z < 1.5**2 * 0.1 / (1519 * 0.288) * 1000


def test_methods_are_compared_on_the_trials_every_one_of_them_reconstructed(
    exact_cell, monkeypatch
):
    import ipbench.eval.calibration.head_views as head_views

    update, calls = head_views.update_left_pose, [0]

    def fails_in_the_second_trial(*args, **kwargs):
        calls[0] += 1
        if calls[0] == 3:  # the second trial's first update (a trial updates both cameras)
            raise CalibrationError("planted: too few matches")
        return update(*args, **kwargs)

    monkeypatch.setattr(head_views, "update_left_pose", fails_in_the_second_trial)
    head = reconstruct_head(exact_cell, None, seed=1, poses=3)
    n, failed = head["trials"], head["failures"]["dynamic_both"]
    assert n == 3 and 1 <= failed < n  # the planted failure, and any the views cause
    # every method is scored on the trials where the last of them to fail did not
    assert head["paired_trials"] == n - failed
    assert len(head["methods"]["true"]["per_trial_rmse_mm"]) == n
    assert head["paired"]["dynamic_both"] == head["methods"]["dynamic_both"]
    true_all = head["methods"]["true"]["per_trial_rmse_mm"]
    for method, summary in head["paired"].items():
        assert len(summary["per_trial_rmse_mm"]) == n - failed, method
    assert set(head["paired"]["true"]["per_trial_rmse_mm"]) < set(true_all)


def test_bad_input_is_refused(exact_cell):
    with pytest.raises(ReconstructionError, match="CellCalibration"):
        reconstruct_head(object(), None, 0)
    with pytest.raises(ReconstructionError, match="no wrist cameras"):
        reconstruct_wrist(exact_cell, None, 0)
    with pytest.raises(ReconstructionError, match="poses must be an int >= 1"):
        reconstruct_head(exact_cell, None, 0, poses=0)
    with pytest.raises(ReconstructionError, match="robot_seed"):
        reconstruct_head(exact_cell, -1, 0)


def test_ideal_corners_and_the_true_cameras_reconstruct_the_board_to_round_off():
    # the true cell of a robot seed, its true lenses: corners projected exactly (no detector)
    # and triangulated as the "true" method does leave nothing but round-off
    import cv2
    import mujoco

    import ipbench.eval.calibration.reconstruction as reconstruction
    from ipbench.envs.sensors import intrinsics

    board, errors = Checkerboard(), reconstruction._errors(ROBOT_SEED)
    model, _ = reconstruction._spec(board, 40, errors)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    size = (1024, 680)
    cams = ("head_left", "head_right")
    K = {n: intrinsics(model, reconstruction.CAMERAS[n], *size).K for n in cams}
    dist = {n: np.array(errors.distortion[reconstruction.CAMERAS[n]].coefficients) for n in cams}
    assert all(np.any(d) for d in dist.values())  # real lenses: undistortion is exercised
    pose = {n: reconstruction._cam_base(model, data, n) for n in cams}
    local = board.object_points().reshape(-1, 3) - [0.1, 0.06, -1.4]  # 1.4 m ahead, centred
    world = local @ pose["head_left"][:3, :3].T + pose["head_left"][:3, 3]
    pixels = {}
    for n in cams:
        inv = np.linalg.inv(pose[n])
        xy, _ = cv2.projectPoints(world, cv2.Rodrigues(inv[:3, :3])[0], inv[:3, 3], K[n], dist[n])
        pixels[n] = xy.reshape(-1, 2)
    points = reconstruction._triangulate(
        K["head_left"], pose["head_left"], dist["head_left"], K["head_right"],
        pose["head_right"], dist["head_right"], pixels["head_left"], pixels["head_right"],
    )  # fmt: skip
    errors_mm = board_errors(points, board, np.eye(3))
    assert np.abs(errors_mm["distance_errors_mm"]).max() < 1e-6
    assert np.abs(points - world).max() < 1e-9  # m


def test_no_method_is_scored_on_the_board_the_dynamic_update_saw(exact_cell, monkeypatch):
    import ipbench.eval.calibration.head_views as head_views
    import ipbench.eval.calibration.reconstruction as reconstruction
    from ipbench.perception.calibration.target import find_corners

    update, triangulate = head_views.update_left_pose, reconstruction._triangulate
    seen, scored = [], []

    def spy_update(*args, **kwargs):
        seen.extend(a for a in args if isinstance(a, np.ndarray) and a.ndim == 3)  # images
        return update(*args, **kwargs)

    def spy_triangulate(*args):
        scored.append(args[6])  # the left camera's corners, as every method triangulates them
        return triangulate(*args)

    monkeypatch.setattr(head_views, "update_left_pose", spy_update)
    monkeypatch.setattr(reconstruction, "_triangulate", spy_triangulate)
    head = reconstruct_head(exact_cell, None, seed=1, poses=2)
    assert head["trials"] == 2 and scored and seen
    board = Checkerboard()
    fitted = [c for c in (find_corners(img, board) for img in seen) if c is not None]
    assert fitted  # the update's images show a board: the one it may fit
    for corners in scored:
        for other in fitted:  # the scored board is elsewhere in the image: another pose
            assert np.median(np.linalg.norm(corners - other, axis=1)) > 10.0
