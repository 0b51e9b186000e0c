"""The wrist Xtion's reconstruction of the 24 mm board, in its own frame and in the robot's
(thesis Table 4.4).

The left arm holds the board face up at the capture's ``wrist_board_centre`` in the *true* cell
of ``robot_seed`` (:func:`~ipbench.envs.cell.model_errors.sample_model_errors`) and the right arm
moves the Xtion to random viewpoints (the sampling of
:mod:`ipbench.eval.calibration.calibrate`'s wrist
capture). The depth is the Sorting-v2 sensor's (:data:`~ipbench.envs.sensors.depth_noise.
STRUCTURED_LIGHT` via :meth:`~ipbench.envs.sensors.depth_noise.DepthNoiseModel.apply`, as
``SortingEnv._observation`` calls it, with one unit error per run whose depth-to-RGB shift is
the true cell's registration offset, as in the envs). Each corner found in the RGB image
(undistorted with the calibrated lens) takes the depth at its nearest pixel and is
back-projected with the calibrated ``K``: a point in the camera frame. A view is kept when the
board is found and at least half of its corners have depth; corners without depth are left out.
Two measurements per view:

- **board shape** (as the head's, :func:`~ipbench.eval.calibration.reconstruction.board_errors`):
  distances between adjacent corners against 24 mm and the residuals of a rigid fit of the
  board model, per axis of the camera frame.
- **robot frame** (:data:`ROBOT_FRAME_CHAINS`): the points carried into the robot base frame
  by what the robot believes of its camera at its joint readings, exactly as
  :class:`~ipbench.envs.cell.extrinsics.CameraKnowledge` gives it to the envs: ``calibrated`` (the
  nominal forward kinematics of the flange times the calibration file's eye-in-hand ``X``)
  and ``nominal`` (the nominal model's camera mount: no calibration); against each corner's
  TRUE base-frame position (the plate's pose in the true cell and the board's layout on it).
  Residual = believed - true, per axis of the base frame, mm; 3D RMSE over all corners. The
  arm chains carry no model error (:mod:`ipbench.eval.calibration.calibrate`), so what is left is
  the
  hand-eye ``X``, the intrinsics and the depth; the thesis' 12.5 mm (Table 4.4, a Baxter arm
  and a real Xtion) also holds a real arm's kinematic error.
"""

from __future__ import annotations

import dataclasses
import tempfile
import time
from pathlib import Path

import cv2
import mujoco
import numpy as np

from ipbench.envs.cell.calibration_file import CalibrationFile
from ipbench.envs.cell.extrinsics import BASE_BODY, CameraKnowledge
from ipbench.envs.sensors import SensorRenderer, intrinsics, specular_geoms
from ipbench.envs.sensors.depth_noise import STRUCTURED_LIGHT, DepthNoiseConfig, DepthNoiseModel
from ipbench.eval.calibration.calibrate import (
    CAMERAS,
    CellCalibration,
    _base_pose,
    _wrist_look,
    _wrist_setup,
)
from ipbench.eval.calibration.reconstruction import (
    _MAX_ATTEMPTS,
    ReconstructionError,
    _check,
    _errors,
    _spec,
    _summary,
    board_errors,
)
from ipbench.perception.calibration.poses import invert
from ipbench.perception.calibration.target import Checkerboard

__all__ = ["ROBOT_FRAME_CHAINS", "reconstruct_wrist", "robot_frame_summary"]

ROBOT_FRAME_CHAINS: tuple[str, ...] = ("calibrated", "nominal")
"""The robot's beliefs of the wrist camera's pose (``extrinsics`` modes of the envs)."""


