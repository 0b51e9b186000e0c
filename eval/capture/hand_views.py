"""In-hand views: every catalogue object picked up and turned in front of the wrist camera.

GP-IPM inspects an uncertain object by holding it up to the wrist camera (thesis ch. 6). Seen
that way an object is partly hidden by the jaws, seen from closer and from other angles than on
the table, and cut out by :func:`~ipbench.perception.segmentation.segment_in_hand` rather than
by the table-top segmentation; a model trained on table-top views alone labels such views of
unseen instances right only about two times in three (``ipbench eval perception``). These views
train the in-hand model.

The capture rig is the benchmark environment itself (the dataset's ``env_id``, by default
``ipbench/Sorting-v1``, reset with a one-object layout): the object stands alone at the
centre of the spawn area in each resting pose the scenes use (upright; on its side when it
can lie), the gripper picks it across its narrower side at its bounding-box grasp point (the
rig knows where it put the object, as an operator would; a short object with the pads just
under its top, as the policies' grasp planning holds it: dataset version 2, before which the
pads closed 2 cm lower and held no noodle bowl at all), presents it to the wrist camera and
turns it by ``in_hand_turn_deg`` between ``in_hand_views`` views. The wrist turns through
about 180 deg, so each pose is captured from ``in_hand_placements`` grasps, the object put
down turned by 360 deg / ``in_hand_placements`` between them, to show every side. Skills,
camera, depth noise and in-hand segmentation (with the gripper pose from the joint positions)
are those of an inspection during an episode. A capture stops early when the object slips out
or the wrist cannot turn further. ``InHandAblationConfig.in_hand_removed`` removes one
factor of :data:`~ipbench.eval.capture.hand_factors.IN_HAND_FACTORS` from the capture (the in-hand
ablation, :mod:`ipbench.eval.perception.in_hand_ablation`).
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from typing import TYPE_CHECKING

import gymnasium as gym
import mujoco
import numpy as np

from ipbench.assets.objects import CATEGORIES, ObjectInstance, resting_poses
from ipbench.envs.layout import Layout, PlacedObject
from ipbench.envs.sorting import COMMANDS, workcell_places
from ipbench.eval.capture.hand_factors import (
    check_factor,
    gripper_pixels,
    ideal_view,
    object_pixels,
    view_from_distance,
)
from ipbench.perception.cloud import PerceptionError, depth_to_points
from ipbench.perception.features import fpfh
from ipbench.perception.segmentation import segment_in_hand
from ipbench.perception.viewset import POINTS_PER_VIEW, ViewSet, sample_points
from ipbench.policies import EVAL_CAMERAS
from ipbench.policies.grasping.boxes import ROUND, grasp_point, grasp_yaws, is_short, jaw_span
from ipbench.policies.grasping.free import GRASP_DEPTH
from ipbench.policies.kinematics import HandKinematics

if TYPE_CHECKING:
    from ipbench.eval.capture.dataset import DatasetConfig

__all__ = ["HAND_POSES", "render_in_hand_factors", "render_in_hand_views"]

HAND_POSES: tuple[str, ...] = ("upright", "side")
"""Resting poses an object is picked from (those the standard scenes use)."""
_INSPECT_IN_HAND = COMMANDS.index("inspect_in_hand")


def _seed(config: DatasetConfig, inst: ObjectInstance, pose: str) -> int:
    text = f"{config.seed}/{inst.name}/{pose}"
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:4], "little")


def _layout(inst: ObjectInstance, pose_name: str, yaw: float) -> Layout | None:
    """``inst`` alone at the spawn area's centre, resting in ``pose_name`` turned by ``yaw``
    (rad); None when it cannot rest that way."""
    pose = next((p for p in resting_poses(inst) if p.name == pose_name), None)
    if pose is None:
        return None
    places = workcell_places()
    x, y, _ = places.spawn_area.center
    position = (float(x), float(y), float(places.table_height + pose.height))
    quat = np.empty(4)
    mujoco.mju_mulQuat(quat, [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)], pose.quat)
    placed = PlacedObject(0, inst, pose, position, yaw, tuple(float(v) for v in quat))
    return Layout("in_hand", 0, (placed,))


def render_in_hand_views(
    inst: ObjectInstance,
    config: DatasetConfig,
    point_rng: Callable[[int], np.random.Generator] | None = None,
) -> ViewSet:
    """Up to ``config.in_hand_views`` in-hand views of ``inst`` per grasp: one grasp per pose
    of :data:`HAND_POSES` and each of ``config.in_hand_placements`` yaws on the table (see the
    module docstring), each with a :data:`~ipbench.perception.viewset.POINTS_PER_VIEW` sample
    of its segment's points (view ``v`` drawn by ``point_rng(v)``; None: no points stored);
    with ``config.in_hand_removed`` removed (an
    :class:`~ipbench.eval.capture.dataset.InHandAblationConfig`; a plain config: nothing
    removed)."""
    removed = getattr(config, "in_hand_removed", None)
    return render_in_hand_factors(inst, config, (removed,), point_rng)[removed]


def render_in_hand_factors(
    inst: ObjectInstance,
    config: DatasetConfig,
    factors: tuple[str | None, ...],
    point_rng: Callable[[int], np.random.Generator] | None = None,
) -> dict[str | None, ViewSet]:
    """:func:`render_in_hand_views` for each of ``factors`` (None: every factor as captured,
    else one of :data:`~ipbench.eval.capture.hand_factors.IN_HAND_FACTORS` removed) from one pass of
    grasps and turns: each factor's views are those of the same presentations
    (an ``in_hand_removed`` of ``config`` is ignored)."""
    for factor in factors:
        check_factor(factor)
    found: dict[str | None, list] = {f: [] for f in factors}
    if config.in_hand_views > 0:
        kinematics = HandKinematics()
        env = gym.make(config.env_id, depth_noise=config.sensor, cameras=EVAL_CAMERAS)
        try:
            for pose_name in HAND_POSES:
                for placement in range(config.in_hand_placements):
                    yaw = 2 * np.pi * placement / config.in_hand_placements
                    layout = _layout(inst, pose_name, yaw)
                    if layout is None:
                        break
                    seed = _seed(config, inst, f"{pose_name}/{placement}")
                    _, info = env.reset(seed=seed, options={"layout": layout})
                    obj = info["objects"][0]
                    for views in _capture(env, obj, inst, kinematics, config, factors):
                        for factor, view in views.items():
                            if view is not None and len(view[0]):
                                found[factor].append(view)
        finally:
            env.close()
    label = CATEGORIES.index(inst.category)
    out = {}
    for factor, views in found.items():
        n = len(views)
        samples = None
        if point_rng is not None:
            samples = [
                sample_points(p, POINTS_PER_VIEW, point_rng(v)) for v, (_, p) in enumerate(views)
            ]
        descriptors = [d for d, _ in views]
        out[factor] = ViewSet.from_views(
            descriptors, [label] * n, [inst.name] * n, [inst.known] * n, "in_hand", samples
        )
    return out


def _capture(
    env, obj: dict, inst: ObjectInstance, kinematics, config, factors
) -> list[dict[str | None, tuple[np.ndarray, np.ndarray] | None]]:
    """Pick the object ``obj`` (its ``info["objects"]`` entry) and describe up to
    ``config.in_hand_views`` in-hand views, turning it between them: per presentation, each of
    ``factors``' (FPFH, segment points), None when nothing was segmented."""
    quat = obj["pose"][3:]
    yaw = grasp_yaws(quat, inst.size, round_=inst.category in ROUND)[0]
    yaw = (yaw + np.pi) % (2 * np.pi) - np.pi  # the action space's range
    point = grasp_point(obj["center"], quat, inst.size)
    if is_short(quat, inst.size):  # the pads just under its top, as grasp planning holds it
        point[2] += GRASP_DEPTH  # (the skill goes grasp_depth below the position it is given)
    action = {
        "command": _INSPECT_IN_HAND,
        "position": point.astype(np.float32),
        "yaw": np.array([yaw], np.float32),
        "bin": 0,
        "opening": np.array([jaw_span(quat, inst.size, yaw)], np.float32),
    }
    presentations = []
    for _ in range(config.in_hand_views):
        obs, _, _, _, info = env.step(action)
        if not all(s["success"] for s in info["skills"]):
            break  # dropped, or the wrist cannot turn further
        action["yaw"] = np.array([np.radians(config.in_hand_turn_deg)], np.float32)
        presentations.append({f: _view(env, obs, info, kinematics, config, f) for f in factors})
    return presentations


