"""Seeded table scenes of ``ipbench/Exploration-v0`` (thesis ch. 3: find known objects).

Classes are specific textured products, as in the thesis' recognition database:
:data:`DATABASE_CLASSES` names ten v2 catalogue instances (``"<category>/<index>"``) whose
printed labels and carton/box prints tell them apart (cartons, juice boxes, PET bottles with
labels; distinct textures, tested). A scene holds, on the front work table:

* database objects: ``n_classes`` distinct classes, ``n_duplicates`` of them present twice (the
  thesis' "multiple same-class object instances");
* distractors: other textured v2 instances (any category) that are not in the database;
* background clutter: a few upright 1 L briks and 2 L cartons (not in the database) in a strip
  at the back of the table, and posters on the lab's walls (:mod:`ipbench.assets.room`: the
  room's walls at their documented places, A1/A2 adverts at gallery height).

Levels (:data:`LEVELS`) follow the thesis' three: ``simple`` (5 objects on the table),
``medium`` (9) and ``complex`` (14), plus background objects (2, 3, 4) and wall posters
(2, 4, 6; the posters are drawn from a stream of their own, so they leave the objects' layout
of a seed as it was). Poses (upright or lying, yaw, position,
with non-overlapping bounding circles) and the head's start gaze (both PTUs aimed at a point
drawn on the table) come from the seed: the same seed gives the same scene.

The objects are **static**: nothing touches them in this task, so the environment adds them
without a free joint (welded to the world); the physics only moves the head.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import mujoco
import numpy as np

from ipbench.assets.compose import HEAD_SIDES, build_workcell_spec, head_gaze
from ipbench.assets.objects import (
    ObjectInstance,
    add_object,
    get_instance,
    instances,
    resting_poses,
)
from ipbench.assets.objects.object_model import RELEASED_MODEL, ObjectModel
from ipbench.assets.room import Poster, add_room, layout_posters
from ipbench.envs.cell.model_errors import ModelErrors, apply_model_errors
from ipbench.envs.ptu import ptu_spec

__all__ = [
    "BACK_STRIP",
    "DATABASE_CLASSES",
    "FRONT_AREA",
    "LEVELS",
    "SceneError",
    "SceneLevel",
    "SceneObject",
    "ExplorationScene",
    "GAZE_JOINTS",
    "aim_head",
    "build_model",
    "database_instance",
    "sample_scene",
    "table_height",
    "table_top",
]

DATABASE_CLASSES: tuple[str, ...] = (
    "juice_bottle/0",
    "juice_bottle/4",
    "juice_bottle/10",
    "milk_carton/1",
    "milk_carton/11",
    "milk_carton/17",
    "juice_box/2",
    "juice_box/12",
    "juice_box/19",
    "juice_box/26",
)
"""The recognition database: v2 instances ``"<category>/<index>"`` (fixed; an action's report
``label`` indexes this tuple)."""

GAZE_JOINTS: tuple[str, ...] = tuple(f"head_{s}_{a}" for s in HEAD_SIDES for a in ("pan", "tilt"))
"""The head joints (and position actuators) of a gaze (4,), in order."""
FRONT_AREA = ((0.58, 1.17), (-0.55, 0.35))
"""(x range, y range) of the objects' footprints on the front work table (world, m; the
table top spans x 0.55-1.35, y -0.6-0.4, ``work_table_top`` in ``workcell.xml``)."""
BACK_STRIP = ((1.19, 1.345), (-0.55, 0.35))
"""(x range, y range) of the background clutter at the back of the table (world, m)."""
_GAP = 0.01  # free space between two objects' bounding circles (m)
_TRIES = 400  # placement tries per object before the whole scene is drawn again
_ATTEMPTS = 50  # whole-scene attempts per seed
_BACK_YAW = 0.3  # background objects face the head, yaw within +-0.3 rad
_GAZE_AREA = ((0.75, 1.05), (-0.30, 0.10))  # where the start gaze's target is drawn (m)


class SceneError(ValueError):
    """An unknown level or a scene that cannot be laid out."""


@dataclass(frozen=True)
class SceneLevel:
    """A level's composition: distinct database classes, how many of them appear twice,
    distractors, background objects, and the fraction of objects lying on their side."""

    name: str
    n_classes: int
    n_duplicates: int
    n_distractors: int
    n_background: int
    lying_fraction: float
    n_posters: int = 0

    @property
    def n_table(self) -> int:
        """Objects on the front table (database objects and distractors)."""
        return self.n_classes + self.n_duplicates + self.n_distractors


LEVELS: dict[str, SceneLevel] = {
    "simple": SceneLevel("simple", 3, 1, 1, 2, 0.0, 2),
    "medium": SceneLevel("medium", 5, 2, 2, 3, 0.2, 4),
    "complex": SceneLevel("complex", 7, 3, 4, 4, 0.2, 6),
}
"""The three levels (thesis ch. 3: simple, medium and complex scenes)."""


@dataclass(frozen=True)
class SceneObject:
    """One placed object.

    Attributes
    ----------
    name : body name ``object_<k:02d>``.
    instance : the v2 catalogue instance.
    label : its :data:`DATABASE_CLASSES` name, ``None`` for distractors and background.
    role : ``"database"``, ``"distractor"`` or ``"background"``.
    resting : resting pose name (``"upright"``, ``"side"``, ...).
    position : (3,) world position of the object frame (m), resting on the table.
    quat : (4,) world orientation (w, x, y, z).
    """

    name: str
    instance: ObjectInstance
    label: str | None
    role: str
    resting: str
    position: tuple[float, float, float]
    quat: tuple[float, float, float, float]


@dataclass(frozen=True)
class ExplorationScene:
    """A seeded scene: its objects, the head's start gaze ``home_gaze`` (4,) rad
    (left pan, left tilt, right pan, right tilt; on the PTU step grid), aimed at
    ``home_target`` (3,) world m, and the posters on the walls."""

    level: str
    seed: int
    objects: tuple[SceneObject, ...]
    home_gaze: tuple[float, float, float, float]
    home_target: tuple[float, float, float]
    posters: tuple[Poster, ...] = ()


def database_instance(label: str) -> ObjectInstance:
    """The v2 instance of a :data:`DATABASE_CLASSES` name."""
    if label not in DATABASE_CLASSES:
        raise SceneError(f"unknown class {label!r}; valid: {', '.join(DATABASE_CLASSES)}")
    category, index = label.split("/")
    return get_instance(category, int(index), "v2")


@cache
def _pools() -> tuple[tuple[ObjectInstance, ...], tuple[ObjectInstance, ...]]:
    """(distractor pool, background pool): v2 instances not in the database."""
    taken = {database_instance(c).name for c in DATABASE_CLASSES}
    back = tuple(
        i
        for i in instances(catalog="v2")
        if i.family in ("brik_1l", "gable_2l") and i.name not in taken
    )
    front = tuple(i for i in instances(catalog="v2") if i.name not in taken and i not in set(back))
    return front, back


@cache
def _model() -> mujoco.MjModel:
    """The empty work cell (for the table height and the head's kinematics)."""
    return build_workcell_spec().compile()


@cache
def table_top() -> tuple[np.ndarray, np.ndarray]:
    """The work table's top: (centre (3,), half extents (3,)) in the world, m (the cell's
    model, site ``work_table_top``)."""
    model = _model()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    return data.site("work_table_top").xpos.copy(), model.site("work_table_top").size.copy()


def table_height() -> float:
    """Height of the work table's top in the world, m (the cell's model)."""
    return float(table_top()[0][2])


def _circle(inst: ObjectInstance, quat) -> tuple[np.ndarray, float]:
    """(offset (2,) of the footprint's centre from the object origin; radius of the circle
    around the footprint) m, in resting orientation ``quat`` before any yaw (the radius does
    not change with yaw). Round bowls: the rim's circle; others: the footprint rectangle's."""
    half = 0.5 * np.asarray(inst.size)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, np.asarray(quat, float))
    xy = ((np.asarray(inst.center) + signs * half) @ rot.reshape(3, 3).T)[:, :2]
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    h = 0.5 * (hi - lo)
    return 0.5 * (lo + hi), float(h.max() if inst.category == "bowl" else np.hypot(*h))


