"""What the robot knows of its cameras: the envs' ``extrinsics`` option (thesis ch. 4).

``extrinsics`` (:data:`EXTRINSICS`) chooses where an observation's camera matrices ``*_K``,
poses ``*_pose`` and (not ``"true"``) distortion ``*_dist`` come from:

* ``"true"`` (default, the released ids): the simulator's exact values; the world is the nominal
  model and the images are pinhole renders. The envs take the same code path as without the
  option and never build a :class:`CameraKnowledge`.
* ``"nominal"``: the world is the TRUE one (the nominal model with
  :func:`~ipbench.envs.cell.model_errors.sample_model_errors` of ``robot_seed`` applied, images
  distorted by its lenses, the PTUs' backlash acting on every head move (Exploration: the output
  trails the motor, :func:`~ipbench.envs.ptu.play`; the encoders count the motor) and the wrist
  depth image shifted by the Xtion's depth-to-RGB registration error (Sorting: in place of the
  sensor preset's per-episode unit shift)), and the robot believes its nominal model: ``K`` from
  the nominal model (:func:`~ipbench.envs.sensors.intrinsics`), ``dist`` zeros (a pinhole), the
  pose by forward kinematics of the NOMINAL model at the joint encoder readings.
* ``"calibrated"``: the same true world; ``K`` and ``dist`` from a calibration file
  (:class:`~ipbench.envs.cell.calibration_file.CalibrationFile`, written by
  ``ipbench calibrate``), ``K`` scaled to the observed image size; the wrist pose is the nominal
  FK of the flange ``right_flange`` times the file's eye-in-hand ``X`` (camera-to-flange); a head
  camera's pose is the file's eye-to-hand ``X`` (camera-to-``base`` at the file's ``head_gaze``
  ``g0``) carried to the current gaze ``g`` by the nominal PTU kinematics, the "encoders-only"
  update of thesis §4.4.4: ``T_base_cam(g) = T_base_tilt(g) @ inv(T_base_tilt(g0)) @ X``
  (``tilt``: the head's tilt link).

Every belief is ``pose = T_world_frame(q) @ anchor`` with a constant ``anchor`` per camera (the
camera's own frame for ``nominal``, the flange or tilt link for ``calibrated``), evaluated on a
nominal model compiled once per :class:`CameraKnowledge` (robot only: arms, turntable, head).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import mujoco
import numpy as np

from ipbench.assets.compose import CAMERA_ARM, HEAD_SIDES, build_workcell_spec
from ipbench.envs.cell.calibration_file import CalibrationFile, CalibrationFileError
from ipbench.envs.ptu import AXES
from ipbench.envs.sensors import camera_pose, intrinsics
from ipbench.envs.sensors.lens_distortion import LensDistortion, distort_image

__all__ = [
    "CAMERA_MODEL_NAMES",
    "DIST_SIZE",
    "EXTRINSICS",
    "CameraBelief",
    "CameraKnowledge",
    "ExtrinsicsError",
    "check_extrinsics",
    "distort_labels",
]

EXTRINSICS: tuple[str, ...] = ("true", "nominal", "calibrated")
"""Valid values of the envs' ``extrinsics`` option (module docstring)."""
CAMERA_MODEL_NAMES: dict[str, str] = {
    "wrist": f"{CAMERA_ARM}_wrist_camera",
    **{f"head_{s}": f"head_{s}_camera" for s in HEAD_SIDES},
}
"""Observation camera name -> the model's camera name."""
DIST_SIZE = 5
"""Length of an observation's ``*_dist``: OpenCV ``(k1, k2, p1, p2, k3)``."""
BASE_BODY = "base"  # the robot base: frame of the head's eye-to-hand X (eval/calibrate.py)
FLANGE_SITE = f"{CAMERA_ARM}_flange"  # frame of the wrist's eye-in-hand X
_ONE_DOF = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))


class ExtrinsicsError(ValueError):
    """A bad ``extrinsics`` option, robot seed or calibration file for it."""


