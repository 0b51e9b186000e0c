"""``ipbench/Exploration-v0``: explore a table scene with the stereo head.

Thesis ch. 3: the robot's two PTU-mounted cameras saccade over a table and report the
database objects they recognise. The public contract:

* Action: ``{"gaze": Box(4) float64, "report": {"kind": Discrete(3), "label":
  Discrete(len(DATABASE_CLASSES)), "position": Box(3)}}``. ``gaze`` = (left pan, left tilt,
  right pan, right tilt) targets, rad, within the PTU limits (:mod:`ipbench.envs.ptu`).
  ``report.kind``: 0 none, 1 an object of class ``DATABASE_CLASSES[label]`` at world point
  ``position`` (m), 2 done (ends the episode). A report is scored first (+1 true positive,
  -1 false positive; :mod:`ipbench.envs.exploration_scoring`), then (unless done) the head
  saccades: each physics step the PTU position actuators get the rate-limited setpoints of
  the quantised targets until the head has settled (encoder on target, speed below
  ``settle_speed``) or ``max_saccade_time`` has passed. ``saccade_budget`` saccades truncate.
* Observation: ``head_left``/``head_right`` (HxWx3 uint8), ``head_*_K`` (3x3), ``head_*_pose``
  (4x4 world-from-camera, OpenCV axes, by forward kinematics of the encoder readings: what
  the robot knows), ``head_qpos`` (4,) encoder readings, rad. With ``fovea_factor`` f > 1 the
  cameras are foveated (:mod:`ipbench.envs.sensors.foveation`): each eye renders HxW, and
  ``head_*`` is the whole field downsampled to (H/f)x(W/f) with its ``head_*_K``, while
  ``head_*_fovea`` is the central (H/f)x(W/f) window at full resolution with its
  ``head_*_fovea_K`` (same pose). ``extrinsics="nominal"`` or
  ``"calibrated"`` (:mod:`ipbench.envs.cell.extrinsics`): the world is the true cell of
  ``robot_seed`` (images and masks distorted by its lenses), ``head_*_K``/``head_*_pose`` are
  the robot's beliefs and ``head_*_dist`` (5,) the distortion it believes.
* ``info`` (ground truth, evaluation and oracles only): ``objects`` {name: class (a
  database class or None), instance, role, position (3,), radius}, ``head_left_mask`` /
  ``head_right_mask`` (int32 index into ``objects``' order, -1 none, the size of
  ``head_*``; foveated: also ``head_*_fovea_mask``), ``score``,
  ``report`` (this step's outcome or None), ``saccade_s``, ``saccades``.
* ``step()``/``render()`` before ``reset()`` or after ``close()``: :class:`ResetNeededError`;
  a bad action: :class:`InvalidActionError` naming the field and the valid range.
"""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium as gym
import mujoco
import numpy as np
from gymnasium import spaces

from ipbench.assets.compose import HEAD_SIDES
from ipbench.assets.objects.object_model import RELEASED_MODEL, ObjectModel
from ipbench.envs.cell.extrinsics import DIST_SIZE, CameraKnowledge, check_extrinsics
from ipbench.envs.cell.model_errors import sample_model_errors
from ipbench.envs.errors import InvalidActionError, ResetNeededError
from ipbench.envs.exploration_scene import (
    DATABASE_CLASSES,
    GAZE_JOINTS,
    LEVELS,
    build_model,
    sample_scene,
)
from ipbench.envs.exploration_scoring import GroundTruthObject, Scorer
from ipbench.envs.head_observation import observe_head
from ipbench.envs.ptu import (
    PtuError,
    PtuSpec,
    head_spec_arrays,
    play,
    ptu_spec,
    setpoint_step,
)
from ipbench.envs.sensors import SensorRenderer, fit_offscreen
from ipbench.envs.sensors.foveation import fovea_window, foveate

__all__ = [
    "EXPLORATION_V1",
    "GAZE_JOINTS",
    "REPORT_KINDS",
    "ExplorationConfig",
    "ExplorationEnv",
    "InvalidActionError",
    "ResetNeededError",
]

REPORT_KINDS: tuple[str, ...] = ("none", "object", "done")
"""Meaning of ``action["report"]["kind"]``."""
POSITION_BOUND = 5.0
"""A report's ``position`` lies in [-5, 5]^3 m (the work cell is well inside)."""