def _place(picks, rng, area, lying: float, height: float, yaw_range: float = math.pi):
    """Place ``picks`` [(instance, label, role)] in ``area`` without overlap, yaw drawn in
    +-``yaw_range``; None on failure. A circle wider than the area is centred in it."""
    (x0, x1), (y0, y1) = area
    placed, circles = [], []
    can_lie = [k for k, p in enumerate(picks) if len(resting_poses(p[0])) > 1 and lying > 0]
    n_lie = int(round(lying * len(can_lie)))
    lie = set(rng.permutation(can_lie)[:n_lie].tolist()) if can_lie else set()
    for k, (inst, label, role) in enumerate(picks):
        poses = resting_poses(inst)
        pose = poses[1] if k in lie else poses[0]  # lying: "side" (bowls: upside down)
        off0, r = _circle(inst, pose.quat)
        for _ in range(_TRIES):
            yaw = float(rng.uniform(-yaw_range, yaw_range))
            qyaw = np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
            quat = np.empty(4)
            mujoco.mju_mulQuat(quat, qyaw, np.asarray(pose.quat, float))
            cy, sy = math.cos(yaw), math.sin(yaw)
            offset = np.array([[cy, -sy], [sy, cy]]) @ off0
            lo, hi = np.array([x0, y0]) + r, np.array([x1, y1]) - r
            c = rng.uniform(np.minimum(lo, (lo + hi) / 2), np.maximum(hi, (lo + hi) / 2))
            if all(np.hypot(*(c - q)) >= r + s + _GAP for q, s in circles):
                break
        else:
            return None
        circles.append((c, r))
        xy = c - offset
        placed.append((inst, label, role, pose.name, (*xy.tolist(), height + pose.height), quat))
    return placed