def check_extrinsics(mode, calibration=None, robot_seed=0) -> str:
    """``mode`` checked against :data:`EXTRINSICS` with its ``calibration`` and ``robot_seed``.

    ``calibrated`` needs a ``calibration`` file path; the others take none. ``robot_seed`` is
    the true cell's error seed (an int >= 0). Returns ``mode``.
    """
    valid = ", ".join(map(repr, EXTRINSICS))
    if not isinstance(mode, str) or mode not in EXTRINSICS:
        raise ExtrinsicsError(f"unknown extrinsics {mode!r}; valid: {valid}")
    if isinstance(robot_seed, bool) or not isinstance(robot_seed, (int, np.integer)):
        raise ExtrinsicsError(f"robot_seed must be an int >= 0, got {robot_seed!r}")
    if robot_seed < 0:
        raise ExtrinsicsError(f"robot_seed must be an int >= 0, got {robot_seed!r}")
    if mode == "calibrated" and calibration is None:
        raise ExtrinsicsError(
            "extrinsics='calibrated' needs calibration=FILE, a file written by `ipbench "
            "calibrate --robot-seed R --out FILE` (R: the env's robot_seed)"
        )
    if calibration is not None and not isinstance(calibration, (str, os.PathLike)):
        raise ExtrinsicsError(f"calibration must be a file path or None, got {calibration!r}")
    if mode != "calibrated" and calibration is not None:
        raise ExtrinsicsError(
            f"calibration={calibration!r} is only read with extrinsics='calibrated', not "
            f"{mode!r}; drop it or set extrinsics='calibrated'"
        )
    return mode


@dataclass(frozen=True, eq=False)
class CameraBelief:
    """One camera as the robot believes it.

    Attributes
    ----------
    K : (3, 3) float64 camera matrix at the observed image size, px.
    dist : (5,) float64 OpenCV distortion ``(k1, k2, p1, p2, k3)``.
    pose : (4, 4) float64 world-from-camera, OpenCV axes, m.
    """

    K: np.ndarray
    dist: np.ndarray
    pose: np.ndarray


def _scaled_K(  # noqa: N802
    model: mujoco.MjModel,
    camera: str,
    K: np.ndarray,
    size_from,
    size_to,  # noqa: N803
) -> np.ndarray:
    """``K`` of a ``size_from`` (width, height) image rescaled to a ``size_to`` image as the
    camera maps its image sizes: each of fx, fy and (cx, cy) + 0.5 (pixel centres at integers)
    scales as the nominal model's (MuJoCo's ``fovy`` camera keeps its vertical field of view
    and square pixels, so a change of aspect ratio does not scale fx by the width)."""
    a = intrinsics(model, camera, *size_from)
    b = intrinsics(model, camera, *size_to)
    sx, sy = b.fx / a.fx, b.fy / a.fy
    out = np.array(K, dtype=np.float64)
    out[0, :2] *= sx
    out[1, 1] *= sy
    out[0, 2] = (K[0, 2] + 0.5) * (b.cx + 0.5) / (a.cx + 0.5) - 0.5
    out[1, 2] = (K[1, 2] + 0.5) * (b.cy + 0.5) / (a.cy + 0.5) - 0.5
    return out


def _dist5(dist: np.ndarray, name: str, path) -> np.ndarray:
    dist = np.asarray(dist, dtype=np.float64)
    if len(dist) > DIST_SIZE and np.any(dist[DIST_SIZE:]):
        raise ExtrinsicsError(
            f"{path}: camera {name!r} has a {len(dist)}-coefficient lens model; the observation's "
            f"*_dist holds {DIST_SIZE} (k1, k2, p1, p2, k3): calibrate with OpenCV's default model"
        )
    return np.concatenate([dist, np.zeros(DIST_SIZE)])[:DIST_SIZE]


