"""Reconstruction accuracy of the calibrated cameras, as thesis Tables 4.2-4.5.

The 24 mm checkerboard (thesis ch. 4) is presented by the left arm at ``poses`` random poses
(the sampling of :mod:`ipbench.eval.calibration.calibrate`'s head capture: a point in the
presentation
box, the face turned towards the head within ``head_tilt_deg`` and rolled within
``head_roll_deg``), in the *true* cell of ``robot_seed``
(:func:`~ipbench.envs.cell.model_errors.sample_model_errors`), and reconstructed:

- **head** (:func:`reconstruct_head`): per trial the board is presented at pose *A*, both
  head cameras image the scene at the calibration gaze ``g0`` (the *before* images), then both
  PTUs move to a random gaze ``g = g0 + (dpan, dtilt)`` (uniform within :data:`PAN_RANGE_DEG`
  and :data:`TILT_RANGE_DEG` per unit, on the PTU step grid) and image it again (the *after*
  images, from which the dynamic update is computed: board *A*, still through the move, gives
  it most of its features, so it must be whole in both after images). Then the arm shows the
  board at another sampled pose *B* and both cameras image it (the *scored* images): its
  corners are found there (``cv2.findChessboardCornersSB`` on the distorted images; a view in
  which the image border cuts the printed board, margin included, is drawn again and counted
  in ``cut_by_border``: :func:`~ipbench.perception.calibration.target.board_in_view`; so is a
  view with a corner found off the board's plane, beyond
  :data:`~ipbench.perception.calibration.target.PLANAR_PX` of the homography the corners fit
  once undistorted with the calibrated lens, counted in ``off_plane``). Every
  method is scored on board *B*, which no estimate saw: the update cannot be scored on
  corners it fitted. Poses and gazes that put a board outside a view by geometry alone (the
  pinhole cameras of the true cell) are drawn again before anything is rendered. The corners
  are undistorted with the calibrated distortion and triangulated with:

  * ``true``: the true intrinsics, lens and poses (the floor set by corner detection);
  * ``encoders``: the calibrated camera poses carried from ``g0`` to ``g`` by the *nominal*
    PTU kinematics (the cell compiled without errors) at the encoder readings,
    ``T_base_cam(g) = T_base_tilt(g) inv(T_base_tilt(g0)) T_base_cam_cal``;
  * ``dynamic`` (§4.4.4): :func:`~ipbench.perception.calibration.dynamic.update_left_pose`
    from the before/after images (SIFT) for the left camera, and the right camera by
    :func:`~ipbench.perception.calibration.dynamic.right_from_chain` with the left-to-right
    transform of the calibrated chain at the encoder readings (the calibrated stereo at
    ``g0`` carried by the nominal PTU kinematics, as ``encoders``);
  * ``dynamic_both``: the same update run for each camera on its own (the right camera as the
    "left" of the swapped pair). Reported because, with the right camera by the chain, the
    ``dynamic`` pair has exactly the ``encoders`` pair's relative pose (only the pair's place in
    the base frame changes), and corner distances depend on the relative pose only;
  * ``dynamic_checked``: ``dynamic_both`` unless the check of
    :func:`~ipbench.perception.calibration.consistency.epipolar_consistency` on the after
    images (no ground truth: the stereo pair's epipolar consensus) finds the encoders' pair
    more consistent, or the update failed; then the ``encoders`` pair. This is the robot's
    dynamic update as it would use it (``head_dynamic_rmse_mm``).

  Calibrated poses: the left camera's is the head-left hand-eye ``X`` (camera-to-base at
  ``g0``), the right one's follows from it by the calibrated stereo transform (the refined
  eq. 4.7), so the pair at ``g0`` is the calibrated stereo pair.

  Stable features: the head at ``g0`` looks at the work table, which is untextured, so
  :data:`N_PRODUCTS` textured products of the v1 catalogue (:mod:`ipbench.assets.objects`) stand
  on the table where the left camera's view at ``g0`` meets it (the room's posters are out of
  the head's view at that gaze). The board, still during a trial, is also in view.

  PTU backlash (:class:`~ipbench.envs.cell.model_errors.PtuErrors`, a dead band ``b`` per axis; no
  env applies it yet): the output shaft lags the commanded (encoder) position by ``b / 2``
  against the direction of the last move. The calibration capture reached ``g0`` moving from
  the zero position, so at ``g`` the true angle is ``g - (b / 2) (s - s0)`` with
  ``s = sign(g - g0)`` and ``s0 = sign(g0)``: no error when the move keeps the direction, ``b``
  when it reverses. The PTU zero offsets act through the true model itself.

- **wrist** (:func:`~ipbench.eval.calibration.wrist_reconstruction.reconstruct_wrist`, its own
  module,
  re-exported here): the Xtion's corners from its noisy depth, as board shape and in the robot
  base frame through the robot's calibrated (and nominal) chain.

Per trial: distances between horizontally and vertically adjacent corners against 24 mm,
and the residuals of the reconstruction against the Kabsch (rigid) fit of the board model,
per axis of the method's left camera frame (x right, y down, z along the view), mm.
Aggregates: RMSE of the distance errors and mean |residual| per axis, over all trials.

Thesis figures (A. Khan, PhD thesis, University of Glasgow, 2018, ch. 4): head RMSE 0.16 mm
(Table 4.3), per-axis residuals < 0.3 mm (Table 4.2), Xtion 12.5 mm (Table 4.4), Kinect v2
11.6 mm (Table 4.5); the Xtion's 12.5 mm is in the robot frame (a checkerboard reconstructed
through the Baxter's kinematic chain, §4.3.1). Ranges chosen from geometry before any result:
pan +-8 deg and tilt +-5 deg keep most of the before view in sight (head FOV about 37 x 25 deg
at 1024 x 680, f = 1519 px) and stay within the 13 px parallax the dynamic update's homography
filter was set for (``dynamic.py``).
"""