def aim_head(target, iterations: int = 3) -> np.ndarray:
    """(4,) gaze (left pan, left tilt, right pan, right tilt) rad, on the PTU step grid, that
    points both head cameras' optical axes at ``target`` (3,) world m (refined by forward
    kinematics of the work cell at home, as ``ipbench.envs.world`` aims the home gaze)."""
    model, spec = _model(), ptu_spec()
    data = mujoco.MjData(model)
    target = np.asarray(target, float)
    adr = {
        s: [model.jnt_qposadr[model.joint(f"head_{s}_{j}").id] for j in ("pan", "tilt")]
        for s in HEAD_SIDES
    }
    for k in range(iterations + 1):
        mujoco.mj_forward(model, data)
        for s in HEAD_SIDES:
            base = model.body_parentid[model.body(f"head_{s}_pan_link").id]
            rot = data.xmat[base].reshape(3, 3)
            if k == 0:
                pan, tilt = head_gaze(data.xpos[base], rot, target)
            else:
                cam = data.cam(f"head_{s}_camera")
                now = head_gaze(np.zeros(3), rot, -cam.xmat.reshape(3, 3)[:, 2])
                want = head_gaze(cam.xpos, rot, target)
                pan = data.qpos[adr[s][0]] + want[0] - now[0]
                tilt = data.qpos[adr[s][1]] + want[1] - now[1]
            data.qpos[adr[s]] = spec.command(np.clip([pan, tilt], spec.lower, spec.upper))
    return np.concatenate([data.qpos[adr[s]] for s in HEAD_SIDES])


def sample_scene(level: str, seed: int) -> ExplorationScene:
    """The scene of ``level`` (a key of :data:`LEVELS`) for ``seed`` (deterministic)."""
    if level not in LEVELS:
        raise SceneError(f"unknown scene level {level!r}; valid: {', '.join(LEVELS)}")
    cfg = LEVELS[level]
    rng = np.random.default_rng([int(seed), 2018, 3])
    front, back = _pools()
    height = table_height()
    for _ in range(_ATTEMPTS):
        classes = [DATABASE_CLASSES[i] for i in rng.permutation(len(DATABASE_CLASSES))]
        classes = classes[: cfg.n_classes]
        twice = classes[: cfg.n_duplicates]
        picks = [(database_instance(c), c, "database") for c in classes + twice]
        picks += [(front[i], None, "distractor") for i in rng.permutation(len(front))]
        picks = picks[: cfg.n_table]
        order = rng.permutation(len(picks))
        table = _place([picks[k] for k in order], rng, FRONT_AREA, cfg.lying_fraction, height)
        bg = [(back[i], None, "background") for i in rng.permutation(len(back))]
        strip = _place(bg[: cfg.n_background], rng, BACK_STRIP, 0.0, height, _BACK_YAW)
        if table is not None and strip is not None:
            break
    else:
        raise SceneError(f"could not lay out level {level!r} for seed {seed}; reduce its counts")
    objects = tuple(
        SceneObject(f"object_{k:02d}", inst, label, role, rest, tuple(map(float, pos)), quat)
        for k, (inst, label, role, rest, pos, quat) in enumerate(
            (*p[:5], tuple(float(v) for v in p[5])) for p in table + strip
        )
    )
    (gx0, gx1), (gy0, gy1) = _GAZE_AREA
    target = np.array([rng.uniform(gx0, gx1), rng.uniform(gy0, gy1), height])
    gaze = aim_head(target)
    posters = layout_posters(np.random.default_rng([int(seed), 2018, 4]), cfg.n_posters)
    return ExplorationScene(
        level, int(seed), objects, tuple(map(float, gaze)), tuple(map(float, target)), posters
    )


def build_model(
    scene: ExplorationScene,
    errors: ModelErrors | None = None,
    objects: ObjectModel = RELEASED_MODEL,
) -> mujoco.MjModel:
    """The work cell in its room with the scene's objects welded to the world (no free joint)
    and its posters, keyframe ``home``: arms at zero, the head at the scene's start gaze,
    every servo holding it. With ``errors``, the TRUE cell: the work cell's spec with
    :func:`~ipbench.envs.cell.model_errors.apply_model_errors` before the room and objects.
    ``objects``: how the objects are modelled (e.g. their print orientation)."""
    spec = build_workcell_spec()
    if errors is not None:
        apply_model_errors(spec, errors)
    add_room(spec, scene.posters)
    for obj in scene.objects:
        body = add_object(
            spec, obj.instance, obj.name, pos=obj.position, quat=obj.quat, model=objects
        )
        for joint in list(body.joints):  # static: nothing touches them in this task
            spec.delete(joint)
    spec.add_key(name="home")
    model = spec.compile()
    key = model.key("home").id
    for j, q in zip(GAZE_JOINTS, scene.home_gaze, strict=True):
        model.key_qpos[key, model.jnt_qposadr[model.joint(j).id]] = q
    for a in range(model.nu):
        model.key_ctrl[key, a] = model.key_qpos[key, model.jnt_qposadr[model.actuator_trnid[a, 0]]]
    return model