def _frame_pose(model: mujoco.MjModel, data: mujoco.MjData, kind: str, index: int) -> np.ndarray:
    pose = np.eye(4)
    if kind == "camera":
        return camera_pose(model, data, index)
    if kind == "site":
        pose[:3, :3], pose[:3, 3] = data.site_xmat[index].reshape(3, 3), data.site_xpos[index]
    else:
        pose[:3, :3], pose[:3, 3] = data.xmat[index].reshape(3, 3), data.xpos[index]
    return pose


@dataclass(frozen=True, eq=False)
class CameraKnowledge:
    """What the robot knows of its cameras, for ``nominal`` or ``calibrated`` (built once per
    env by :meth:`build`; ``observe`` gives the beliefs at given encoder readings).

    Attributes
    ----------
    mode : ``"nominal"`` or ``"calibrated"``.
    cameras : observation camera names (keys of :data:`CAMERA_MODEL_NAMES`).
    model : the nominal robot model (compiled without errors) for forward kinematics.
    joint_names : names of ``model``'s joints, in the order ``observe`` takes their readings.
    calibration : the calibration file (``calibrated``) or None.
    """

    mode: str
    cameras: tuple[str, ...]
    model: mujoco.MjModel
    joint_names: tuple[str, ...]
    calibration: CalibrationFile | None = None
    _anchors: dict = field(default_factory=dict, repr=False)  # camera -> (kind, id, (4, 4))
    _data: mujoco.MjData | None = field(default=None, repr=False)  # scratch FK data

    @classmethod
    def build(
        cls,
        mode: str,
        cameras: Sequence[str],
        calibration: str | os.PathLike | None = None,
        robot_seed: int | None = None,
    ) -> CameraKnowledge:
        """Knowledge of ``cameras`` for ``mode`` (``calibration``: the file, ``calibrated``)
        in the true cell of ``robot_seed`` (a file that records another cell is refused)."""
        check_extrinsics(mode, calibration)
        if mode == "true":
            raise ExtrinsicsError(
                "extrinsics='true' reads the simulator's values and needs no CameraKnowledge; "
                "valid modes here: 'nominal', 'calibrated'"
            )
        cameras = tuple(cameras)
        unknown = [c for c in cameras if c not in CAMERA_MODEL_NAMES]
        if not cameras or unknown:
            raise ExtrinsicsError(
                f"cameras {cameras!r}: unknown {unknown}; valid: {list(CAMERA_MODEL_NAMES)}"
            )
        model = build_workcell_spec().compile()
        data = mujoco.MjData(model)
        names = tuple(
            model.joint(j).name for j in range(model.njnt)
            if int(model.jnt_type[j]) in _ONE_DOF
        )  # fmt: skip
        anchors = {}
        file = None
        if mode == "nominal":
            for c in cameras:
                anchors[c] = ("camera", model.camera(CAMERA_MODEL_NAMES[c]).id, np.eye(4))
        else:
            file = _load(calibration, cameras)
            measured = None if file.cell is None else file.cell["robot_seed"]
            if file.cell is not None and robot_seed is not None and measured != robot_seed:
                where = "the nominal cell" if measured is None else f"robot_seed={measured}"
                raise ExtrinsicsError(
                    f"{calibration} was measured in {where}, but this env's true cell is "
                    f"robot_seed={robot_seed}: calibrate that cell with `ipbench calibrate "
                    f"--robot-seed {robot_seed} --out FILE`, or set robot_seed to the file's"
                )
            for c in cameras:
                X = file.hand_eye[c].X  # noqa: N806
                if c == "wrist":
                    anchors[c] = ("site", model.site(FLANGE_SITE).id, np.array(X))
                    continue
                # the calibration's gaze g0 (other joints at the model's qpos0, as captured)
                tilt = int(model.jnt_bodyid[model.joint(f"{c}_tilt").id])
                mujoco.mj_resetData(model, data)
                for k, joint in enumerate(f"head_{s}_{a}" for s in HEAD_SIDES for a in AXES):
                    data.qpos[model.jnt_qposadr[model.joint(joint).id]] = file.head_gaze[k]
                mujoco.mj_kinematics(model, data)
                base = _frame_pose(model, data, "body", model.body(BASE_BODY).id)
                tilt0 = _frame_pose(model, data, "body", tilt)
                anchors[c] = ("body", tilt, np.linalg.inv(tilt0) @ base @ X)
        return cls(mode, cameras, model, names, file, anchors, data)

    def observe(
        self, readings: np.ndarray, sizes: Mapping[str, tuple[int, int]]
    ) -> dict[str, CameraBelief]:
        """Each camera's belief at joint ``readings`` ((len(joint_names),) rad or m, in
        ``joint_names`` order: the encoders) for images of ``sizes[camera]`` = (width, height)."""
        readings = np.asarray(readings, dtype=np.float64)
        if readings.shape != (len(self.joint_names),) or not np.isfinite(readings).all():
            raise ExtrinsicsError(
                f"readings must be {len(self.joint_names)} finite joint values in joint_names "
                f"order, got shape {readings.shape}"
            )
        m, d = self.model, self._data
        mujoco.mj_resetData(m, d)
        d.qpos[m.jnt_qposadr[[m.joint(j).id for j in self.joint_names]]] = readings
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_camlight(m, d)
        out = {}
        for c in self.cameras:
            w, h = sizes[c]
            kind, index, anchor = self._anchors[c]
            pose = _frame_pose(m, d, kind, index) @ anchor
            if self.mode == "nominal":
                K, dist = intrinsics(m, CAMERA_MODEL_NAMES[c], w, h).K, np.zeros(DIST_SIZE)  # noqa: N806
            else:
                cal = self.calibration.camera(c)
                K = _scaled_K(m, CAMERA_MODEL_NAMES[c], cal.K, cal.image_size, (w, h))  # noqa: N806
                dist = _dist5(cal.dist, c, "calibration")
            out[c] = CameraBelief(K, dist, pose)
        return out