def _view(
    env, obs: dict, info: dict, kinematics: HandKinematics, config: DatasetConfig, factor
) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`_describe` of the view after a presentation with ``factor`` removed
    (:mod:`ipbench.eval.capture.hand_factors`; None: as captured)."""
    if factor == "true_mask":
        return _describe(obs, kinematics, config, true_mask=info["wrist_mask"])
    if factor == "no_jaws":
        return _describe(obs, kinematics, config, drop=gripper_pixels(env))
    if factor == "ideal_depth":
        return _describe(ideal_view(env, obs), kinematics, config)
    if factor == "table_distance":
        moved = view_from_distance(env, info["objects"][0]["center"], config.distance)
        return None if moved is None else _describe(moved, kinematics, config)
    return _describe(obs, kinematics, config)


def _describe(
    obs: dict,
    kinematics: HandKinematics,
    config: DatasetConfig,
    true_mask: np.ndarray | None = None,
    drop: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray] | None:
    """FPFH descriptors (n, 33) of the object in hand and its segment's (m, 3) points (world,
    m), None when it is not segmented. ``true_mask`` (H, W): take the points of object 0 in
    this ground-truth mask instead of segmenting; ``drop`` (H * W,) bool: remove these pixels'
    points from the cloud before segmenting."""
    q = obs["qpos"]
    try:
        cloud = depth_to_points(obs["wrist_depth"], obs["wrist_K"], obs["wrist_pose"])
        if drop is not None:
            cloud = cloud.subset(~drop[cloud.pixels])
        if true_mask is not None:
            points = object_pixels(cloud, true_mask, 0).points
            if len(points) < config.segmentation.min_points:
                return None
            return fpfh(points, config.features, viewpoint=obs["wrist_pose"][:3, 3]), points
        segment = segment_in_hand(
            cloud, kinematics.tcp_pose(q), kinematics.jaw_opening(q), config=config.segmentation
        )
    except PerceptionError:
        return None
    if segment is None:
        return None
    desc = fpfh(segment.points, config.features, viewpoint=obs["wrist_pose"][:3, 3])
    return desc, segment.points
