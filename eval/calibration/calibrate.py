"""The robot calibrates itself in the simulated cell (thesis ch. 4): ``ipbench calibrate``.

The left gripper holds the 24 mm checkerboard plate (:mod:`ipbench.assets.calibration_target`)
and the robot samples views automatically, as the thesis did with its arm:

- **head** (eye-to-hand, Fig. 4.4): both PTUs are aimed once, at the centre of the volume
  where the board is presented, and stay there for the whole run; the left arm presents the
  board at sampled poses (positions in a box around that centre, the face turned towards the
  head within :attr:`CalibrationCaptureConfig.head_tilt_deg` and rolled within
  ``head_roll_deg``), solved by :class:`~ipbench.envs.ik.ArmIK` on ``left_gripper_tcp``
  (unconverged solves are discarded). Both head cameras are rendered; a view is kept when
  both find the whole board. *Choice*: the PTUs are fixed at one gaze per run, so each head
  camera's hand-eye ``X`` is camera-to-robot-base at that gaze (the file format's
  ``eye_to_hand`` X, Fig. 4.4's head calibrated against the robot base), and the stereo
  transform is the one at that gaze; the gaze is recorded in :class:`HeadViews` and in the
  file's ``head_gaze``. (With the
  PTUs moving, ``X`` would instead be taken relative to the tilt link through the encoders.)
- **wrist** (eye-in-hand): the left gripper holds the board still, face up; the right arm
  moves the Xtion around it (viewpoints within ``wrist_tilt_deg`` of the board's normal at
  ``wrist_distance_m``, looking at the board; IK on ``right_wrist_optical`` with a free roll).
  The Xtion sits on the B link, so joint T is not moved (it does not move the camera) and
  ``X`` is camera-to-flange (``right_flange``), constant.

Arms and PTUs are set kinematically (``mj_forward``; no physics). The robot's own poses are
the forward kinematics of the model from its joint readings. With
:attr:`CalibrationCaptureConfig.robot_seed` set, the simulated cell is a *true* one that
differs from the nominal model by :func:`~ipbench.envs.cell.model_errors.sample_model_errors`
(camera mounts, PTU bases and zeros, lens distortion): images are rendered from it and
distorted by its lenses, and the truth is read from it. The arm chains carry no error, so the
gripper and flange poses the robot computes from its encoders are the true ones.
:func:`calibrate_capture` then calibrates each camera's intrinsics
(``cv2.calibrateCamera``), solves each view's board pose (``cv2.solvePnP`` with those
intrinsics), runs every method of ``HAND_EYE_METHODS`` and keeps, per camera, the one with the
smallest ``AX = XB`` residual (score: translation RMS in mm plus the rotation RMS as the
displacement it causes at 1 m, 1000 mm x rad; fixed before any result was seen), and the
head's stereo transform by eq. 4.7 refined by bundle adjustment. :func:`calibration_truth`
reads the simulator's true values, for evaluation only.

Sources: 24 mm squares and sampling by the arm (thesis ch. 4); head image 1024 x 680 (the
envs' ``head_size``) and wrist 640 x 480 (``ipbench.envs.sorting.WRIST_SIZE``); 15 poses per
camera (the thesis used 10 board poses; OpenCV's test 10; 15 leaves margin for rejects).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import cv2
import mujoco
import numpy as np

from ipbench.assets.calibration_target import TargetPlate, add_target_plate
from ipbench.assets.compose import (
    CAMERA_ARM,
    GRIPPER_ARM,
    HEAD_SIDES,
    arm_joint_names,
    build_workcell_spec,
    head_gaze,
)
from ipbench.envs.cell.calibration_file import (
    CalibrationFile,
    CameraCalibration,
    HandEyeEntry,
    StereoEntry,
)
from ipbench.envs.cell.model_errors import ModelErrors, apply_model_errors, sample_model_errors
from ipbench.envs.ik import ArmIK, look_at_rotation
from ipbench.envs.ptu import ptu_spec
from ipbench.envs.sensors import SensorRenderer, camera_pose, intrinsics
from ipbench.envs.sensors.lens_distortion import distort_image
from ipbench.envs.sorting import WRIST_SIZE
from ipbench.perception.calibration.errors import CalibrationError
from ipbench.perception.calibration.hand_eye import (
    HAND_EYE_METHODS,
    MIN_POSES,
    HandEyeResult,
    calibrate_hand_eye,
)
from ipbench.perception.calibration.intrinsics import Intrinsics, calibrate_intrinsics
from ipbench.perception.calibration.poses import from_rvec_tvec, invert
from ipbench.perception.calibration.stereo_extrinsics import (
    StereoRefinement,
    refine_stereo,
    stereo_from_target_poses,
)
from ipbench.perception.calibration.target import Checkerboard, find_corners

__all__ = [
    "CAMERA_GROUPS",
    "CalibrationCapture",
    "CalibrationCaptureConfig",
    "CalibrationRoutineError",
    "CalibrationTruth",
    "CellCalibration",
    "HeadViews",
    "WristViews",
    "build_calibration_model",
    "calibrate_capture",
    "calibrate_cell",
    "calibration_truth",
    "capture_views",
    "model_errors",
]

CAMERA_GROUPS = ("head", "wrist")
CAMERAS = {  # observation name -> MuJoCo camera
    "head_left": "head_left_camera",
    "head_right": "head_right_camera",
    "wrist": f"{CAMERA_ARM}_wrist_camera",
}
BASE_BODY = "base"  # the robot base (motoman.xml), the frame of the robot's kinematics
GRIPPER_SITE = f"{GRIPPER_ARM}_gripper_tcp"
FLANGE_SITE = f"{CAMERA_ARM}_flange"
OPTICAL_SITE = f"{CAMERA_ARM}_wrist_optical"
_UP = np.array([0.0, 0.0, 1.0])  # the wrist board faces up
HEAD_SIZE = (1024, 680)  # (width, height); the envs' head_size (680, 1024)
WRIST_IMAGE_SIZE = (WRIST_SIZE[1], WRIST_SIZE[0])  # (width, height) 640 x 480
# the left arm holds the board from its own side, the plate extending along -y from the TCP
# (the board upright with the gripper below it left the arm in the head's view, or unreachable)
_HEAD_HOLD_UP = (0.0, -1.0, 0.0)
# hand-eye choice: a rotation residual counts as the displacement it causes at this distance
_LEVER_MM = 1000.0


class CalibrationRoutineError(CalibrationError):
    """Bad configuration of the calibration routine, or a capture that cannot calibrate."""


def _size(value, name: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in value)
    except (TypeError, ValueError):
        raise CalibrationRoutineError(f"{name} must be (width, height) px, got {value!r}") from None
    if (w, h) != tuple(value) or not (64 <= w <= 1280 and 64 <= h <= 960):
        raise CalibrationRoutineError(
            f"{name} must be whole (width, height) px within 64-1280 x 64-960 (the cell's "
            f"offscreen buffer), got {value!r}"
        )
    return w, h


@dataclass(frozen=True)
class CalibrationCaptureConfig:
    """What the routine captures.

    cameras : subset of :data:`CAMERA_GROUPS` (``"head"``: both head cameras and their stereo
        transform; ``"wrist"``: the wrist Xtion).
    poses_per_camera : board views kept per camera group (>= 3).
    head_size, wrist_size : (width, height) of the rendered images, px.
    seed : seed of the pose sampling (int >= 0).
    max_attempts : sampled poses per kept view at most (IK failures and missed boards).
    px_per_square : texture resolution of the board, px per 24 mm square.
    head_centre : (3,) world centre of the head's presentation volume, m.
    head_spread : (3,) half extents of that volume, m.
    head_tilt_deg, head_roll_deg : largest turn of the face away from the head, and roll of
        the board about its normal, deg.
    wrist_board_centre : (3,) world centre of the board held for the wrist camera, m.
    wrist_tilt_deg : largest angle of a wrist viewpoint from the board normal, deg.
    wrist_distance_m : (near, far) distance of the wrist camera from the board, m.
    robot_seed : seed of the cell's model errors (``None``: the true cell is the nominal one).
    """

    cameras: tuple[str, ...] = CAMERA_GROUPS
    poses_per_camera: int = 15
    head_size: tuple[int, int] = HEAD_SIZE
    wrist_size: tuple[int, int] = WRIST_IMAGE_SIZE
    seed: int = 0
    max_attempts: int = 6
    px_per_square: int = 32
    head_centre: tuple[float, float, float] = (0.70, 0.0, 1.30)
    head_spread: tuple[float, float, float] = (0.15, 0.25, 0.15)
    head_tilt_deg: float = 40.0
    head_roll_deg: float = 25.0
    wrist_board_centre: tuple[float, float, float] = (0.65, -0.15, 1.05)
    wrist_tilt_deg: float = 35.0
    wrist_distance_m: tuple[float, float] = (0.40, 0.60)
    robot_seed: int | None = None

    def __post_init__(self) -> None:
        cams = self.cameras
        if isinstance(cams, str):
            cams = tuple(c.strip() for c in cams.split(","))
        cams = tuple(cams)
        bad = [c for c in cams if c not in CAMERA_GROUPS]
        if not cams or bad or len(set(cams)) != len(cams):
            raise CalibrationRoutineError(
                f"cameras {self.cameras!r} are not a non-empty subset of {CAMERA_GROUPS}"
                + (f" (unknown: {bad})" if bad else "")
            )
        object.__setattr__(self, "cameras", tuple(c for c in CAMERA_GROUPS if c in cams))
        for name, least in (("poses_per_camera", MIN_POSES), ("max_attempts", 1),
                            ("px_per_square", 8), ("seed", 0)):  # fmt: skip
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
                raise CalibrationRoutineError(f"{name} must be an int >= {least}, got {value!r}")
        robot = self.robot_seed
        if robot is not None and (
            isinstance(robot, bool) or not isinstance(robot, (int, np.integer)) or robot < 0
        ):
            raise CalibrationRoutineError(f"robot_seed must be None or an int >= 0, got {robot!r}")
        object.__setattr__(self, "head_size", _size(self.head_size, "head_size"))
        object.__setattr__(self, "wrist_size", _size(self.wrist_size, "wrist_size"))
        near, far = self.wrist_distance_m
        if not 0.2 <= near <= far <= 1.2:
            raise CalibrationRoutineError(
                f"wrist_distance_m must be (near, far) with 0.2 <= near <= far <= 1.2 m, got "
                f"{self.wrist_distance_m!r}"
            )
        for name in ("head_tilt_deg", "head_roll_deg", "wrist_tilt_deg"):
            if not 0.0 <= float(getattr(self, name)) <= 60.0:
                raise CalibrationRoutineError(f"{name} must be within 0-60 deg")


@dataclass(frozen=True, eq=False)
class HeadViews:
    """The head's captured views (V of them, N board corners each).

    gaze : (4,) PTU joints (left pan, left tilt, right pan, right tilt), rad, for all views.
    gripper_to_base : (V, 4, 4) TCP pose in the robot base frame (forward kinematics), m.
    left_corners, right_corners : (V, N, 2) detected corners, px.
    image_size : (width, height), px.
    """

    gaze: np.ndarray
    gripper_to_base: np.ndarray
    left_corners: np.ndarray
    right_corners: np.ndarray
    image_size: tuple[int, int]


@dataclass(frozen=True, eq=False)
class WristViews:
    """The wrist camera's captured views.

    flange_to_base : (V, 4, 4) camera arm's flange pose in the robot base frame, m.
    corners : (V, N, 2) detected corners, px.
    image_size : (width, height), px.
    """

    flange_to_base: np.ndarray
    corners: np.ndarray
    image_size: tuple[int, int]


@dataclass(frozen=True, eq=False)
class CalibrationCapture:
    """Everything captured: views per camera group (None when not asked for), the board, the
    attempts made (sampled poses per group) and the wall time, s."""

    config: CalibrationCaptureConfig
    board: Checkerboard
    head: HeadViews | None
    wrist: WristViews | None
    attempts: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0


@dataclass(frozen=True, eq=False)
class CellCalibration:
    """A calibration run's results: the file, every camera's intrinsics, every hand-eye
    method's result per camera (name -> method -> result), the stereo refinement."""

    file: CalibrationFile
    intrinsics: dict[str, Intrinsics]
    hand_eye: dict[str, dict[str, HandEyeResult]]
    stereo: StereoRefinement | None
    capture: CalibrationCapture


