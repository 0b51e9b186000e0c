"""``ipbench/Sorting-v1`` (and ``-v0``): sort the objects on the table into their category's bin.

The public contract (external policies and the benchmark's checks rely on it; the README
documents it):

* Categories, in bin order: ``juice_bottle, milk_carton, bowl, mug, juice_box``.
* Action: ``{"command": Discrete(3), "position": Box(3), "yaw": Box(1), "bin": Discrete(5),
  "opening": Box(1)}`` (v0: no ``opening``).
  ``0 = place_in_bin``: pick whatever is at ``position`` (world frame, m) with the jaws turned
  to ``yaw`` and opened to ``opening`` (m, at most ``MAX_JAW_OPENING``; the descent stops
  where a jaw lands on something) and drop it in bin ``bin``; ``1 = inspect_in_area``: pick
  it and set it down in the inspection area (or, when an object is already there or in
  hand, turn it by ``yaw`` there); ``2 = inspect_in_hand``: pick it and present it to the
  wrist camera (or, with an object in hand or in the area, turn it by ``yaw`` and present it
  again); v2 only (``Discrete(4)``): ``3 = pick`` (:data:`PICK`): pick it and hold it. While
  an object is in hand or in the area, ``place_in_bin`` acts on it and ``position`` is
  ignored. Each
  inspect step's observation is the new view; after ``place_in_bin`` the camera looks at
  the table again.
* Observation: ``wrist_rgb`` (480x640x3 uint8), ``wrist_depth`` (480x640 float32, m, 0 =
  no depth), ``head_left``/``head_right`` (HxWx3 uint8), ``qpos`` (robot joints, in the order of
  ``ROBOT_JOINTS``),
  ``wrist_K``/``head_*_K`` (3x3 intrinsics), ``wrist_pose``/``head_*_pose`` (4x4
  world-from-camera, OpenCV convention: x right, y down, z forward).
  ``cameras=`` (:data:`CAMERAS`; default both) chooses which cameras are rendered: e.g.
  ``gym.make("ipbench/Sorting-v2", cameras=("wrist",))`` renders no head images and its
  observation (and space) has no ``head_*`` keys; every other value is what the default
  gives.
* ``info``: ``objects`` (per object id: category, instance, known, pose (7,) position and
  quaternion of the object frame, center (3,) of its bounding box, status),
  ``wrist_mask`` (480x640 int16 object id per pixel, -1 = none; only with the wrist camera),
  ``skills`` (what ran, with success and reason), ``physics_undone`` (v1: this step's physics
  blew up and was rolled back; its skill is reported as failed), ``physics_unstable`` (v0: it
  blew up).
  Ground truth lives only in ``info``.
* ``step()`` or ``render()`` before ``reset()`` or after ``close()`` raises
  :class:`ResetNeededError`; ``close()`` is idempotent and ``reset()`` starts a new episode.
* ``reset(seed=..., options={"layout": Layout})`` sets the objects up as the given
  :class:`~ipbench.envs.layout.Layout` instead of sampling the scene's (a capture rig or a
  hand-made scene); without options the scene's seeded layout is used.
* Reward: +1 per object that lands in its own bin, -1 in another bin, ``-step_cost`` per skill.
  Terminated when no object is left on the table, in the area or in hand; truncated at
  ``max_steps`` or (v0) when the physics blows up: a non-finite state, a MuJoCo warning, or
  (v1 only, which rolls the step back instead) an object moving faster than
  ``MAX_OBJECT_SPEED``.

Versions: v1 pre-shapes the jaws, guards the descent, closes the fingers at a gripper's speed
with realistic finger inertia, and rolls back contact blow-ups (:data:`V0` lists what v0
fixes instead). Before v1 a grasp in clutter could launch the neighbours off the table.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from functools import lru_cache

import cv2
import gymnasium as gym
import mujoco
import numpy as np

from ipbench.assets.compose import (
    CAMERA_ARM,
    GRIPPER_ARM,
    HEAD_SIDES,
    arm_joint_names,
    build_workcell_spec,
)
from ipbench.assets.objects import CATALOGS, CATEGORIES
from ipbench.envs.cell.extrinsics import CameraKnowledge, distort_labels
from ipbench.envs.cell.model_errors import apply_model_errors, sample_model_errors
from ipbench.envs.errors import InvalidActionError, ResetNeededError
from ipbench.envs.head_observation import observe_head
from ipbench.envs.layout import Layout, sample_layout
from ipbench.envs.robot import RobotController, ik_model
from ipbench.envs.sensors import SensorRenderer, camera_pose, intrinsics, specular_geoms
from ipbench.envs.sensors.depth_noise import DepthNoiseModel
from ipbench.envs.sensors.lens_distortion import distort_image
from ipbench.envs.sensors.structured_light import UnitError, apply_unit
from ipbench.envs.settling import settle_gently
from ipbench.envs.skills import SkillResult, Skills
from ipbench.envs.sorting_config import CAMERAS, V0, V2, V3, SortingConfig
from ipbench.envs.sorting_scenes import SCENES, scenes_for
from ipbench.envs.sorting_spaces import action_space, check_action, observation_space
from ipbench.envs.world import (
    Places,
    World,
    build_world,
    object_status,
)

__all__ = [
    "CAMERAS",
    "COMMANDS",
    "PICK",
    "ROBOT_JOINTS",
    "WRIST_CAMERA",
    "InvalidActionError",
    "MAX_JAW_OPENING",
    "MAX_OBJECT_SPEED",
    "ResetNeededError",
    "V0",
    "V2",
    "V3",
    "workcell_places",
    "SortingConfig",
    "SortingEnv",
]

COMMANDS = ("place_in_bin", "inspect_in_area", "inspect_in_hand")
"""Meaning of ``action["command"]`` (v0, v1); ``Sorting-v2`` adds :data:`PICK`."""
PICK = "pick"
"""``Sorting-v2``'s command 3: pick the object at ``position`` and hold it above the table (the
camera keeps looking at the table); the next ``place_in_bin`` puts it into a bin. A pick
followed by a place moves the robot exactly as one ``place_in_bin`` does, with an observation
in between (e.g. for a policy that wants to know what it holds before choosing the bin)."""
WRIST_CAMERA = f"{CAMERA_ARM}_wrist_camera"
ROBOT_JOINTS: tuple[str, ...] = (
    ("turntable_joint",)
    + arm_joint_names(GRIPPER_ARM)
    + (f"{GRIPPER_ARM}_gripper_finger_a", f"{GRIPPER_ARM}_gripper_finger_b")
    + arm_joint_names(CAMERA_ARM)
    + tuple(f"head_{s}_{j}" for s in HEAD_SIDES for j in ("pan", "tilt"))
)
"""Joint names of ``observation["qpos"]``, in order (rad; the two fingers in m)."""
WRIST_SIZE = (480, 640)
_UNSAFE = {"on_table", "in_inspection_area", "in_hand"}
UNDONE_REASON = "undone: the contact solver blew up during this step, which was rolled back"
MAX_JAW_OPENING = 0.21
"""The gripper's full jaw opening (m): the largest ``action["opening"]``."""
MAX_OBJECT_SPEED = 6.0
"""An object moving faster than this (m/s; a fall from 1.8 m) means the contact solver blew
up: the robot moves at most ~3 m/s and nothing in the cell can throw that fast."""


