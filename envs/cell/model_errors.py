"""The true work cell differs from the nominal one by documented, seeded errors.

The *nominal* model is what the robot's software believes: the work cell of
:func:`ipbench.assets.compose.build_workcell_spec`, exactly as the released envs simulate it.
The *true* model, which the simulator would run and render, is that spec changed by
:func:`apply_model_errors` before compiling. Nothing else calls it: released envs are unchanged.
Errors and their frames (``E`` = :attr:`MountError.matrix`, from a translation and a rotation
vector):

* camera mounts (:data:`CAMERA_MOUNTS`): ``E`` is in the camera's nominal optical frame (OpenCV
  axes, as :func:`ipbench.envs.sensors.camera_pose`): at the same joint positions
  ``camera_pose(true) = camera_pose(nominal) @ E``, so ``E`` is the hand-eye error itself. The
  wrist error moves the whole Xtion body (geoms, camera, ``optical`` site), as a sensor screwed
  on a few mm off; a head camera error moves the camera on its PTU plate (the Nikon's geoms are
  visual only).
* PTU bases (:data:`PTU_BASE_MOUNTS`): ``E`` is in the base frame, the ``head_*_mount`` site of
  ``motoman.xml`` where ``compose.py`` attaches the unit: ``base_pose(true) = base_pose(nominal)
  @ E`` and the unit follows.
* PTU encoder zero offsets: the encoder reads ``true angle - offset``. The pan (tilt) link's body
  frame is turned by the offset about its joint's axis through the joint's anchor, so the true
  model at ``qpos = e`` is the nominal one at ``e + offset``. Chosen over the joint's ``ref``:
  it keeps ``qpos0``, keyframes, limits and position actuators in encoder units, as the PTU-D46
  keeps its limits and commands in positions (User's Manual v2.14.0 §4.3.4), so ``qpos`` stays
  what the encoder reads (before the 0.0514 deg quantisation of :mod:`ipbench.envs.ptu`).
* Data for the envs, applied by them (not by the spec): PTU backlash (dead band on a reversal,
  rad per axis), each camera's true lens (:class:`LensDistortion`; the nominal model is a
  pinhole) and the wrist's depth-to-RGB registration offset ``(du, dv)`` px at 640 x 480 (the
  reported depth at RGB pixel ``(u, v)`` is the ideal registered depth at ``(u - du, v - dv)``).

:data:`ERROR_SCALES` gives every size with its source; :func:`sample_model_errors` draws a set.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from typing import Literal

import mujoco
import numpy as np

from ipbench.assets.compose import CAMERA_ARM, HEAD_SIDES
from ipbench.envs.ptu import AXES, STEP_RAD
from ipbench.envs.sensors.lens_distortion import D5100_35MM, XTION_RGB, LensDistortion

__all__ = [
    "CAMERA_MOUNTS",
    "ERROR_SCALES",
    "MARKER_TEXT",
    "MOUNTS",
    "PTU_BASE_MOUNTS",
    "ErrorScale",
    "ModelErrors",
    "ModelErrorsError",
    "MountError",
    "PtuErrors",
    "apply_model_errors",
    "sample_model_errors",
]

CAMERA_MOUNTS: tuple[str, ...] = ("wrist_camera", "head_left_camera", "head_right_camera")
"""Mounts whose error is in the camera's optical frame (OpenCV axes)."""
PTU_BASE_MOUNTS: tuple[str, ...] = tuple(f"head_{side}_base" for side in HEAD_SIDES)
"""Mounts whose error is in the PTU base frame (the ``head_*_mount`` site)."""
MOUNTS: tuple[str, ...] = CAMERA_MOUNTS + PTU_BASE_MOUNTS
"""Every mount of :class:`ModelErrors`, in the order :func:`sample_model_errors` draws them."""
MARKER_TEXT = "ipbench_model_errors"
"""Text element :func:`apply_model_errors` adds to the spec (the errors applied, as JSON)."""
_WRIST_BODY = f"{CAMERA_ARM}_wrist_body"  # xtion.xml's "body" as compose.py attaches it
_CAMERAS = {"wrist_camera": f"{CAMERA_ARM}_wrist_camera"} | {
    f"head_{s}_camera": f"head_{s}_camera" for s in HEAD_SIDES
}  # camera mount -> the model's camera name
_STREAM = 1400  # sample_model_errors draws from default_rng([seed, 1400])
_CV_FROM_MJ = np.diag([1.0, -1.0, -1.0, 1.0])  # MuJoCo camera frame <-> OpenCV (self-inverse)