@dataclass(frozen=True, eq=False)
class CalibrationTruth:
    """The simulator's true values (evaluation only).

    K : camera name -> (3, 3) matrix at the captured image size, px.
    X : camera name -> (4, 4) hand-eye (wrist: camera-to-flange; head: camera-to-base at the
        capture's gaze), m, OpenCV camera axes.
    left_to_right : (4, 4) head stereo transform at the gaze, m, or None.
    """

    K: dict[str, np.ndarray]
    X: dict[str, np.ndarray]
    left_to_right: np.ndarray | None


def model_errors(config: CalibrationCaptureConfig) -> ModelErrors:
    """The cell's true model errors for ``config`` (none without a ``robot_seed``)."""
    if config.robot_seed is None:
        return ModelErrors.none()
    return sample_model_errors(int(config.robot_seed))


def build_calibration_model(
    board: Checkerboard, px_per_square: int = 32, errors: ModelErrors | None = None
) -> tuple[mujoco.MjModel, TargetPlate]:
    """The work cell (true: with ``errors`` applied) with ``board`` printed on a plate held by
    the left gripper."""
    texture = board.render_texture(px_per_square)
    origin = (board.texture_corners_px(px_per_square)[0] + 0.5) * board.size_m[0] / texture.shape[1]
    spec = build_workcell_spec()
    if errors is not None:
        apply_model_errors(spec, errors)
    plate = add_target_plate(spec, texture, board.size_m, GRIPPER_SITE, origin_m=tuple(origin))
    return spec.compile(), plate