def robot_frame_summary(residuals: list[np.ndarray]) -> dict:
    """``{"rmse_mm", "axis_mean_mm", "axis_std_mm", "per_trial_rmse_mm", "corners"}`` of
    per-trial ``residuals`` ((N_i, 3) believed minus true corner positions, mm, base frame):
    3D RMSE over all corners, mean and standard deviation per axis (3,), RMSE per trial."""
    if not residuals or any(np.ndim(r) != 2 or np.shape(r)[1] != 3 for r in residuals):
        raise ReconstructionError("residuals must be a non-empty list of (N, 3) arrays, mm")
    res = np.concatenate(residuals)

    def rmse(r: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.sum(r**2, axis=1))))

    return {
        "rmse_mm": rmse(res),
        "axis_mean_mm": [float(v) for v in res.mean(axis=0)],
        "axis_std_mm": [float(v) for v in res.std(axis=0)],
        "per_trial_rmse_mm": [rmse(r) for r in residuals],
        "corners": len(res),
    }


def _body_pose(data, name: str) -> np.ndarray:
    pose = np.eye(4)
    body = data.body(name)
    pose[:3, :3], pose[:3, 3] = body.xmat.reshape(3, 3), body.xpos
    return pose


def _beliefs(file: CalibrationFile) -> dict[str, CameraKnowledge]:
    """The envs' knowledge of the wrist camera per chain (the file goes through disk, as the
    envs read it)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = file.save(Path(tmp) / "calibration.json")
        calibrated = CameraKnowledge.build("calibrated", ("wrist",), path)
    return {"calibrated": calibrated, "nominal": CameraKnowledge.build("nominal", ("wrist",))}


def _nominal_base(knowledge: CameraKnowledge) -> np.ndarray:
    data = mujoco.MjData(knowledge.model)
    mujoco.mj_kinematics(knowledge.model, data)
    return _body_pose(data, BASE_BODY)


def _partial_errors(pts, ok, board: Checkerboard, pair_ok, errs) -> dict:
    """``board_errors`` restricted to corners with depth (distances of pairs with both)."""
    model = np.asarray(board.object_points(), float).reshape(-1, 3)[ok]
    p = pts[ok]
    pm, mm = p.mean(0), model.mean(0)
    u, _, vt = np.linalg.svd((model - mm).T @ (p - pm))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    R = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return {
        "distance_errors_mm": errs["distance_errors_mm"][pair_ok],
        "residuals_mm": 1000.0 * (p - ((model - mm) @ R.T + pm)),
    }


def reconstruct_wrist(
    calibration: CellCalibration,
    robot_seed: int | None,
    seed: int,
    poses: int = 10,
    *,
    depth_noise: DepthNoiseConfig | None = STRUCTURED_LIGHT,
) -> dict:
    """Wrist Xtion reconstruction of the board at ``poses`` viewpoints (module docstring).

    ``depth_noise``: the sensor model (default: Sorting-v2's); ``None`` reads the ideal
    rendered depth (a check of the measurement itself). Returns ``{"rmse_mm",
    "mean_abs_distance_error_mm", "axis_mean_abs_residual_mm", "per_trial_rmse_mm", "trials",
    "attempts", "missing_corners", "depth_unit", "robot_frame", "seconds"}``: the board-shape
    figures in the camera frame; ``depth_unit``, the run's unit error (``depth_scale``,
    ``depth_offset_m``, and ``shift_px``: the true cell's registration shift; None: none);
    ``robot_frame``: chain
    (:data:`ROBOT_FRAME_CHAINS`) -> :func:`robot_frame_summary`.
    """
    if depth_noise is not None and not isinstance(depth_noise, DepthNoiseConfig):
        raise ReconstructionError(
            f"depth_noise must be a DepthNoiseConfig (e.g. STRUCTURED_LIGHT) or None (ideal "
            f"depth), got {type(depth_noise).__name__}"
        )
    _check(calibration, "wrist", poses, seed)
    if calibration.file.hand_eye.get("wrist") is None:
        raise ReconstructionError(
            "the calibration has no wrist hand-eye X; calibrate with cameras including 'wrist'"
        )
    start = time.perf_counter()
    capture = calibration.capture
    config, board = capture.config, capture.board
    errors = _errors(robot_seed)
    rng = np.random.default_rng([seed, 14, 7])
    model, plate = _spec(board, config.px_per_square, errors)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    ik = _wrist_setup(model, data, plate, config, ReconstructionError)
    q_hold = data.qpos.copy()
    calib = calibration.intrinsics["wrist"]
    w, h = calib.image_size
    noise = None if depth_noise is None else DepthNoiseModel(depth_noise)
    unit = None if noise is None else noise.draw_unit(rng)
    if unit is not None:  # as the envs: the robot's registration replaces the unit's shift
        unit = dataclasses.replace(unit, shift_px=(0, 0))
    shiny = specular_geoms(model)
    du, dv = errors.registration_shift_px
    beliefs = _beliefs(calibration.file)
    base_belief = {c: invert(_nominal_base(k)) for c, k in beliefs.items()}
    readings = {c: model.jnt_qposadr[[model.joint(j).id for j in k.joint_names]]
                for c, k in beliefs.items()}  # fmt: skip
    board_pts = np.column_stack([board.object_points().reshape(-1, 3), np.ones(board.n_corners)])
    renderer = SensorRenderer(model)
    trials, robot, missing, attempts = [], {c: [] for c in beliefs}, 0, 0
    try:
        while len(trials) < poses and attempts < poses * _MAX_ATTEMPTS:
            attempts += 1
            corners = _wrist_look(
                ik, q_hold, config, rng, renderer, model, data, (w, h), errors, board
            )
            if corners is None:
                continue
            _, depth = renderer.render_rgbd(data, CAMERAS["wrist"], w, h)
            if noise is not None:
                k_true = intrinsics(model, CAMERAS["wrist"], w, h)
                seg = renderer.render_segmentation(data, CAMERAS["wrist"], w, h)
                specular = shiny[seg] if noise.uses_specular else None
                depth = noise.apply(depth, k_true.fx, k_true.fy, rng, specular=specular, unit=unit)
            ideal = cv2.undistortPoints(corners.reshape(-1, 1, 2), calib.K, calib.dist, P=calib.K)
            ideal = ideal.reshape(-1, 2)
            u = np.clip(np.rint(ideal[:, 0]).astype(int) - du, 0, w - 1)
            v = np.clip(np.rint(ideal[:, 1]).astype(int) - dv, 0, h - 1)
            z = depth[v, u].astype(float)
            ok = z > 0
            if ok.sum() < len(z) / 2:
                continue
            missing += int((~ok).sum())
            rays = np.column_stack([ideal, np.ones(len(ideal))]) @ np.linalg.inv(calib.K).T
            pts = rays * z[:, None]
            errs = board_errors(np.where(ok[:, None], pts, 0.0), board, np.eye(3))
            grid = ok.reshape(board.rows, board.cols)
            pair_ok = np.concatenate([(grid[:, 1:] & grid[:, :-1]).ravel(),
                                      (grid[1:] & grid[:-1]).ravel()])  # fmt: skip
            if not ok.all():  # refit on the corners with depth
                errs = _partial_errors(pts, ok, board, pair_ok, errs)
            trials.append(errs)
            # robot frame: the true corners (plate pose and board layout) against the beliefs
            plate_pose = _body_pose(data, plate.body) @ plate.plate_from_board
            true_base = (invert(_base_pose(data)) @ plate_pose @ board_pts.T).T[ok, :3]
            cam_pts = np.column_stack([pts[ok], np.ones(int(ok.sum()))])
            for c, knowledge in beliefs.items():
                pose = knowledge.observe(data.qpos[readings[c]], {"wrist": (w, h)})["wrist"].pose
                believed = (base_belief[c] @ pose @ cam_pts.T).T[:, :3]
                robot[c].append(1000.0 * (believed - true_base))
    finally:
        renderer.close()
    if not trials:
        raise ReconstructionError(
            f"no wrist view of the board with depth in {attempts} sampled viewpoints"
        )
    out = _summary(trials)
    out.update(trials=len(trials), attempts=attempts, missing_corners=missing,
               depth_unit=None if unit is None  # the shift applied: the robot's registration
               else dataclasses.asdict(dataclasses.replace(unit, shift_px=(du, dv))),
               robot_frame={c: robot_frame_summary(r) for c, r in robot.items()},
               seconds=time.perf_counter() - start)  # fmt: skip
    return out