class ModelErrorsError(ValueError):
    """Bad model errors, or a spec they cannot be applied to."""


def _vector(value, n: int, name: str) -> tuple[float, ...]:
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        v = np.full(0, np.nan)
    if v.shape != (n,) or not np.isfinite(v).all():
        raise ModelErrorsError(f"{name} must be {n} finite numbers, got {value!r}")
    return tuple(float(x) for x in v)


def _transform(pos, quat) -> np.ndarray:
    """(4, 4) rigid transform of a translation and a quaternion (w, x, y, z)."""
    mat, quat = np.zeros(9), np.asarray(quat, float)
    mujoco.mju_quat2Mat(mat, quat / np.linalg.norm(quat))
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = mat.reshape(3, 3), pos
    return out


def _pose(pos, rotvec) -> np.ndarray:
    """(4, 4) rigid transform of a translation and a rotation vector (rad)."""
    rotvec, quat = np.asarray(rotvec, float), np.array([1.0, 0.0, 0.0, 0.0])
    if (angle := float(np.linalg.norm(rotvec))) > 0.0:
        mujoco.mju_axisAngle2Quat(quat, rotvec / angle, angle)
    return _transform(pos, quat)


@dataclass(frozen=True)
class MountError:
    """A part's true mount relative to its nominal mount, in the mount's frame.

    Attributes
    ----------
    translation : (3,) m, the true frame's origin in the nominal frame.
    rotation : (3,) rad, rotation vector (axis times angle) of the true frame in the nominal.
    """

    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "translation", _vector(self.translation, 3, "translation (m)"))
        object.__setattr__(self, "rotation", _vector(self.rotation, 3, "rotation vector (rad)"))

    @property
    def matrix(self) -> np.ndarray:
        """(4, 4) ``E``, the true frame in the nominal one: ``true pose = nominal pose @ E``."""
        return _pose(self.translation, self.rotation)

    @property
    def is_zero(self) -> bool:
        """Whether the true mount is the nominal one."""
        return not any(self.translation + self.rotation)


@dataclass(frozen=True)
class PtuErrors:
    """One PTU-D46's joint errors per axis ``(pan, tilt)``.

    Attributes
    ----------
    zero_offset : (2,) rad; the encoder reads ``true angle - zero_offset``.
    backlash : (2,) rad >= 0; dead band on a direction reversal (applied by the env).
    """

    zero_offset: tuple[float, float] = (0.0, 0.0)
    backlash: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "zero_offset", _vector(self.zero_offset, 2, "zero_offset (rad)"))
        backlash = _vector(self.backlash, 2, "backlash (rad)")
        if min(backlash) < 0:
            raise ModelErrorsError(f"backlash is a dead band, >= 0 rad per axis, got {backlash}")
        object.__setattr__(self, "backlash", backlash)


_FIELD_KINDS = {"MountError": MountError, "PtuErrors": PtuErrors, "LensDistortion": LensDistortion}