@lru_cache(maxsize=1)
def workcell_places() -> Places:
    """The work cell's places, e.g. the inspection area (static: they do not depend on the
    objects; what a policy may know of the cell without seeing it)."""
    return Places.from_model(ik_model())


def _layout_option(options: dict | None) -> Layout | None:
    """The ``layout`` of ``reset``'s options, checked (None when not given)."""
    options = options or {}
    unknown = set(options) - {"layout"}
    if unknown:
        raise ValueError(f"unknown reset option(s) {sorted(unknown)}; valid: layout")
    layout = options.get("layout")
    if layout is None:
        return None
    if not isinstance(layout, Layout) or not layout.objects:
        raise ValueError(
            "options['layout'] must be an ipbench.envs.layout.Layout with at least one object, "
            f"got {layout!r}"
        )
    if sorted(o.object_id for o in layout.objects) != list(range(len(layout.objects))):
        raise ValueError("options['layout']: object ids must be 0 .. n-1, each once")
    return layout


class SortingEnv(gym.Env):
    """Sort household objects into bins with the CloPeMa robot (see the module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 30}

    def __init__(self, render_mode: str | None = None, **config) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', not {render_mode!r}")
        self.config = SortingConfig(**config)
        if self.config.catalog not in CATALOGS:
            raise ValueError(
                f"unknown catalog {self.config.catalog!r}; valid: {', '.join(CATALOGS)}"
            )
        valid_scenes = scenes_for(self.config.catalog)  # "pile": v2 only
        if self.config.scene not in valid_scenes:
            what = f"unknown scene {self.config.scene!r}"
            if self.config.scene in SCENES:
                needs = ", ".join(SCENES[self.config.scene].catalogs)
                what = (
                    f"scene {self.config.scene!r} needs the {needs} catalogue (Sorting-v2), "
                    f"not {self.config.catalog!r}"
                )
            raise ValueError(f"{what}; valid scenes: {', '.join(valid_scenes)}")
        self.render_mode = render_mode
        self._n_objects = SCENES[self.config.scene].n_objects
        self.max_steps = self.config.max_steps or 4 * self._n_objects + 10
        self._noise = DepthNoiseModel(self.config.depth_noise)
        self._renderer: SensorRenderer | None = None
        self.world: World | None = None
        self._closed = False
        self._wrist_seg: np.ndarray | None = None
        self._frame_listeners: list[tuple[float, Callable[[], None]]] = []
        self._robot_joints = ROBOT_JOINTS
        self._knowledge: CameraKnowledge | None = None  # None: extrinsics="true"
        if self.config.extrinsics != "true":
            names = [c for g in self.config.cameras for c in ((g,) if g == "wrist" else
                     tuple(f"head_{s}" for s in HEAD_SIDES))]  # fmt: skip
            self._knowledge = CameraKnowledge.build(
                self.config.extrinsics, names, self.config.calibration, self.config.robot_seed
            )
            self._errors = sample_model_errors(self.config.robot_seed)
        self.observation_space = observation_space(
            self.config.cameras,
            len(self._robot_joints),
            WRIST_SIZE,
            self.config.head_size,
            self.config.depth_noise.max_range_m,
            () if self._knowledge is None else self._knowledge.cameras,
        )
        self.action_space = action_space(
            len(self.commands), MAX_JAW_OPENING if self.config.jaw_opening else None
        )

    @property
    def commands(self) -> tuple[str, ...]:
        """Meaning of ``action["command"]``: :data:`COMMANDS`, and :data:`PICK` in v2."""
        return COMMANDS + ((PICK,) if self.config.pick_command else ())

    # -- frames for videos -----------------------------------------------------------------
    def add_frame_listener(self, callback: Callable[[], None], fps: float = 30.0) -> None:
        """Call ``callback()`` every 1/``fps`` simulated seconds while skills run (videos)."""
        self._frame_listeners.append((1.0 / fps, callback))

    def _physics_step(self) -> None:
        t_before = self.data.time
        mujoco.mj_step(self.model, self.data)
        # v0 knows no speed limit (it truncated on NaN and warnings only)
        if self.config.undo_blowups and not self._blew_up:
            speed = np.abs(self.data.qvel[self._object_dofs])
            self._blew_up = not (speed < MAX_OBJECT_SPEED).all()  # NaN too (the method: fast)
        for period, callback in self._frame_listeners:
            if int(self.data.time / period) != int(t_before / period):
                callback()

    # -- gymnasium API -----------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        layout_seed = int(self.np_random.integers(2**31 - 1))
        places = workcell_places()
        layout = _layout_option(options)
        if layout is None:
            layout = sample_layout(
                self.config.scene,
                layout_seed,
                places.spawn_area.center,
                places.spawn_area.half,
                places.table_height,
                catalog=self.config.catalog,
            )
        # the sensor unit of this episode (its systematic error); its own stream, so that
        # the episode's other draws do not depend on whether the sensor has one
        self._unit = self._noise.draw_unit(np.random.default_rng([layout_seed, 7500]))
        self._registration = (0, 0)  # the true cell's depth-to-RGB shift, px (dx, dy)
        if self._knowledge is not None:
            # the robot's one Xtion: its registration error is the robot's (robot_seed), not
            # the sensor preset's per-episode unit draw, which it replaces
            self._registration = self._errors.registration_shift_px
            if self._unit is not None:
                self._unit = replace(self._unit, shift_px=(0, 0))
        spec = build_workcell_spec(self.config.bin_depth, self.config.bin_floor_backing)
        if self.config.finger_armature is not None:
            for finger in ("a", "b"):
                spec.joint(
                    f"{GRIPPER_ARM}_gripper_finger_{finger}"
                ).armature = self.config.finger_armature
        if self._knowledge is not None:  # the true cell (extrinsics "nominal"/"calibrated")
            apply_model_errors(spec, self._errors)
        self.world = build_world(layout, spec, self.config.physics, self.config.objects)
        self.model = self.world.model
        self.data = mujoco.MjData(self.model)
        mujoco.mj_resetDataKeyframe(self.model, self.data, self.model.key("home").id)
        m = self.model
        # linear velocity dofs of every object's free joint
        self._object_dofs = np.concatenate(
            [m.jnt_dofadr[m.body_jntadr[b]] + np.arange(3) for b in self.world.object_bodies]
        )
        self._blew_up = False
        self.robot = RobotController(
            self.model,
            self.data,
            self._physics_step,
            self.config.motion,
            planning_model=ik_model(self.config.bin_depth),
        )
        self.skills = Skills(self.robot, self.world.places, self.config.skills)
        if self._renderer is not None:
            self._renderer.close()
        self._renderer = SensorRenderer(self.model)
        self._place_arms_at_start()
        if SCENES[self.config.scene].gentle_settle > 0:  # a pile (v2 only)
            settle_gently(
                self.model,
                self.data,
                self.world.object_bodies,
                self.robot.hold,
                SCENES[self.config.scene].gentle_settle,
            )
        self.robot.hold(self.config.settle_time)
        # (ngeom + 1,): shiny geoms; the last entry stands for the background (id -1)
        self._specular_geoms = np.append(specular_geoms(self.model), False)
        self._robot_qadr = np.array([m.jnt_qposadr[m.joint(j).id] for j in self._robot_joints])
        if self._knowledge is not None:  # the encoders the nominal FK reads, by joint name
            self._known_qadr = np.array(
                [m.jnt_qposadr[m.joint(j).id] for j in self._knowledge.joint_names]
            )
        # geom id -> object id (the last entry stands for the background, id -1)
        self._mask_lut = np.full(m.ngeom + 1, -1, np.int16)
        for g, k in self.world.object_geoms.items():
            self._mask_lut[g] = k
        self._steps = 0
        # (grasp position, yaw, jaw opening) of the object in the inspection area
        self._area: tuple[np.ndarray, float, float | None] | None = None
        self._jaws: float | None = None  # the last pick's jaw opening
        self._statuses = self._all_statuses()
        self._unstable = self._blew_up
        self._undone = False
        self._closed = False
        obs = self._observation()
        return obs, self._info([])

    def step(self, action):
        self._require_episode("step")
        command, position, yaw, bin_index, opening = check_action(
            action, self.action_space, self.commands
        )
        self._steps += 1
        warnings_before = sum(w.number for w in self.data.warning)
        snapshot = self._snapshot() if self.config.undo_blowups else None
        results = self._execute(command, position, yaw, bin_index, opening)
        blew_up = bool(
            self._blew_up
            or not np.all(np.isfinite(self.data.qpos))
            or sum(w.number for w in self.data.warning) > warnings_before
        )
        undone = blew_up and snapshot is not None
        if undone:
            self._restore(snapshot)
            name = results[0].name if results else self.commands[command]
            results = [SkillResult(name, False, UNDONE_REASON, 0.0)]
        before = self._statuses
        self._statuses = self._all_statuses()
        reward = -self.config.step_cost * sum(r.sim_time > 0 for r in results)
        for k, status in enumerate(self._statuses):
            if status.startswith("in_bin:") and status != before[k]:
                correct = status == f"in_bin:{self.world.layout.objects[k].instance.category}"
                reward += 1.0 if correct else -1.0
        self._unstable = blew_up and not undone
        self._undone = undone
        terminated = not any(s in _UNSAFE for s in self._statuses)
        truncated = self._unstable or self._steps >= self.max_steps
        obs = self._observation()
        return obs, float(reward), bool(terminated), bool(truncated), self._info(results)

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        self._require_episode("render")
        h, w = self.config.render_size
        return self._renderer.render_rgb(self.data, "overview", w, h)

    @property
    def renderer(self) -> SensorRenderer | None:
        """The sensor renderer of the current episode (``None`` before ``reset``)."""
        return self._renderer

    @property
    def depth_noise(self) -> DepthNoiseModel:
        """The wrist camera's depth-noise model."""
        return self._noise

    def close(self) -> None:
        """Free the renderer and end the episode (idempotent); ``reset()`` starts a new one."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self.world is not None:
            self.world = None
            self._closed = True

    def _require_episode(self, method: str) -> None:
        if self.world is None:
            why = "the environment was closed" if self._closed else "no episode has started"
            raise ResetNeededError(f"{why}: call reset() before {method}()")

    # -- internals ---------------------------------------------------------------------------
    def _execute(
        self,
        command: int,
        position: np.ndarray,
        yaw: float,
        bin_index: int,
        opening: float | None = None,
    ):
        sk, places = self.skills, self.world.places
        results: list[SkillResult] = []

        def run(result: SkillResult) -> bool:
            results.append(result)
            return result.success

        def acquire(target: np.ndarray, grasp_yaw: float) -> bool:
            """Get an object in hand: already held, from the area, or at ``target``."""
            if sk.holding:
                return True
            jaws = opening
            area = self._area
            if area is not None:
                target, grasp_yaw, jaws = area
                self._area = None
            elif self._view != "scene":
                run(sk.look(places.scene_view, places.scene_target))
            self._jaws = jaws
            picked = run(sk.pick(target, grasp_yaw, jaws))
            if (
                not picked
                and area is not None
                and self.config.keep_area_after_failed_pick
                and "in_inspection_area" in self._all_statuses()
            ):
                self._area = area  # still there: the next command tries the area again
            return picked

        name = self.commands[command]
        if name == PICK:
            acquire(position, yaw)  # holding already: nothing to do
        elif name == "place_in_bin":
            if acquire(position, yaw):
                run(sk.place_in_bin(CATEGORIES[bin_index]))
            run(sk.look(places.scene_view, places.scene_target, name="look_at_table"))
            self._view = "scene"
        elif name == "inspect_in_area":
            turn = yaw if (sk.holding or self._area is not None) else 0.0
            if acquire(position, yaw) and run(sk.place_in_inspection_area(turn)):
                a = places.inspection_area.center
                self._area = (
                    np.array([a[0], a[1], a[2] + sk.grasp_height + sk.config.grasp_depth]),
                    sk.grasp_yaw,
                    self._jaws,
                )
            run(sk.look(places.inspection_view, places.inspection_area.center, name="look_at_area"))
            self._view = "area"
        else:  # inspect_in_hand
            turn = yaw if (sk.holding or self._area is not None) else 0.0
            if acquire(position, yaw):
                run(sk.present_in_hand(turn))
                self._view = "hand"
        return results

    def _snapshot(self) -> tuple:
        """Everything a step changes: the physics state and the skills' and env's memory."""
        spec = mujoco.mjtState.mjSTATE_INTEGRATION
        state = np.empty(mujoco.mj_stateSize(self.model, spec))
        mujoco.mj_getState(self.model, self.data, state, spec)
        sk = self.skills
        return state, (sk.holding, sk.grasp_height, sk.grasp_yaw), self._area, self._view

    def _restore(self, snapshot: tuple) -> None:
        state, skills, self._area, self._view = snapshot
        mujoco.mj_setState(self.model, self.data, state, mujoco.mjtState.mjSTATE_INTEGRATION)
        mujoco.mj_forward(self.model, self.data)
        self.skills.holding, self.skills.grasp_height, self.skills.grasp_yaw = skills
        self._blew_up = False

    def _place_arms_at_start(self) -> None:
        """Camera arm looking at the table, gripper arm parked clear of the camera's view."""
        skills = self.skills
        park = self.world.places.inspection_area.center + np.array(
            [-0.05, 0.05, self.config.skills.transit_height + 0.05]
        )
        ready = skills.tool_pose(park[:2], park[2], 0.0)
        targets = dict(zip(skills.camera_ready.joints, skills.camera_ready.qpos, strict=True))
        targets.update(zip(ready.joints, ready.qpos, strict=True))
        self.robot.teleport(targets)
        self.robot.data.ctrl[skills.grasp_actuator] = self.config.skills.open_width
        self._view = "scene"

    def _observation(self) -> dict:
        m, d, r = self.model, self.data, self._renderer
        wrist = "wrist" in self.config.cameras
        obs: dict[str, np.ndarray] = {}
        if wrist:  # (keys in the released ids' order)
            h, w = WRIST_SIZE
            rgb, depth = r.render_rgbd(d, WRIST_CAMERA, w, h)
            seg = r.render_segmentation(d, WRIST_CAMERA, w, h)
            k_wrist = intrinsics(m, WRIST_CAMERA, w, h)
            if self._knowledge is not None:  # the true lens
                lens = self._errors.distortion[WRIST_CAMERA]
                rgb = distort_image(rgb, k_wrist.K, lens)
                depth = distort_image(depth, k_wrist.K, lens, interpolation=cv2.INTER_NEAREST)
                seg = distort_labels(seg, k_wrist.K, lens)
            self._wrist_seg = seg
            specular = self._specular_geoms[seg] if self._noise.uses_specular else None
            depth = self._noise.apply(
                depth, k_wrist.fx, k_wrist.fy, self.np_random, specular=specular, unit=self._unit
            )
            if self._registration != (0, 0):  # the reported depth at RGB pixel (u, v) is the
                # registered depth at (u - du, v - dv) (ModelErrors.depth_registration_px)
                shift = UnitError(shift_px=self._registration)
                depth = apply_unit(np.asarray(depth, np.float32), shift)
            obs["wrist_rgb"], obs["wrist_depth"] = rgb, depth.astype(np.float32)
        obs["qpos"] = d.qpos[self._robot_qadr].copy()
        if wrist:
            obs["wrist_K"], obs["wrist_pose"] = k_wrist.K, camera_pose(m, d, WRIST_CAMERA)
        if "head" in self.config.cameras:
            lenses = None if self._knowledge is None else self._errors.distortion  # true lenses
            obs |= observe_head(r, m, d, self.config.head_size, lenses=lenses)[0]
        if self._knowledge is not None:  # what the robot believes, at its encoder readings
            hh, hw = self.config.head_size
            sizes = {c: (WRIST_SIZE[1], WRIST_SIZE[0]) if c == "wrist" else (hw, hh)
                     for c in self._knowledge.cameras}  # fmt: skip
            for c, belief in self._knowledge.observe(d.qpos[self._known_qadr], sizes).items():
                obs[f"{c}_K"], obs[f"{c}_pose"] = belief.K, belief.pose
                obs[f"{c}_dist"] = belief.dist
        return obs

    def _all_statuses(self) -> list[str]:
        return [
            object_status(self.world, self.data, k, self.skills.pads)
            for k in range(len(self.world.layout.objects))
        ]

    def _info(self, results: list[SkillResult]) -> dict:
        objects = {}
        for k, obj in enumerate(self.world.layout.objects):
            body = self.world.object_bodies[k]
            pos, quat = self.data.xpos[body].copy(), self.data.xquat[body].copy()
            rot = self.data.xmat[body].reshape(3, 3)
            objects[k] = {
                "category": obj.instance.category,
                "instance": obj.instance.name,
                "known": obj.instance.known,
                "pose": np.concatenate([pos, quat]),
                "center": pos + rot @ np.asarray(obj.instance.center),
                "status": self._statuses[k],
            }
        info: dict = {"objects": objects}
        if "wrist" in self.config.cameras:  # (no wrist camera: no view to label)
            info["wrist_mask"] = self._mask_lut[self._wrist_seg]
        return info | {
            "skills": [r.__dict__.copy() for r in results],
            "physics_unstable": self._unstable,
            "physics_undone": self._undone,
            "sim_time": float(self.data.time),
        }