def _render(renderer, model, data, name: str, size: tuple[int, int], errors: ModelErrors):
    """A camera's image as the true lens gives it: the pinhole render, distorted."""
    camera = CAMERAS[name]
    image = renderer.render_rgb(data, camera, *size)
    lens = errors.distortion[camera]
    if not any(lens.coefficients):
        return image
    return distort_image(image, intrinsics(model, camera, *size).K, lens)


def _site_pose(data: mujoco.MjData, name: str) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = data.site(name).xmat.reshape(3, 3)
    pose[:3, 3] = data.site(name).xpos
    return pose


def _base_pose(data: mujoco.MjData) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = data.body(BASE_BODY).xmat.reshape(3, 3)
    pose[:3, 3] = data.body(BASE_BODY).xpos
    return pose


def _aim_head(model: mujoco.MjModel, data: mujoco.MjData, target: np.ndarray) -> np.ndarray:
    """Point both head cameras at ``target`` (head_gaze, refined by forward kinematics three
    times, on the PTU step grid); returns the (4,) gaze."""
    spec = ptu_spec()
    adr = {s: [model.jnt_qposadr[model.joint(f"head_{s}_{j}").id] for j in ("pan", "tilt")]
           for s in HEAD_SIDES}  # fmt: skip
    for k in range(4):
        mujoco.mj_forward(model, data)
        for s in HEAD_SIDES:
            base = model.body_parentid[model.body(f"head_{s}_pan_link").id]
            rot = data.xmat[base].reshape(3, 3)
            cam = data.cam(f"head_{s}_camera")
            want = head_gaze(data.xpos[base] if k == 0 else cam.xpos, rot, target)
            now = (
                (0.0, 0.0) if k == 0 else head_gaze(np.zeros(3), rot, -cam.xmat.reshape(3, 3)[:, 2])
            )
            pan = (0.0 if k == 0 else data.qpos[adr[s][0]]) + want[0] - now[0]
            tilt = (0.0 if k == 0 else data.qpos[adr[s][1]]) + want[1] - now[1]
            data.qpos[adr[s]] = spec.command(np.clip([pan, tilt], spec.lower, spec.upper))
    mujoco.mj_forward(model, data)
    return np.concatenate([data.qpos[adr[s]] for s in HEAD_SIDES])