@dataclass(frozen=True)
class ModelErrors:
    """Every way the true work cell differs from the nominal one (all zero by default).

    Attributes
    ----------
    wrist_camera, head_left_camera, head_right_camera : :class:`MountError`, optical frame.
    head_left_base, head_right_base : :class:`MountError` of each PTU's base, base frame.
    head_left_ptu, head_right_ptu : :class:`PtuErrors` (encoder zero offsets, backlash).
    wrist_distortion, head_left_distortion, head_right_distortion : each camera's true lens.
    depth_registration_px : (2,) ``(du, dv)`` px at 640 x 480, the wrist depth image's shift
        relative to its RGB image.
    """

    wrist_camera: MountError = MountError()
    head_left_camera: MountError = MountError()
    head_right_camera: MountError = MountError()
    head_left_base: MountError = MountError()
    head_right_base: MountError = MountError()
    head_left_ptu: PtuErrors = PtuErrors()
    head_right_ptu: PtuErrors = PtuErrors()
    wrist_distortion: LensDistortion = LensDistortion()
    head_left_distortion: LensDistortion = LensDistortion()
    head_right_distortion: LensDistortion = LensDistortion()
    depth_registration_px: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self)[:-1]:  # all but depth_registration_px
            value, kind = getattr(self, field.name), _FIELD_KINDS[field.type]
            if not isinstance(value, kind):
                raise ModelErrorsError(f"{field.name} must be a {field.type}, got {value!r}")
        px = _vector(self.depth_registration_px, 2, "depth_registration_px (du, dv)")
        object.__setattr__(self, "depth_registration_px", px)

    @property
    def registration_shift_px(self) -> tuple[int, int]:
        """:attr:`depth_registration_px` in whole pixels ``(dx, dy)``: how the true Xtion's
        depth image moves against its RGB image (the envs' and the reconstruction's shift)."""
        du, dv = self.depth_registration_px
        return round(du), round(dv)

    @classmethod
    def none(cls) -> ModelErrors:
        """No errors: the true model is the nominal one."""
        return cls()

    @property
    def mounts(self) -> dict[str, MountError]:
        """Every :class:`MountError` by mount name (:data:`MOUNTS`)."""
        return {name: getattr(self, name) for name in MOUNTS}

    def ptu(self, side: str) -> PtuErrors:
        """The :class:`PtuErrors` of the ``"left"`` or ``"right"`` unit."""
        if side not in HEAD_SIDES:
            raise ModelErrorsError(f"unknown PTU side {side!r}; valid: {list(HEAD_SIDES)}")
        return getattr(self, f"head_{side}_ptu")

    @property
    def distortion(self) -> dict[str, LensDistortion]:
        """Each camera's true lens by the model's camera name (``right_wrist_camera``, ...)."""
        return {
            cam: getattr(self, m[: -len("camera")] + "distortion") for m, cam in _CAMERAS.items()
        }

    def as_dict(self) -> dict:
        """JSON-able form (lists of floats; rad, m and px)."""

        def lists(item) -> dict[str, list[float]]:
            return {k: list(v) for k, v in dataclasses.asdict(item).items()}

        return {
            "mounts": {n: lists(m) for n, m in self.mounts.items()},
            "ptu": {s: lists(self.ptu(s)) for s in HEAD_SIDES},
            "distortion": {c: d.coefficients.tolist() for c, d in self.distortion.items()},
            "depth_registration_px": list(self.depth_registration_px),
        }


@dataclass(frozen=True)
class ErrorScale:
    """The size of one kind of error and where it comes from.

    Attributes
    ----------
    value : ``kind="sigma"``: standard deviation of each component (normal, zero mean);
        ``kind="max"``: upper end of each component's uniform range ``[0, value]``.
    unit : unit of ``value``: ``"m"``, ``"rad"`` or ``"px"``.
    kind : ``"sigma"`` or ``"max"``.
    source : where the number comes from, or that none was found and what was chosen.
    """

    value: float
    unit: str
    kind: Literal["sigma", "max"]
    source: str


# Glasgow head (CloPeMa description, gerac83/ug_bluerobot): right PTU relative to the left, nominal
# (0, -0.30, 0) m, rpy 0 (clopema_UG.urdf.xacro) vs calibrated (0.041, -0.285, 0.004) m, rpy (-2.7,
# 0.3, -1.7) deg (calibration_UG). Per-axis RMS 25.3 mm, 1.85 deg of a relative pose, i.e. of the
# difference of two independent base errors: each base gets RMS / sqrt(2) = 17.9 mm, 1.31 deg.
_GLASGOW_RIGHT_PTU_M = np.array([0.041, -0.285, 0.004]) - np.array([0.0, -0.30, 0.0])
_GLASGOW_RIGHT_PTU_DEG = np.array([-2.7, 0.3, -1.7])
_per_base = float(np.sqrt(np.mean(_GLASGOW_RIGHT_PTU_M**2) / 2.0))
_per_base_deg = float(np.sqrt(np.mean(_GLASGOW_RIGHT_PTU_DEG**2) / 2.0))
_GLASGOW = "CloPeMa ug_bluerobot, Glasgow right PTU nominal vs calibrated; per-axis RMS / sqrt(2)"