def _load(path, cameras: tuple[str, ...]) -> CalibrationFile:
    """The calibration file at ``path``, checked to hold what ``cameras`` need."""
    try:
        file = CalibrationFile.load(Path(path))
    except CalibrationFileError as error:
        raise ExtrinsicsError(f"extrinsics='calibrated': {error}") from None
    redo = f"regenerate it with `ipbench calibrate --cameras head,wrist --out {path}`"
    missing = [c for c in cameras if c not in file.camera_names or c not in file.hand_eye]
    if missing:
        raise ExtrinsicsError(
            f"{path} has no intrinsics and hand-eye for camera(s) {missing} that the env "
            f"observes (it calibrates {list(file.camera_names)}, hand-eye for "
            f"{list(file.hand_eye)}); {redo}"
        )
    for c in cameras:
        want = "eye_in_hand" if c == "wrist" else "eye_to_hand"
        if file.hand_eye[c].setup != want:
            raise ExtrinsicsError(
                f"{path}: hand_eye.{c} is {file.hand_eye[c].setup!r}; valid: {want!r}; {redo}"
            )
        _dist5(file.camera(c).dist, c, path)
    if any(c.startswith("head_") for c in cameras) and file.head_gaze is None:
        raise ExtrinsicsError(
            f"{path} has no head_gaze (the PTU readings of its head calibration, which older "
            f"calibration files lack), so the head's pose cannot follow the PTUs; {redo}"
        )
    return file


def distort_labels(labels: np.ndarray, K: np.ndarray, lens: LensDistortion) -> np.ndarray:  # noqa: N803
    """A per-pixel label image (ints, ``-1`` = none) as the lens ``lens`` sees it: nearest
    neighbour, pixels without a source get ``-1``; same shape and dtype."""
    labels = np.asarray(labels)
    shifted = labels.astype(np.float64) + 1.0  # exact for any int label; 0 = none
    out = distort_image(shifted, K, lens, interpolation=cv2.INTER_NEAREST)
    return (np.rint(out) - 1.0).astype(labels.dtype)