def _turn(rng: np.random.Generator, axis: np.ndarray, max_deg: float) -> np.ndarray:
    """``axis`` turned by an angle uniform in [0, max_deg] about a random perpendicular axis."""
    perp = np.cross(axis, rng.normal(size=3))
    perp /= np.linalg.norm(perp)
    angle = math.radians(rng.uniform(0.0, max_deg))
    return math.cos(angle) * axis + math.sin(angle) * np.cross(perp, axis)


def _holding_pose(plate: TargetPlate, centre, normal, up) -> tuple[np.ndarray, np.ndarray]:
    """TCP position and rotation that put the board's centre at ``centre`` with its face
    looking along ``normal`` and the texture's top towards ``up`` (all world)."""
    x = np.asarray(normal, float) / np.linalg.norm(normal)  # the face looks along TCP +x
    z = np.asarray(up, float) - np.dot(up, x) * x  # the plate extends along TCP +z
    z /= np.linalg.norm(z)
    rot = np.column_stack([x, np.cross(z, x), z])
    w, h = plate.size_m
    face_centre = (plate.site_from_plate @ np.array([w / 2, h / 2, 0.0, 1.0]))[:3]
    return np.asarray(centre, float) - rot @ face_centre, rot


def _gripper_ik(model: mujoco.MjModel) -> ArmIK:
    return ArmIK(model, GRIPPER_SITE, arm_joint_names(GRIPPER_ARM))