ERROR_SCALES: dict[str, ErrorScale] = {
    # No published spread of a camera's mounting: chosen "a few mm and tenths of a degree";
    # per-axis sigma 2 mm / 0.2 deg give mean magnitudes 1.596 sigma = 3.2 mm and 0.32 deg.
    "camera_mount_translation": ErrorScale(0.002, "m", "sigma", "none found; chosen 'a few mm'"),
    "camera_mount_rotation": ErrorScale(
        math.radians(0.2), "rad", "sigma", "none found; chosen 'tenths of a degree'"
    ),
    "ptu_base_translation": ErrorScale(_per_base, "m", "sigma", _GLASGOW),
    "ptu_base_rotation": ErrorScale(math.radians(_per_base_deg), "rad", "sigma", _GLASGOW),
    # The PTU-D46 finds its axis bounds at every reset (manual §4.3.4); no published
    # repeatability of that zero, nor a backlash figure (FLIR's FAQ: worm gears with "very low
    # native backlash" that grows with wear). Both chosen: 2 positions of 0.0514 deg.
    "ptu_zero_offset": ErrorScale(
        2.0 * STEP_RAD, "rad", "sigma", "none found; chosen 2 PTU-D46 positions (manual §4.3.3)"
    ),
    "ptu_backlash": ErrorScale(
        2.0 * STEP_RAD, "rad", "max", "none found; chosen uniform in [0, 2 PTU-D46 positions]"
    ),
    # PrimeSense depth sits (5, 4) px off its IR image (9x7 correlation window; ros-drivers
    # openni_camera/freenect_camera depth_ir_offset_x/y), which drivers correct; factory
    # registration is then "off by just a few pixels" (OpenKinect/libfreenect2 issue #854). No
    # unit statistics found: chosen sigma 2 px per axis (mean 2.5 px), below the (5, 4) px shift.
    "depth_registration": ErrorScale(
        2.0, "px", "sigma", "libfreenect2 #854 'a few pixels', < openni (5, 4) px; chosen 2 px"
    ),
}
"""The size of every sampled error, with its source (see :class:`ErrorScale`)."""