@dataclass(frozen=True)
class ExplorationConfig:
    """Settings of an exploration episode.

    Attributes
    ----------
    scene : level, one of ``"simple"``, ``"medium"``, ``"complex"``
        (:data:`~ipbench.envs.exploration_scene.LEVELS`).
    head_size : (height, width) of each head image, px (D5100-like 3:2).
    saccade_budget : saccades (steps that are not ``done``) before truncation.
    settle_tolerance : the head has settled when every joint is within this many PTU steps
        of its target (0.5: the encoder reads the target) ...
    settle_speed : ... and moves slower than this (rad/s).
    max_saccade_time : longest simulated time of one saccade (s); the slowest full swing,
        tilt's 77.7 deg at 60 deg/s, takes 1.3 s.
    extrinsics : ``"true"`` (default), ``"nominal"`` or ``"calibrated"``
        (:mod:`ipbench.envs.cell.extrinsics`; the module docstring).
    robot_seed : seed of the true cell's model errors (``nominal``/``calibrated`` only).
    calibration : calibration file path for ``extrinsics="calibrated"``, else None.
    fovea_factor : 1: each head image is the whole HxW frame; f > 1: foveated cameras (module
        docstring; f divides H and W and leaves an even border).
    objects : how the objects are modelled (print orientation;
        :class:`~ipbench.assets.objects.object_model.ObjectModel`).
    """

    scene: str = "simple"
    head_size: tuple[int, int] = (680, 1024)
    saccade_budget: int = 30
    settle_tolerance: float = 0.5
    settle_speed: float = 0.01
    max_saccade_time: float = 3.0
    extrinsics: str = "true"
    robot_seed: int = 0
    calibration: str | None = None
    fovea_factor: int = 1
    objects: ObjectModel = RELEASED_MODEL

    def __post_init__(self) -> None:
        check_extrinsics(self.extrinsics, self.calibration, self.robot_seed)
        if self.scene not in LEVELS:
            raise ValueError(f"unknown scene {self.scene!r}; valid: {', '.join(LEVELS)}")
        size = tuple(self.head_size)
        if len(size) != 2 or not all(isinstance(v, int) and 0 < v for v in size):
            raise ValueError(f"head_size must be (height, width) positive ints, got {size!r}")
        object.__setattr__(self, "head_size", size)
        if self.fovea_factor != 1:
            fovea_window(*size, self.fovea_factor)  # a centred fovea exists, else SensorError
        if not isinstance(self.objects, ObjectModel):
            raise ValueError(f"objects must be an ObjectModel, got {self.objects!r}")
        if not (isinstance(self.saccade_budget, int) and self.saccade_budget >= 1):
            raise ValueError(f"saccade_budget must be an int >= 1, got {self.saccade_budget!r}")
        if not (self.settle_tolerance > 0 and self.settle_speed > 0 and self.max_saccade_time > 0):
            raise ValueError("settle_tolerance, settle_speed and max_saccade_time must be > 0")


EXPLORATION_V1: dict = {
    "head_size": (3264, 4928),
    "fovea_factor": 4,
    "objects": ObjectModel(upright_prints=True),
}
"""What ``ipbench/Exploration-v1`` fixes: the thesis' Nikon D5100 frames (4928x3264 px, thesis
ch. 3; the same field of view as v0's 1024x680, K scales with the size), foveated 4 times (two
1232x816 images per eye: the whole field and the central quarter of each side at full
resolution, the fovea the policies verge in), and prints that read upright."""