def _hold(ik: ArmIK, q0: np.ndarray, plate: TargetPlate, centre, normal, up):
    pos, rot = _holding_pose(plate, centre, normal, up)
    result = ik.solve(q0, pos, rot)
    return result.q if result.converged else None


def _head_presentation(rng, centre, head_mid, config):
    """A sampled board pose for the head: (point (3,), face normal (3,), texture up (3,)),
    the point in the box ``centre +- head_spread``, the face turned towards ``head_mid``
    within ``head_tilt_deg`` and rolled within ``head_roll_deg``."""
    point = centre + rng.uniform(-1.0, 1.0, 3) * np.asarray(config.head_spread)
    towards = (head_mid - point) / np.linalg.norm(head_mid - point)
    normal = _turn(rng, towards, config.head_tilt_deg)
    roll = math.radians(rng.uniform(-config.head_roll_deg, config.head_roll_deg))
    up = np.array(_HEAD_HOLD_UP) - np.dot(_HEAD_HOLD_UP, normal) * normal
    up /= np.linalg.norm(up)
    up = math.cos(roll) * up + math.sin(roll) * np.cross(normal, up)
    return point, normal, up


def _capture_head(model, data, renderer, plate, board, config, rng, errors):
    ik = _gripper_ik(model)
    centre = np.asarray(config.head_centre, float)
    gaze = _aim_head(model, data, centre)
    head_mid = 0.5 * (data.cam("head_left_camera").xpos + data.cam("head_right_camera").xpos)
    q_gaze = data.qpos.copy()
    w, h = config.head_size
    poses, left, right, attempts = [], [], [], 0
    while len(poses) < config.poses_per_camera:
        if attempts >= config.poses_per_camera * config.max_attempts:
            break
        attempts += 1
        point, normal, up = _head_presentation(rng, centre, head_mid, config)
        q = _hold(ik, q_gaze, plate, point, normal, up)
        if q is None:
            continue
        data.qpos[:] = q
        mujoco.mj_forward(model, data)
        found = [find_corners(_render(renderer, model, data, c, (w, h), errors), board)
                 for c in ("head_left", "head_right")]  # fmt: skip
        if found[0] is None or found[1] is None:
            continue
        poses.append(invert(_base_pose(data)) @ _site_pose(data, GRIPPER_SITE))
        left.append(found[0])
        right.append(found[1])
    data.qpos[:] = q_gaze
    views = HeadViews(gaze, np.array(poses).reshape(-1, 4, 4), np.array(left), np.array(right),
                      (w, h))  # fmt: skip
    return views, attempts


def _wrist_setup(model, data, plate, config, error=None) -> ArmIK:
    """The left arm holds the board face up at ``wrist_board_centre`` (``data`` is set to it);
    returns the wrist camera's IK (joints S to B, free roll). Raises ``error`` (default
    :class:`CalibrationRoutineError`) when the arm cannot reach it."""
    centre = np.asarray(config.wrist_board_centre, float)
    # held from the left arm's side: the texture's top (plate +z from the TCP) towards -y
    q = _hold(_gripper_ik(model), data.qpos.copy(), plate, centre, _UP, (0.0, -1.0, 0.0))
    if q is None:
        raise (error or CalibrationRoutineError)(
            f"the left arm cannot hold the board at wrist_board_centre {config.wrist_board_centre}"
            "; choose a reachable point in front of the robot"
        )
    data.qpos[:] = q
    return ArmIK(model, OPTICAL_SITE, arm_joint_names(CAMERA_ARM)[:5], free_roll=True)