from __future__ import annotations

import time

import cv2
import mujoco
import numpy as np

from ipbench.assets.calibration_target import add_target_plate
from ipbench.assets.compose import HEAD_SIDES, build_workcell_spec
from ipbench.assets.objects import CATEGORIES, get_instance
from ipbench.assets.objects.builder import add_object
from ipbench.envs.cell.model_errors import ModelErrors, apply_model_errors, sample_model_errors
from ipbench.envs.ptu import ptu_spec
from ipbench.envs.sensors import SensorRenderer, camera_pose, intrinsics
from ipbench.eval.calibration.calibrate import (
    CAMERAS,
    GRIPPER_SITE,
    CellCalibration,
    _base_pose,
    _gripper_ik,
    _head_presentation,
    _hold,
    _render,
)
from ipbench.eval.calibration.head_views import (
    board_geometry,
    checked_update,
    dynamic_updates,
    outline_world,
    sees_whole,
)
from ipbench.perception.calibration.errors import CalibrationError
from ipbench.perception.calibration.poses import invert
from ipbench.perception.calibration.target import (
    PLANAR_PX,
    Checkerboard,
    board_in_view,
    find_corners,
    planar_residual_px,
)
from ipbench.perception.stereo import StereoRig

__all__ = [
    "HEAD_METHODS",
    "N_PRODUCTS",
    "PAN_RANGE_DEG",
    "THESIS",
    "TILT_RANGE_DEG",
    "ReconstructionError",
    "board_errors",
    "reconstruct_head",
]

PAN_RANGE_DEG = 8.0
TILT_RANGE_DEG = 5.0
N_PRODUCTS = 6
HEAD_METHODS = ("true", "encoders", "dynamic", "dynamic_both", "dynamic_checked")
THESIS = {  # A. Khan, PhD thesis, University of Glasgow, 2018, ch. 4
    "head_rmse_mm": 0.16,  # Table 4.3
    "head_axis_residual_max_mm": 0.3,  # Table 4.2
    "xtion_rmse_mm": 12.5,  # Table 4.4
    "kinect_v2_rmse_mm": 11.6,  # Table 4.5
}
_MAX_ATTEMPTS = 300  # sampled trials per kept one at most (boards out of view, IK failures)
_PRODUCT_PIXELS = ((0.15, 0.55), (0.5, 0.6), (0.85, 0.55), (0.2, 0.9), (0.55, 0.92), (0.85, 0.9))