class ExplorationEnv(gym.Env):
    """Find the database objects of a table scene with the stereo head (module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 5}

    def __init__(self, render_mode: str | None = None, **config) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', not {render_mode!r}")
        self.config = ExplorationConfig(**config)
        self.render_mode = render_mode
        self.ptus: tuple[PtuSpec, PtuSpec] = (ptu_spec(), ptu_spec())
        lim = head_spec_arrays(self.ptus)
        self._lower, self._upper, self._speed = lim["lower"], lim["upper"], lim["speed"]
        f = self.config.fovea_factor
        h, w = self.config.head_size[0] // f, self.config.head_size[1] // f  # each image's
        b = POSITION_BOUND
        self.action_space = spaces.Dict(
            gaze=spaces.Box(self._lower, self._upper, dtype=np.float64),
            report=spaces.Dict(
                kind=spaces.Discrete(len(REPORT_KINDS)),
                label=spaces.Discrete(len(DATABASE_CLASSES)),
                position=spaces.Box(-b, b, shape=(3,), dtype=np.float64),
            ),
        )
        obs = {}
        for s in HEAD_SIDES:
            obs[f"head_{s}"] = spaces.Box(0, 255, (h, w, 3), np.uint8)
            obs[f"head_{s}_K"] = spaces.Box(-np.inf, np.inf, (3, 3), np.float64)
            obs[f"head_{s}_pose"] = spaces.Box(-np.inf, np.inf, (4, 4), np.float64)
            if f > 1:
                obs[f"head_{s}_fovea"] = spaces.Box(0, 255, (h, w, 3), np.uint8)
                obs[f"head_{s}_fovea_K"] = spaces.Box(-np.inf, np.inf, (3, 3), np.float64)
        obs["head_qpos"] = spaces.Box(self._lower, self._upper, dtype=np.float64)
        self._knowledge: CameraKnowledge | None = None  # None: extrinsics="true"
        if self.config.extrinsics != "true":
            self._knowledge = CameraKnowledge.build(
                self.config.extrinsics,
                tuple(f"head_{s}" for s in HEAD_SIDES),
                self.config.calibration,
                self.config.robot_seed,
            )
            self._errors = sample_model_errors(self.config.robot_seed)
            for s in HEAD_SIDES:
                obs[f"head_{s}_dist"] = spaces.Box(-np.inf, np.inf, (DIST_SIZE,), np.float64)
        self.observation_space = spaces.Dict(obs)
        self.model = self.data = self.scene = None
        self._renderer: SensorRenderer | None = None
        self._closed = False

    # -- gymnasium API -------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        if options:
            raise ValueError(f"unknown reset option(s) {sorted(options)}; valid: none")
        self.scene = sample_scene(self.config.scene, int(self.np_random.integers(2**31)))
        errors = None if self._knowledge is None else self._errors  # the true cell's
        self.model = m = build_model(self.scene, errors, self.config.objects)
        if tuple(PtuSpec.from_model(m, f"head_{s}_") for s in HEAD_SIDES) != self.ptus:
            raise RuntimeError("the work cell's PTUs differ from assets/head/ptu_d46.xml")
        self.data = mujoco.MjData(m)
        mujoco.mj_resetDataKeyframe(m, self.data, m.key("home").id)
        mujoco.mj_forward(m, self.data)
        self._fk = mujoco.MjData(m)
        if self._knowledge is not None:  # the robot's joints, by name, for the nominal FK
            self._known_qadr = np.array(
                [m.jnt_qposadr[m.joint(j).id] for j in self._knowledge.joint_names]
            )
        self._qadr = np.array([m.jnt_qposadr[m.joint(j).id] for j in GAZE_JOINTS])
        self._dadr = np.array([m.jnt_dofadr[m.joint(j).id] for j in GAZE_JOINTS])
        self._act = np.array(  # the position actuator of each gaze joint
            [
                next(a for a in range(m.nu) if m.actuator_trnid[a, 0] == m.joint(j).id)
                for j in GAZE_JOINTS
            ]
        )
        self._setpoint = np.asarray(self.scene.home_gaze, float)
        # PTU backlash (the true cell only): each axis' output follows its motor (the setpoint,
        # which the encoder counts) through a dead band of width b (ModelErrors' PtuErrors),
        # starting centred at home
        self._output = self._setpoint.copy()
        if self._knowledge is not None:
            self._half_play = 0.5 * np.concatenate(
                [self._errors.ptu(s).backlash for s in HEAD_SIDES]
            )
        if self._renderer is not None:
            self._renderer.close()
        fit_offscreen(m, self.config.head_size[1], self.config.head_size[0])
        self._renderer = SensorRenderer(m)
        roots = {m.body(o.name).id: k for k, o in enumerate(self.scene.objects)}
        self._mask_lut = np.full(m.ngeom + 1, -1, np.int32)  # last entry: background (-1)
        for g in range(m.ngeom):
            self._mask_lut[g] = roots.get(int(m.body_rootid[m.geom_bodyid[g]]), -1)
        self._truth = tuple(self._ground_truth(o) for o in self.scene.objects)
        self._scorer = Scorer(self._truth, DATABASE_CLASSES)
        self._saccades, self._closed = 0, False
        obs = self._observation()
        return obs, self._info(None, 0.0)

    def step(self, action):
        self._require_episode("step")
        gaze, kind, label, position = self._validate(action)
        reward, outcome = 0.0, None
        if REPORT_KINDS[kind] == "object":
            outcome = self._scorer.report(DATABASE_CLASSES[label], position)
            reward = 1.0 if outcome.kind == "true_positive" else -1.0
        terminated = REPORT_KINDS[kind] == "done"
        saccade_s = 0.0
        if not terminated:
            saccade_s = self._saccade(gaze)
            self._saccades += 1
        truncated = not terminated and self._saccades >= self.config.saccade_budget
        obs = self._observation()
        report = None if outcome is None else outcome.__dict__.copy()
        return obs, reward, terminated, truncated, self._info(report, saccade_s)

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        self._require_episode("render")
        return self._last_left.copy()

    def close(self) -> None:
        """Free the renderer and end the episode (idempotent); ``reset()`` starts a new one."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self.model is not None:
            self.model = self.data = None
            self._closed = True

    # -- internals -----------------------------------------------------------------------------
    def _require_episode(self, method: str) -> None:
        if self.model is None:
            why = "the environment was closed" if self._closed else "no episode has started"
            raise ResetNeededError(f"{why}: call reset() before {method}()")

    def _validate(self, action) -> tuple[np.ndarray, int, int, np.ndarray]:
        keys = sorted(self.action_space.spaces)
        if not isinstance(action, dict) or sorted(action) != keys:
            got = sorted(action) if isinstance(action, dict) else type(action).__name__
            raise InvalidActionError(f"an action is a dict with keys {keys}; got {got}")
        gaze = np.asarray(action["gaze"], float).reshape(-1)
        if gaze.shape != (4,) or not np.isfinite(gaze).all():
            raise InvalidActionError(
                f"action['gaze'] = {action['gaze']!r}: 4 finite angles (rad) {list(GAZE_JOINTS)}"
            )
        for k, ptu in enumerate(self.ptus):
            try:
                ptu.check(gaze[2 * k : 2 * k + 2])  # the PTU's own limits (envs/ptu.py)
            except PtuError as err:
                joints = ", ".join(GAZE_JOINTS[2 * k : 2 * k + 2])
                raise InvalidActionError(
                    f"action['gaze'][{2 * k}:{2 * k + 2}] ({joints}) is outside the PTU "
                    f"limits: {err}"
                ) from err
        report = action["report"]
        rkeys = sorted(self.action_space["report"].spaces)
        if not isinstance(report, dict) or sorted(report) != rkeys:
            raise InvalidActionError(
                f"action['report'] is a dict with keys {rkeys}; got {report!r}"
            )
        values = []
        for key, names in (("kind", REPORT_KINDS), ("label", DATABASE_CLASSES)):
            v = report[key]
            if not (np.ndim(v) == 0 and float(v) == int(v) and 0 <= int(v) < len(names)):
                valid = ", ".join(f"{i}={n}" for i, n in enumerate(names))
                raise InvalidActionError(f"action['report'][{key!r}] = {v!r}; valid: {valid}")
            values.append(int(v))
        pos = np.asarray(report["position"], float).reshape(-1)
        if pos.shape != (3,) or not np.isfinite(pos).all() or np.abs(pos).max() > POSITION_BOUND:
            raise InvalidActionError(
                f"action['report']['position'] = {report['position']!r}: 3 finite floats (world "
                f"m) within [-{POSITION_BOUND}, {POSITION_BOUND}]"
            )
        return gaze, values[0], values[1], pos

    def _saccade(self, gaze: np.ndarray) -> float:
        """Drive the PTUs to ``gaze`` until settled or the time limit; simulated seconds."""
        m, d, cfg = self.model, self.data, self.config
        target = np.concatenate(
            [p.command(gaze[2 * k : 2 * k + 2]) for k, p in enumerate(self.ptus)]
        )
        max_delta = self._speed * m.opt.timestep
        tol = cfg.settle_tolerance * self.ptus[0].step
        start = d.time
        while d.time - start < cfg.max_saccade_time - 1e-9:
            self._setpoint = setpoint_step(self._setpoint, target, max_delta)
            if self._knowledge is None:
                d.ctrl[self._act] = self._output = self._setpoint
            else:
                self._output = play(self._output, self._setpoint, self._half_play)
                d.ctrl[self._act] = self._output
            mujoco.mj_step(m, d)
            if (
                np.array_equal(self._setpoint, target)
                and np.all(np.abs(d.qpos[self._qadr] - self._output) <= tol)
                and np.all(np.abs(d.qvel[self._dadr]) < cfg.settle_speed)
            ):
                break
        mujoco.mj_forward(m, d)
        return float(d.time - start)

    def _encoder(self) -> np.ndarray:
        """What the PTUs' encoders read: the joints (the motors: plus the backlash lag)."""
        q = self.data.qpos[self._qadr]
        if self._knowledge is not None:
            q = q + (self._setpoint - self._output)
        return np.concatenate([p.encoder(q[2 * k : 2 * k + 2]) for k, p in enumerate(self.ptus)])

    def _observation(self) -> dict:
        m, d, r = self.model, self.data, self._renderer
        h, w = self.config.head_size
        enc = self._encoder()
        fk = self._fk  # the robot's belief: forward kinematics of the encoder readings
        fk.qpos[:] = d.qpos
        fk.qpos[self._qadr] = enc
        mujoco.mj_kinematics(m, fk)
        mujoco.mj_comPos(m, fk)
        mujoco.mj_camlight(m, fk)
        lenses = None if self._knowledge is None else self._errors.distortion  # the true lenses
        obs, self._masks = observe_head(
            r, m, d, self.config.head_size, pose_data=fk, lenses=lenses, mask_lut=self._mask_lut
        )
        if self._knowledge is not None:  # what the robot believes, at its encoder readings
            readings = fk.qpos[self._known_qadr]
            sizes = {f"head_{s}": (w, h) for s in HEAD_SIDES}
            for c, belief in self._knowledge.observe(readings, sizes).items():
                obs[f"{c}_K"], obs[f"{c}_pose"], obs[f"{c}_dist"] = (
                    belief.K,
                    belief.pose,
                    belief.dist,
                )
        if self.config.fovea_factor > 1:
            self._foveate(obs)
        obs["head_qpos"] = enc
        self._last_left = obs["head_left"]
        return obs

    def _foveate(self, obs: dict) -> None:
        """Replace each full-resolution head image (and mask) by its periphery and fovea."""
        f = self.config.fovea_factor
        h, w = self.config.head_size
        r0, c0, rows, cols = fovea_window(h, w, f)
        for s in HEAD_SIDES:
            eye = foveate(obs[f"head_{s}"], obs[f"head_{s}_K"], f)
            obs[f"head_{s}"], obs[f"head_{s}_K"] = eye.periphery, eye.periphery_K
            obs[f"head_{s}_fovea"], obs[f"head_{s}_fovea_K"] = eye.fovea, eye.fovea_K
            mask = self._masks[s]  # labels are not averaged: each block's pixel (f//2, f//2)
            self._masks[s] = np.ascontiguousarray(mask[f // 2 :: f, f // 2 :: f])
            self._masks[f"{s}_fovea"] = np.ascontiguousarray(mask[r0 : r0 + rows, c0 : c0 + cols])

    def _ground_truth(self, obj) -> GroundTruthObject:
        rot = np.empty(9)
        mujoco.mju_quat2Mat(rot, np.asarray(obj.quat, float))
        inst = obj.instance
        center = np.asarray(obj.position) + rot.reshape(3, 3) @ np.asarray(inst.center)
        radius = 0.5 * float(np.linalg.norm(inst.size))
        return GroundTruthObject(obj.name, obj.label, tuple(center.tolist()), radius)

    def _info(self, report: dict | None, saccade_s: float) -> dict:
        objects = {
            t.name: {
                "class": t.label,
                "instance": o.instance.name,
                "role": o.role,
                "position": np.array(t.position),
                "radius": t.radius,
            }
            for t, o in zip(self._truth, self.scene.objects, strict=True)
        }
        masks = {f"head_{side}_mask": mask for side, mask in self._masks.items()}
        return {
            "objects": objects,
            **masks,
            "score": self._scorer.score.as_dict(),
            "report": report,
            "saccade_s": saccade_s,
            "saccades": self._saccades,
        }