def _wrist_viewpoint(ik: ArmIK, q_hold: np.ndarray, config, rng) -> np.ndarray | None:
    """Joint positions putting the wrist camera at a sampled viewpoint of the held board
    (within ``wrist_tilt_deg`` of its normal, ``wrist_distance_m`` away, looking at it), or
    None when the IK does not converge."""
    centre = np.asarray(config.wrist_board_centre, float)
    near, far = config.wrist_distance_m
    view = _turn(rng, _UP, config.wrist_tilt_deg)
    eye = centre + rng.uniform(near, far) * view
    look = centre + rng.uniform(-0.03, 0.03, 3) * np.array([1.0, 1.0, 0.0])
    result = ik.solve(q_hold, eye, look_at_rotation(eye, look))
    return result.q if result.converged else None


def _wrist_look(ik, q_hold, config, rng, renderer, model, data, size, errors, board):
    """Move the wrist camera to a sampled viewpoint (``data`` set, forward kinematics done)
    and find the board in its image; the corners (N, 2) or None (no IK, or board not found)."""
    q = _wrist_viewpoint(ik, q_hold, config, rng)
    if q is None:
        return None
    data.qpos[:] = q
    mujoco.mj_forward(model, data)
    return find_corners(_render(renderer, model, data, "wrist", size, errors), board)


def _capture_wrist(model, data, renderer, plate, board, config, rng, errors):
    ik = _wrist_setup(model, data, plate, config)
    w, h = config.wrist_size
    flanges, corners, attempts = [], [], 0
    q_hold = data.qpos.copy()
    while len(flanges) < config.poses_per_camera:
        if attempts >= config.poses_per_camera * config.max_attempts:
            break
        attempts += 1
        found = _wrist_look(ik, q_hold, config, rng, renderer, model, data, (w, h), errors, board)
        if found is None:
            continue
        flanges.append(invert(_base_pose(data)) @ _site_pose(data, FLANGE_SITE))
        corners.append(found)
    return WristViews(np.array(flanges).reshape(-1, 4, 4), np.array(corners), (w, h)), attempts


def capture_views(
    config: CalibrationCaptureConfig = CalibrationCaptureConfig(),
) -> CalibrationCapture:
    """Build the cell with the board in the left gripper and capture the configured views."""
    if not isinstance(config, CalibrationCaptureConfig):
        raise CalibrationRoutineError(
            f"config must be a CalibrationCaptureConfig, got {type(config).__name__}"
        )
    start = time.perf_counter()
    board = Checkerboard()
    errors = model_errors(config)
    model, plate = build_calibration_model(board, config.px_per_square, errors)
    rng = np.random.default_rng([config.seed, 14])
    renderer = SensorRenderer(model)
    head = wrist = None
    attempts = {}
    try:
        for group in config.cameras:
            data = mujoco.MjData(model)
            mujoco.mj_forward(model, data)
            run = _capture_head if group == "head" else _capture_wrist
            views, attempts[group] = run(model, data, renderer, plate, board, config, rng, errors)
            n = len(views.gripper_to_base if group == "head" else views.flange_to_base)
            if n < MIN_POSES:
                raise CalibrationRoutineError(
                    f"only {n} of {attempts[group]} sampled {group} poses gave a view of the "
                    f"board (need >= {MIN_POSES}); raise max_attempts or move the presentation "
                    "volume into the cameras' view"
                )
            if group == "head":
                head = views
            else:
                wrist = views
    finally:
        renderer.close()
    return CalibrationCapture(config, board, head, wrist, attempts, time.perf_counter() - start)


def _target_poses(corners: np.ndarray, board: Checkerboard, intr: Intrinsics) -> np.ndarray:
    poses = []
    for view in corners:
        ok, rvec, tvec = cv2.solvePnP(board.object_points(), view, intr.K, intr.dist)
        if not ok:
            raise CalibrationRoutineError("cv2.solvePnP found no board pose for a captured view")
        poses.append(from_rvec_tvec(rvec, tvec))
    return np.stack(poses)


def _best_hand_eye(robot: np.ndarray, targets: np.ndarray, setup: str):
    results = {m: calibrate_hand_eye(robot, targets, method=m, setup=setup)
               for m in HAND_EYE_METHODS}  # fmt: skip

    def score(r: HandEyeResult) -> float:
        return r.translation_rms_mm + _LEVER_MM * math.radians(r.rotation_rms_deg)

    best = min(results.values(), key=score)
    entry = HandEyeEntry(best.method, setup, best.X, best.rotation_rms_deg,
                         best.translation_rms_mm, best.n_poses)  # fmt: skip
    return results, entry