def sample_model_errors(seed: int) -> ModelErrors:
    """Every error drawn at the sizes of :data:`ERROR_SCALES`, deterministically from ``seed``.

    Own stream ``numpy.random.default_rng([seed, 1400])``. Order: per mount of :data:`MOUNTS`
    translation then rotation (3 normals each); per PTU (left, right) zero offsets then backlash;
    the depth registration offset. True lenses are the presets (``D5100_35MM`` on the head,
    ``XTION_RGB`` on the wrist, :mod:`ipbench.envs.sensors.lens_distortion`), not drawn: no
    unit-to-unit spread was found.
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ModelErrorsError(f"seed must be a non-negative int, got {seed!r}")
    rng = np.random.default_rng([int(seed), _STREAM])
    s = {key: scale.value for key, scale in ERROR_SCALES.items()}
    fields = {}
    for name in MOUNTS:
        kind = "camera_mount" if name in CAMERA_MOUNTS else "ptu_base"
        t = rng.normal(0.0, s[f"{kind}_translation"], 3)
        fields[name] = MountError(t, rng.normal(0.0, s[f"{kind}_rotation"], 3))
    for side in HEAD_SIDES:
        offset = rng.normal(0.0, s["ptu_zero_offset"], 2)
        fields[f"head_{side}_ptu"] = PtuErrors(offset, rng.uniform(0.0, s["ptu_backlash"], 2))
    return ModelErrors(
        **fields,
        wrist_distortion=XTION_RGB,
        head_left_distortion=D5100_35MM,
        head_right_distortion=D5100_35MM,
        depth_registration_px=rng.normal(0.0, s["depth_registration"], 2),
    )


def _local_pose(element) -> np.ndarray:
    """(4, 4) pose of a body or camera in its frame (its parent body's if it has none)."""
    quat, c = element.quat, element.compiler
    if element.alt.type != mujoco.mjtOrientation.mjORIENTATION_QUAT:
        quat = mujoco.MjSpec.resolve_orientation(c.degree, c.eulerseq, element.alt)
    return _transform(element.pos, quat)


def apply_model_errors(spec: mujoco.MjSpec, errors: ModelErrors) -> None:
    """Turn the composed work cell's ``spec`` into the TRUE model (edits it; compile after).

    Moves each mount by its :class:`MountError` and turns each PTU link by its zero offset (see
    the module docstring for the frames); a zero error leaves its element untouched, so
    :meth:`ModelErrors.none` gives the nominal model exactly. Adds the text element
    :data:`MARKER_TEXT` with the errors as JSON and refuses a spec that has it (errors applied
    twice would compound). Everything is checked before the spec is changed.
    """
    if not isinstance(spec, mujoco.MjSpec):
        raise ModelErrorsError(f"spec must be a mujoco.MjSpec, got {type(spec).__name__}")
    if not isinstance(errors, ModelErrors):
        raise ModelErrorsError(f"errors must be a ModelErrors, got {type(errors).__name__}")
    fresh = "build a fresh one with ipbench.assets.compose.build_workcell_spec()"
    if spec.text(MARKER_TEXT) is not None:
        raise ModelErrorsError(f"model errors were already applied to this spec; {fresh}")
    wanted = [("camera", c) for c in _CAMERAS.values()] + [("body", _WRIST_BODY)]
    wanted += [("body", m) for m in PTU_BASE_MOUNTS]
    wanted += [("joint", f"head_{s}_{a}") for s in HEAD_SIDES for a in AXES]
    found = {name: getattr(spec, kind)(name) for kind, name in wanted}
    missing = [f"{kind} {name!r}" for kind, name in wanted if found[name] is None]
    if missing:
        raise ModelErrorsError(
            f"spec is not the composed work cell: no {', '.join(missing)}; "
            f"{fresh} (or build_robot_spec())"
        )
    wrist = found[_CAMERAS["wrist_camera"]]
    if wrist.parent.name != _WRIST_BODY or wrist.frame is not None:
        raise ModelErrorsError(f"the wrist camera must sit directly on {_WRIST_BODY!r}; {fresh}")

    edits = []  # (element, its new local pose), all computed before any change
    for mount, cam_name in _CAMERAS.items():
        error = errors.mounts[mount]
        if error.is_zero:
            continue
        cam_cv = _local_pose(found[cam_name]) @ _CV_FROM_MJ
        if mount == "wrist_camera":  # the Xtion body moves so that its camera moves by E
            body = found[_WRIST_BODY]
            edits.append((body, _local_pose(body) @ cam_cv @ error.matrix @ np.linalg.inv(cam_cv)))
        else:
            edits.append((found[cam_name], cam_cv @ error.matrix @ _CV_FROM_MJ))
    for mount in PTU_BASE_MOUNTS:
        if not errors.mounts[mount].is_zero:
            edits.append((found[mount], _local_pose(found[mount]) @ errors.mounts[mount].matrix))
    for side in HEAD_SIDES:
        for axis, offset in zip(AXES, errors.ptu(side).zero_offset, strict=True):
            if offset == 0.0:
                continue
            joint = found[f"head_{side}_{axis}"]
            turn = _pose(np.zeros(3), np.asarray(joint.axis) / np.linalg.norm(joint.axis) * offset)
            turn[:3, 3] = joint.pos - turn[:3, :3] @ joint.pos  # about the joint's anchor
            edits.append((joint.parent, _local_pose(joint.parent) @ turn))

    for element, pose in edits:
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, pose[:3, :3].ravel())
        element.pos, element.quat = pose[:3, 3], quat
        element.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT
    spec.add_text(name=MARKER_TEXT, data=json.dumps(errors.as_dict()))