class ReconstructionError(CalibrationError):
    """Bad input to the reconstruction evaluation, or a run that cannot reconstruct."""


def board_errors(points: np.ndarray, board: Checkerboard, frame: np.ndarray) -> dict:
    """Distance errors and rigid-fit residuals of a reconstructed board.

    points : (N, 3) corners, m, in the order of ``board.object_points()``.
    frame : (3, 3) rotation whose columns are the axes the residuals are given in.
    Returns ``distance_errors_mm`` ((E,) adjacent-corner distances minus the square, mm) and
    ``residuals_mm`` ((N, 3) reconstruction minus the fitted board, mm, in ``frame``).
    """
    points = np.asarray(points, float)
    model = np.asarray(board.object_points(), float).reshape(-1, 3)
    if points.shape != model.shape or not np.all(np.isfinite(points)):
        raise ReconstructionError(
            f"points must be finite {model.shape} corners of the board, got {points.shape}"
        )
    grid = points.reshape(board.rows, board.cols, 3)
    lengths = np.concatenate([
        np.linalg.norm(np.diff(grid, axis=1), axis=2).ravel(),
        np.linalg.norm(np.diff(grid, axis=0), axis=2).ravel(),
    ])  # fmt: skip
    # Kabsch: the rotation and translation taking the board model onto the points
    pm, mm = points.mean(0), model.mean(0)
    u, _, vt = np.linalg.svd((model - mm).T @ (points - pm))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    R = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    fitted = (model - mm) @ R.T + pm
    return {
        "distance_errors_mm": 1000.0 * (lengths - board.square_m),
        "residuals_mm": 1000.0 * (points - fitted) @ np.asarray(frame, float),
    }


def _summary(trials: list[dict]) -> dict:
    dist = np.concatenate([t["distance_errors_mm"] for t in trials])
    res = np.concatenate([t["residuals_mm"] for t in trials])
    return {
        "rmse_mm": float(np.sqrt(np.mean(dist**2))),
        "mean_abs_distance_error_mm": float(np.mean(np.abs(dist))),
        "axis_mean_abs_residual_mm": [float(v) for v in np.mean(np.abs(res), axis=0)],
        "per_trial_rmse_mm": [
            float(np.sqrt(np.mean(t["distance_errors_mm"] ** 2))) for t in trials
        ],  # fmt: skip
    }


def _trial_record(trial: dict) -> dict:
    """A trial as ``per_trial`` reports it: gaze, the scored board's geometry, the check, and
    each method's RMSE, mm."""
    rmse = {m: float(np.sqrt(np.mean(e["distance_errors_mm"] ** 2)))
            for m, e in trial["methods"].items()}  # fmt: skip
    return {k: v for k, v in trial.items() if k != "methods"} | {"rmse_mm": rmse}


def _errors(robot_seed) -> ModelErrors:
    if robot_seed is None:
        return ModelErrors.none()
    if (
        isinstance(robot_seed, bool)
        or not isinstance(robot_seed, (int, np.integer))
        or robot_seed < 0
    ):
        raise ReconstructionError(f"robot_seed must be None or an int >= 0, got {robot_seed!r}")
    return sample_model_errors(int(robot_seed))


