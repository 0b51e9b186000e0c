"""The wrist Xtion's board corners in the robot frame (thesis Table 4.4)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ipbench.envs.sensors.depth_noise import STRUCTURED_LIGHT, without_effect
from ipbench.eval.calibration.calibrate import (
    CalibrationCaptureConfig,
    calibrate_capture,
    calibration_truth,
    capture_views,
)
from ipbench.eval.calibration.reconstruction import ReconstructionError
from ipbench.eval.calibration.wrist_reconstruction import (
    ROBOT_FRAME_CHAINS,
    reconstruct_wrist,
    robot_frame_summary,
)

OFFSET_MM = np.array([6.0, -8.0, 0.0])  # |offset| = 10 mm, in the flange frame


@pytest.fixture(scope="module")
def cell():
    """A wrist calibration of the exact cell (no model errors) and its truth."""
    capture = capture_views(CalibrationCaptureConfig(cameras=("wrist",), poses_per_camera=5))
    return calibrate_capture(capture), calibration_truth(capture)


def _with(calibration, X, K):  # noqa: N803
    """``calibration`` with the wrist's hand-eye ``X`` and a pinhole of matrix ``K``."""
    entry = dataclasses.replace(calibration.file.hand_eye["wrist"], X=X)
    file = dataclasses.replace(
        calibration.file, hand_eye={**calibration.file.hand_eye, "wrist": entry}
    )
    intr = dataclasses.replace(calibration.intrinsics["wrist"], K=K, dist=np.zeros(5))
    return dataclasses.replace(
        calibration, file=file, intrinsics={**calibration.intrinsics, "wrist": intr}
    )


def test_robot_frame_summary_of_known_residuals():
    a = np.array([[3.0, 0.0, 4.0], [3.0, 0.0, -4.0]])  # each 5 mm long
    b = np.array([[0.0, 1.0, 0.0]])
    s = robot_frame_summary([a, b])
    assert s["rmse_mm"] == pytest.approx(np.sqrt((25 + 25 + 1) / 3))
    assert s["axis_mean_mm"] == pytest.approx([2.0, 1 / 3, 0.0])
    assert s["axis_std_mm"] == pytest.approx(np.std(np.vstack([a, b]), axis=0))
    assert s["per_trial_rmse_mm"] == pytest.approx([5.0, 1.0])
    assert s["corners"] == 3
    with pytest.raises(ReconstructionError, match=r"\(N, 3\)"):
        robot_frame_summary([np.zeros((4, 2))])
    with pytest.raises(ReconstructionError, match="non-empty"):
        robot_frame_summary([])


def test_true_chain_and_ideal_depth_put_the_corners_where_they_are(cell):
    # the measurement itself: exact X, K and lens, no model errors, noiseless depth; left are
    # corner detection and the depth at the nearest pixel (measured 0.04-0.12 mm)
    calibration, truth = cell
    exact = _with(calibration, truth.X["wrist"], truth.K["wrist"])
    out = reconstruct_wrist(exact, None, seed=0, poses=2, depth_noise=None)
    assert set(out["robot_frame"]) == set(ROBOT_FRAME_CHAINS)
    for chain in ROBOT_FRAME_CHAINS:  # without model errors the nominal mount is the true one
        summary = out["robot_frame"][chain]
        assert summary["corners"] == out["trials"] * calibration.capture.board.n_corners
        assert summary["rmse_mm"] < 0.25
        assert np.abs(summary["axis_mean_mm"]).max() < 0.1


def test_an_X_off_by_a_translation_moves_every_corner_by_it(cell):
    calibration, truth = cell
    X = truth.X["wrist"].copy()  # noqa: N806
    X[:3, 3] += OFFSET_MM / 1000.0
    out = reconstruct_wrist(
        _with(calibration, X, truth.K["wrist"]), None, seed=0, poses=2, depth_noise=None
    )
    calibrated = out["robot_frame"]["calibrated"]
    offset = float(np.linalg.norm(OFFSET_MM))
    assert calibrated["rmse_mm"] == pytest.approx(offset, abs=0.3)
    assert calibrated["per_trial_rmse_mm"] == pytest.approx([offset] * out["trials"], abs=0.3)
    assert out["robot_frame"]["nominal"]["rmse_mm"] < 0.25  # the nominal chain reads no X


def test_noisy_depth_errors_are_the_sensors_random_noise_plus_its_unit_error(cell):
    calibration, truth = cell
    exact = _with(calibration, truth.X["wrist"], truth.K["wrist"])
    random_only = without_effect(without_effect(STRUCTURED_LIGHT, "unit_depth_error"),
                                 "registration")  # fmt: skip
    out = reconstruct_wrist(exact, None, seed=2, poses=3, depth_noise=random_only)
    assert out["depth_unit"] is None
    summary = out["robot_frame"]["calibrated"]
    # Nguyen et al. sigma_z is 1.2-1.3 mm at the viewpoints' 0.4-0.6 m (plus 1/8 px steps)
    assert 0.5 < summary["rmse_mm"] < 2.5
    assert np.abs(summary["axis_mean_mm"]).max() < 0.5  # unbiased
    # the full sensor adds the unit's systematic z' = z (1 + s) + o: every corner moves along
    # its ray by about s z + o (z from 0.4 to 0.6 m: s z varies by < 0.65 mm for |s| <= 1 %)
    full = reconstruct_wrist(exact, None, seed=2, poses=3)
    unit = full["depth_unit"]
    shift_mm = 1000.0 * abs(unit["depth_scale"] * 0.5 + unit["depth_offset_m"])
    assert shift_mm > 3.0  # this seed's unit is a clear case (-0.56 %, -4.3 mm)
    mean = np.linalg.norm(full["robot_frame"]["calibrated"]["axis_mean_mm"])
    assert mean == pytest.approx(shift_mm, abs=1.0)
    with pytest.raises(ReconstructionError, match="DepthNoiseConfig"):
        reconstruct_wrist(exact, None, seed=0, poses=1, depth_noise=True)


def test_calibration_buys_most_of_the_mount_error_in_the_robot_frame():
    # the true cell of robot seed 3 has its Xtion a few mm off the nominal mount (and a
    # depth-to-RGB registration offset); ideal depth isolates the chain
    capture = capture_views(
        CalibrationCaptureConfig(cameras=("wrist",), poses_per_camera=5, robot_seed=3)
    )
    out = reconstruct_wrist(calibrate_capture(capture), 3, seed=0, poses=3, depth_noise=None)
    calibrated, nominal = (out["robot_frame"][c]["rmse_mm"] for c in ("calibrated", "nominal"))
    assert nominal > 3.0  # measured 5.9 mm
    assert calibrated < 0.3 * nominal  # measured 0.6 mm
