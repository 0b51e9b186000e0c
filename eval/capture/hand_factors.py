"""Switches that remove one factor from an in-hand capture (:mod:`ipbench.eval.capture.hand_views`).

An in-hand view may carry less information than a first look on the table for five reasons:
the in-hand segmentation (it may cut the object or keep the jaws' points), the jaws' points in
the cloud, the sensor's noise, the distance (the object is held closer than the table-top views
are taken), and the physics (the jaws hide part of the object). Each of
:data:`IN_HAND_FACTORS` removes one of the first four from the capture, with what only the
simulator knows — this is capture-rig code, as the renderer of the dataset is:

* ``true_mask``: the held object's points are those of its true mask (the simulator's
  segmentation, ``info["wrist_mask"]``) instead of
  :func:`~ipbench.perception.segmentation.segment_in_hand`'s segment;
* ``no_jaws``: every point on a geom of the gripper (the simulator's segmentation of the
  palm and finger bodies) is dropped before the in-hand segmentation;
* ``ideal_depth``: the depth image rendered again from the same state without the sensor's
  noise (``DepthNoiseConfig(enabled=False)``: depth clipped to the sensor's range, nothing
  else);
* ``table_distance``: the wrist camera moved back along its line of sight until it is the
  table-top views' distance (``DatasetConfig.distance``) from the object's centre, the view
  rendered there (with the sensor's noise), and the state put back.

Each switch acts on the view after a presentation, never on the physics: the grasps and turns
(and the noise draws of the other views) are those of the capture with every factor in, so one
pass captures every factor's views of the same presentations. The physics (the jaws hiding the
object) is what no switch removes.
"""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np

from ipbench.assets.compose import GRIPPER_ARM
from ipbench.envs.ik import look_at_rotation
from ipbench.envs.robot import PlanningError
from ipbench.envs.sensors import camera_pose, intrinsics
from ipbench.envs.sensors.depth_noise import DepthNoiseConfig, DepthNoiseModel
from ipbench.envs.sorting import WRIST_CAMERA, WRIST_SIZE
from ipbench.perception.cloud import Cloud

__all__ = [
    "IN_HAND_FACTORS",
    "check_factor",
    "gripper_geoms",
    "gripper_pixels",
    "ideal_view",
    "object_pixels",
    "sensor_without_noise",
    "view_from_distance",
]

IN_HAND_FACTORS: tuple[str, ...] = ("true_mask", "no_jaws", "ideal_depth", "table_distance")
"""The factors an in-hand capture can remove, one at a time (see the module docstring)."""


def check_factor(factor: str | None) -> None:
    """Raise ``ValueError`` unless ``factor`` is None (every factor in) or one of
    :data:`IN_HAND_FACTORS`."""
    if factor is not None and factor not in IN_HAND_FACTORS:
        raise ValueError(
            f"unknown in-hand factor {factor!r}; valid: None (as captured), "
            + ", ".join(IN_HAND_FACTORS)
        )


def sensor_without_noise(sensor: DepthNoiseConfig) -> DepthNoiseConfig:
    """``sensor`` with every effect off: ideal depth within its range (``ideal_depth``)."""
    return replace(sensor, enabled=False)


def gripper_geoms(model: mujoco.MjModel) -> np.ndarray:
    """(ngeom + 1,) bool: the geoms of the gripper's palm and fingers (the bodies under
    ``{GRIPPER_ARM}_gripper_palm``); the last entry, for segmentation id -1 (background), is
    False."""
    palm = model.body(f"{GRIPPER_ARM}_gripper_palm").id
    inside = np.zeros(model.nbody, bool)
    inside[palm] = True
    for body in range(palm + 1, model.nbody):  # bodies are numbered parents first
        inside[body] = inside[model.body_parentid[body]]
    return np.append(inside[model.geom_bodyid], False)


def gripper_pixels(env) -> np.ndarray:
    """(H * W,) bool: the pixels of the wrist camera's current view that show the gripper
    (``env``: a Sorting env after a step; rendered from the simulator's state)."""
    base = env.unwrapped
    h, w = WRIST_SIZE
    seg = base.renderer.render_segmentation(base.data, WRIST_CAMERA, w, h)
    return gripper_geoms(base.model)[seg.reshape(-1)]


def object_pixels(cloud: Cloud, wrist_mask: np.ndarray, object_id: int) -> Cloud:
    """The points of ``cloud`` whose pixel belongs to object ``object_id`` in the (H, W)
    ground-truth ``wrist_mask`` (``info["wrist_mask"]``): the object's true mask."""
    return cloud.subset(np.asarray(wrist_mask).reshape(-1)[cloud.pixels] == object_id)


def ideal_view(env, obs: dict) -> dict:
    """``obs`` with its ``wrist_depth`` (H, W float32, m) rendered again from the simulator's
    current state without noise (only clipped to the sensor's range)."""
    base = env.unwrapped
    h, w = WRIST_SIZE
    depth = base.renderer.render_rgbd(base.data, WRIST_CAMERA, w, h)[1]
    k = intrinsics(base.model, WRIST_CAMERA, w, h)
    ideal = DepthNoiseModel(sensor_without_noise(base.config.depth_noise))
    clipped = ideal.apply(depth, k.fx, k.fy, np.random.default_rng(0))
    return {**obs, "wrist_depth": np.asarray(clipped, np.float32)}


def view_from_distance(env, center: np.ndarray, distance: float) -> dict | None:
    """The wrist observation with the camera moved back (or forward) along its line of sight to
    ``distance`` (m) from ``center`` (3,) (world, m), looking at it; the simulator's state and
    the env's random stream are restored afterwards. None when the camera arm cannot reach
    that pose."""
    base = env.unwrapped
    model, data, robot = base.model, base.data, base.robot
    eye = camera_pose(model, data, WRIST_CAMERA)[:3, 3]
    ray = eye - np.asarray(center, float)
    new_eye = center + distance * ray / np.linalg.norm(ray)
    try:
        solution = robot.solve(
            robot.camera_ik,
            new_eye,
            look_at_rotation(new_eye, center),
            seeds=(base.skills.camera_ready,),
        )
    except PlanningError:
        return None
    spec = mujoco.mjtState.mjSTATE_INTEGRATION
    state = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, state, spec)
    stream = base.np_random.bit_generator.state
    try:
        robot.teleport(dict(zip(solution.joints, solution.qpos, strict=True)))
        return base._observation()  # the env's own rendering, noise and sensor unit
    finally:
        mujoco.mj_setState(model, data, state, spec)
        mujoco.mj_forward(model, data)
        base.np_random.bit_generator.state = stream