def _check(calibration, group: str, poses, seed) -> None:
    if not isinstance(calibration, CellCalibration):
        raise ReconstructionError(
            f"calibration must be a CellCalibration (eval.calibrate.calibrate_capture), got "
            f"{type(calibration).__name__}"
        )
    name = "head_left" if group == "head" else group
    if name not in calibration.intrinsics or (group == "head" and calibration.stereo is None):
        raise ReconstructionError(
            f"the calibration has no {group} cameras (it has {sorted(calibration.intrinsics)}); "
            f"calibrate with cameras including {group!r}"
        )
    for name, value, least in (("poses", poses, 1), ("seed", seed, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
            raise ReconstructionError(f"{name} must be an int >= {least}, got {value!r}")


def _spec(board: Checkerboard, px: int, errors: ModelErrors | None, products=()):
    """The calibration cell (as ``calibrate.build_calibration_model``) plus free products
    standing still at ``products`` ((category, index, (x, y, z)) each)."""
    spec = build_workcell_spec()
    if errors is not None:
        apply_model_errors(spec, errors)
    texture = board.render_texture(px)
    origin = (board.texture_corners_px(px)[0] + 0.5) * board.size_m[0] / texture.shape[1]
    plate = add_target_plate(spec, texture, board.size_m, GRIPPER_SITE, origin_m=tuple(origin))
    for k, (category, index, pos) in enumerate(products):
        add_object(spec, get_instance(category, index), f"recon_product_{k}", pos)
    return spec.compile(), plate


def _head_adr(model) -> list[int]:
    return [model.jnt_qposadr[model.joint(f"head_{s}_{j}").id]
            for s in HEAD_SIDES for j in ("pan", "tilt")]  # fmt: skip


def _products(model, gaze: np.ndarray, size, rng: np.random.Generator) -> list:
    """Products where the left camera's rays through :data:`_PRODUCT_PIXELS` meet the table."""
    data = mujoco.MjData(model)
    data.qpos[_head_adr(model)] = gaze
    mujoco.mj_forward(model, data)
    w, h = size
    K = intrinsics(model, CAMERAS["head_left"], w, h).K
    pose = camera_pose(model, data, CAMERAS["head_left"])
    out, geom = [], np.zeros(1, np.int32)
    for k, (fu, fv) in enumerate(_PRODUCT_PIXELS):
        ray = pose[:3, :3] @ np.linalg.solve(K, [fu * w, fv * h, 1.0])
        dist = mujoco.mj_ray(model, data, pose[:3, 3], ray / np.linalg.norm(ray), None, 1, -1,
                             geom)  # fmt: skip
        if dist < 0:
            continue
        hit = pose[:3, 3] + dist * ray / np.linalg.norm(ray)
        category = CATEGORIES[k % len(CATEGORIES)]
        out.append((category, int(rng.integers(12)), tuple(hit)))
    return out


def _tilt_pose(model, data, side: str) -> np.ndarray:
    body = data.body(f"head_{side}_tilt_link")
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = body.xmat.reshape(3, 3), body.xpos
    return invert(_base_pose(data)) @ pose


def _cam_base(model, data, name: str) -> np.ndarray:
    return invert(_base_pose(data)) @ camera_pose(model, data, CAMERAS[name])


def _backlash(gaze: np.ndarray, g0: np.ndarray, errors: ModelErrors) -> np.ndarray:
    """True PTU angles at encoder reading ``gaze`` after a move from ``g0`` (module docstring)."""
    b = np.concatenate([errors.ptu(s).backlash for s in HEAD_SIDES])
    return gaze - 0.5 * b * (np.sign(gaze - g0) - np.sign(g0))


def _triangulate(K_l, pose_l, dist_l, K_r, pose_r, dist_r, xl, xr) -> np.ndarray:
    def ideal(xy, K, dist):
        return cv2.undistortPoints(xy.reshape(-1, 1, 2), K, dist, P=K).reshape(-1, 2)

    rig = StereoRig(K_l, pose_l, K_r, pose_r)
    return rig.triangulate(ideal(xl, K_l, dist_l), ideal(xr, K_r, dist_r))


def reconstruct_head(
    calibration: CellCalibration, robot_seed: int | None, seed: int, poses: int = 10
) -> dict:
    """Head reconstruction of the board at ``poses`` random poses and gazes (module docstring).

    Returns ``{"methods": {method: summary}, "trials": [...], "seconds": float, ...}`` where
    each summary (:data:`HEAD_METHODS`) has ``rmse_mm``, ``mean_abs_distance_error_mm``,
    ``axis_mean_abs_residual_mm`` ((3,) x, y, z), ``per_trial_rmse_mm``; a method whose
    update fails in a trial (:class:`CalibrationError`) is left out of that trial and counted
    in ``failures``; ``paired`` holds the same summaries over the ``paired_trials`` trials
    that every method reconstructed (compare methods there); ``cut_by_border`` counts the
    views drawn again because the image border cut the board, ``off_plane`` those drawn again
    for a corner found off the board's plane; ``fallbacks`` the trials whose
    ``dynamic_checked`` is the encoders' pair; ``per_trial`` each trial's gaze, the scored
    board's distance and incidence (``board_distance_m``, ``incidence_deg``), what the check
    saw (``check``) and each method's RMSE (``rmse_mm``).
    """
    _check(calibration, "head", poses, seed)
    start = time.perf_counter()
    capture, file = calibration.capture, calibration.file
    config, board, head = capture.config, capture.board, capture.head
    errors = _errors(robot_seed)
    rng = np.random.default_rng([seed, 14, 6])
    g0 = np.asarray(head.gaze, float)
    size = head.image_size
    nominal_plain, _ = _spec(board, config.px_per_square, None)
    products = _products(nominal_plain, g0, size, rng)
    true_model, plate = _spec(board, config.px_per_square, errors, products)
    nominal, _ = _spec(board, config.px_per_square, None, products)
    data, ndata = mujoco.MjData(true_model), mujoco.MjData(nominal)
    adr = _head_adr(true_model)
    intr = {n: calibration.intrinsics[n] for n in ("head_left", "head_right")}
    K = {n: i.K for n, i in intr.items()}
    dist = {n: i.dist for n, i in intr.items()}
    cal = {"head_left": np.asarray(file.hand_eye["head_left"].X, float)}
    cal["head_right"] = cal["head_left"] @ invert(np.asarray(file.stereo.left_to_right, float))
    ndata.qpos[adr] = g0
    mujoco.mj_forward(nominal, ndata)
    tilt0 = {s: _tilt_pose(nominal, ndata, s) for s in HEAD_SIDES}
    true_K = {n: intrinsics(true_model, CAMERAS[n], *size).K for n in K}
    true_dist = {n: np.array(errors.distortion[CAMERAS[n]].coefficients, float) for n in K}
    ik = _gripper_ik(true_model)
    centre = np.asarray(config.head_centre, float)
    spec = ptu_spec()
    mujoco.mj_forward(true_model, data)
    q_home = data.qpos.copy()
    data.qpos[adr] = g0
    mujoco.mj_forward(true_model, data)
    head_mid = 0.5 * (data.cam(CAMERAS["head_left"]).xpos + data.cam(CAMERAS["head_right"]).xpos)
    renderer = SensorRenderer(true_model)
    trials, failures = [], {m: 0 for m in HEAD_METHODS}
    attempts = cut = fallbacks = off_plane = 0
    try:
        while len(trials) < poses and attempts < poses * _MAX_ATTEMPTS:
            attempts += 1
            # board A, still through the move, gives the update its features; board B, shown
            # after the update, is scored: no method is scored on a corner it fitted
            shown = [_head_presentation(rng, centre, head_mid, config) for _ in range(2)]
            step = np.radians(
                rng.uniform(-1.0, 1.0, 4) * np.tile([PAN_RANGE_DEG, TILT_RANGE_DEG], 2)
            )
            gaze = np.concatenate([spec.command(g) for g in np.split(g0 + step, 2)])
            truly_at = _backlash(gaze, g0, errors)
            boards = [outline_world(shown[0], board), outline_world(shown[1], board)]
            views = ((g0, boards[0]), (truly_at, boards[0]), (truly_at, boards[1]))
            if not all(sees_whole(true_model, data, adr, at, b, true_K, size) for at, b in views):
                continue  # a board out of a view, by geometry alone: nothing is rendered
            q_update, q_scored = (_hold(ik, q_home, plate, *s) for s in shown)
            if q_update is None or q_scored is None:
                continue
            data.qpos[:] = q_update
            data.qpos[adr] = g0
            mujoco.mj_forward(true_model, data)
            before = {n: _render(renderer, true_model, data, n, size, errors) for n in K}
            data.qpos[adr] = truly_at
            mujoco.mj_forward(true_model, data)
            after = {n: _render(renderer, true_model, data, n, size, errors) for n in K}
            seen = [find_corners(after[n], board) for n in K]
            if any(c is None or not board_in_view(c, board, size) for c in seen):
                continue  # the update needs board A's texture in view: the products are few
            data.qpos[:] = q_scored
            data.qpos[adr] = truly_at
            mujoco.mj_forward(true_model, data)
            scored = {n: _render(renderer, true_model, data, n, size, errors) for n in K}
            corners = {n: find_corners(scored[n], board) for n in K}
            if corners["head_left"] is None or corners["head_right"] is None:
                continue
            if not all(board_in_view(c, board, size) for c in corners.values()):
                cut += 1  # the border cuts the board: its outer corners are not measurable
                continue
            if any(planar_residual_px(corners[n], board, K[n], dist[n]) > PLANAR_PX for n in K):
                off_plane += 1  # a corner found off the board's plane: the detector failed
                continue
            ndata.qpos[adr] = gaze
            mujoco.mj_forward(nominal, ndata)
            enc = {}
            for n, s in zip(("head_left", "head_right"), HEAD_SIDES, strict=True):
                enc[n] = _tilt_pose(nominal, ndata, s) @ invert(tilt0[s]) @ cal[n]
            est = {
                "true": {n: _cam_base(true_model, data, n) for n in K},
                "encoders": enc,
            }
            est.update(dynamic_updates(before, after, K, dist, cal, enc, failures))
            est["dynamic_checked"], check = checked_update(after, K, dist, est)
            fallbacks += check["chosen"] != "dynamic_both"
            trial = {"gaze_rad": gaze.tolist(), "methods": {}, "check": check,
                     **board_geometry(shown[1], head_mid)}  # fmt: skip
            for method, pose in est.items():
                k = true_K if method == "true" else K
                dd = true_dist if method == "true" else dist
                pts = _triangulate(k["head_left"], pose["head_left"], dd["head_left"],
                                   k["head_right"], pose["head_right"], dd["head_right"],
                                   corners["head_left"], corners["head_right"])  # fmt: skip
                trial["methods"][method] = board_errors(pts, board, pose["head_left"][:3, :3])
            trials.append(trial)
    finally:
        renderer.close()
    if not trials:
        raise ReconstructionError(
            f"no board view in {attempts} sampled trials; move the presentation volume into the "
            "head's view or lower PAN_RANGE_DEG / TILT_RANGE_DEG"
        )
    methods = {}
    for m in HEAD_METHODS:
        kept = [t["methods"][m] for t in trials if m in t["methods"]]
        if kept:
            methods[m] = _summary(kept)
    # the same trials for every method: a method that fails on hard views is otherwise scored
    # on easier ones than the others
    common = [t for t in trials if all(m in t["methods"] for m in HEAD_METHODS)]
    paired = {m: _summary([t["methods"][m] for t in common]) for m in HEAD_METHODS if common}
    return {
        "methods": methods,
        "paired": paired,
        "paired_trials": len(common),
        "failures": failures,
        "trials": len(trials),
        "attempts": attempts,
        "cut_by_border": cut,
        "off_plane": off_plane,
        "products": [p[:2] for p in products],
        "fallbacks": fallbacks,
        "per_trial": [_trial_record(t) for t in trials],
        "seconds": time.perf_counter() - start,
    }