def calibrate_capture(capture: CalibrationCapture) -> CellCalibration:
    """Intrinsics, hand-eye (all methods, the best kept in the file) and stereo from a capture."""
    board = capture.board
    intr: dict[str, Intrinsics] = {}
    all_hand_eye: dict[str, dict[str, HandEyeResult]] = {}
    entries: dict[str, HandEyeEntry] = {}
    stereo = stereo_entry = None
    if capture.head is not None:
        head = capture.head
        targets = {}
        for name, corners in (("head_left", head.left_corners), ("head_right", head.right_corners)):
            intr[name] = calibrate_intrinsics(list(corners), board, head.image_size)
            targets[name] = _target_poses(corners, board, intr[name])
            all_hand_eye[name], entries[name] = _best_hand_eye(
                head.gripper_to_base, targets[name], "eye_to_hand"
            )
        initial = stereo_from_target_poses(targets["head_left"], targets["head_right"])
        stereo = refine_stereo(
            board.object_points(), list(head.left_corners), list(head.right_corners),
            intr["head_left"].K, intr["head_left"].dist, intr["head_right"].K,
            intr["head_right"].dist, initial.left_to_right, targets["head_left"],
        )  # fmt: skip
        stereo_entry = StereoEntry("head_left", "head_right", stereo.left_to_right, stereo.rms_px)
    if capture.wrist is not None:
        wrist = capture.wrist
        intr["wrist"] = calibrate_intrinsics(list(wrist.corners), board, wrist.image_size)
        targets = _target_poses(wrist.corners, board, intr["wrist"])
        all_hand_eye["wrist"], entries["wrist"] = _best_hand_eye(
            wrist.flange_to_base, targets, "eye_in_hand"
        )
    cameras = tuple(CameraCalibration(n, i.K, i.dist, i.image_size, i.rms_px)
                    for n, i in intr.items())  # fmt: skip
    gaze = None if capture.head is None else capture.head.gaze  # where the head's X holds
    cell = {"robot_seed": capture.config.robot_seed}  # the simulated cell measured
    file = CalibrationFile(
        cameras, entries, stereo_entry, capture.config.seed, head_gaze=gaze, cell=cell
    )
    return CellCalibration(file, intr, all_hand_eye, stereo, capture)


def calibrate_cell(
    config: CalibrationCaptureConfig = CalibrationCaptureConfig(),
) -> CalibrationFile:
    """Run the whole routine in the simulated cell; returns the calibration file (unsaved)."""
    return calibrate_capture(capture_views(config)).file


def calibration_truth(capture: CalibrationCapture) -> CalibrationTruth:
    """The simulator's true intrinsics, hand-eye transforms and stereo transform for the
    cameras of ``capture`` (evaluation only: the routine never reads these)."""
    errors = model_errors(capture.config)
    model, _ = build_calibration_model(capture.board, capture.config.px_per_square, errors)
    data = mujoco.MjData(model)
    K, X, stereo = {}, {}, None
    if capture.head is not None:
        adr = [model.jnt_qposadr[model.joint(f"head_{s}_{j}").id]
               for s in HEAD_SIDES for j in ("pan", "tilt")]  # fmt: skip
        data.qpos[adr] = capture.head.gaze
        mujoco.mj_forward(model, data)
        base = _base_pose(data)
        poses = {}
        for name in ("head_left", "head_right"):
            K[name] = intrinsics(model, CAMERAS[name], *capture.head.image_size).K
            poses[name] = camera_pose(model, data, CAMERAS[name])
            X[name] = invert(base) @ poses[name]
        stereo = invert(poses["head_right"]) @ poses["head_left"]
    if capture.wrist is not None:
        mujoco.mj_forward(model, data)
        K["wrist"] = intrinsics(model, CAMERAS["wrist"], *capture.wrist.image_size).K
        X["wrist"] = invert(_site_pose(data, FLANGE_SITE)) @ camera_pose(
            model, data, CAMERAS["wrist"]
        )
    return CalibrationTruth(K, X, stereo)
