"""Grasps of an object whose pose and bounding box are known: yaws, grasp point, jaw opening.

The ground-truth sorter (:mod:`ipbench.policies.scripted`) and the in-hand views' capture
rig know each object's pose and bounding box; these
functions turn them into a top-down parallel-jaw grasp: the jaw yaws that close across the
object (:func:`grasp_yaws`), the one that keeps farthest from its neighbours
(:func:`clearest_yaw`), where to grasp (:func:`grasp_point`: a short object just under its
top) and how far to open the jaws (:func:`jaw_span`). The rules for short objects
(:data:`SHORT`, :data:`TOP_MARGIN`) and the jaw opening across a box (:func:`opening_across`,
:data:`OPENING_MARGIN`) are those of the perceived segments' grasps too
(:mod:`ipbench.policies.grasping.segments`).
"""

from __future__ import annotations

import mujoco
import numpy as np

from ipbench.envs.sorting import MAX_JAW_OPENING

__all__ = [
    "JAW_REACH",
    "OPENING_MARGIN",
    "ROUND",
    "SHORT",
    "TOP_MARGIN",
    "clearest_yaw",
    "grasp_point",
    "grasp_yaws",
    "is_short",
    "jaw_span",
    "opening_across",
]

ROUND = frozenset({"juice_bottle", "bowl", "mug"})
"""Categories with a round body (any jaw yaw closes across it)."""
JAW_REACH = 0.13
"""Half-span of the open jaws including the fingers (m): neighbours inside it get hit."""


def grasp_yaws(quat: np.ndarray, size: tuple[float, float, float], round_: bool) -> list[float]:
    """Candidate jaw yaws (rad) that close across an object.

    ``quat`` (4,) is the object's world orientation (w, x, y, z), ``size`` its (x, y, z)
    bounding box in its own frame (m). Upright: across the smaller of x and y (either side of
    a square), any yaw for a round body; lying: across the object's long (z) axis.
    """
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, np.asarray(quat, float))
    rot = rot.reshape(3, 3)
    if abs(rot[2, 2]) <= 0.7:
        axis = np.array([-rot[1, 2], rot[0, 2], 0.0])
        return [float(np.arctan2(axis[1], axis[0]))]
    base = float(np.arctan2(rot[1, 0], rot[0, 0]))
    if round_:
        return [base + a for a in np.linspace(0, np.pi, 12, endpoint=False)]
    if abs(size[0] - size[1]) < 0.01:
        return [base, base + np.pi / 2]
    return [base if size[0] <= size[1] else base + np.pi / 2]


def clearest_yaw(center: np.ndarray, yaws: list[float], neighbours: list[np.ndarray]) -> float:
    """The yaw whose jaw line keeps farthest from the neighbouring objects' centres."""

    def clearance(yaw: float) -> float:
        u = np.array([np.cos(yaw), np.sin(yaw)])
        worst = np.inf
        for n in neighbours:
            d = np.asarray(n[:2]) - np.asarray(center[:2])
            along, across = abs(d @ u), abs(d[0] * u[1] - d[1] * u[0])
            # distance from the swept jaw segment [-JAW_REACH, JAW_REACH] along u
            worst = min(worst, float(np.hypot(max(along - JAW_REACH, 0.0), across)))
        return worst

    return max(yaws, key=clearance)


OPENING_MARGIN = 0.05
"""Clearance added to an object's width across the jaws when pre-shaping the gripper (m):
2.5 cm a side covers depth noise in a segment's extent and a centring error."""
SHORT = 0.15
"""Objects whose top is lower than this above their base (m) are grasped near the top."""
TOP_MARGIN = 0.025
"""How far below the top short objects are grasped (m): a bowl by its rim, not its slope."""


def _half_height(quat: np.ndarray, size: tuple[float, float, float]) -> float:
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, np.asarray(quat, float))
    return 0.5 * float(np.abs(rot.reshape(3, 3)[2]) @ np.asarray(size))


def is_short(quat: np.ndarray, size: tuple[float, float, float]) -> bool:
    """Whether an object of ``size`` (3,) (its own frame, m) turned by ``quat`` stands lower
    than :data:`SHORT` (its top is where it is grasped)."""
    return 2 * _half_height(quat, size) < SHORT


def grasp_point(
    center: np.ndarray, quat: np.ndarray, size: tuple[float, float, float]
) -> np.ndarray:
    """Where to grasp (3,): the bounding-box centre, lowered to just under the top for short
    objects (the jaws close on a bowl's rim rather than wedging its conical wall upwards)."""
    point = np.array(center, float)
    half_height = _half_height(quat, size)
    if 2 * half_height < SHORT:
        point[2] += half_height - TOP_MARGIN
    return point


def jaw_span(quat: np.ndarray, size: tuple[float, float, float], yaw: float) -> float:
    """Jaw opening (m) for closing along ``yaw`` on an object of bounding box ``size`` (its own
    frame, m) turned by ``quat``: see :func:`opening_across`."""
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, np.asarray(quat, float))
    return opening_across(rot.reshape(3, 3)[:2], size, yaw)


def opening_across(axes: np.ndarray, extent, yaw: float) -> float:
    """Jaw opening (m) for closing along ``yaw`` on a box with side lengths ``extent`` (k,)
    along axes whose horizontal parts are the columns of ``axes`` (2, k): the box's width
    along the closing direction plus :data:`OPENING_MARGIN`, at most the full opening."""
    closing = np.array([np.cos(yaw), np.sin(yaw)])
    width = float(np.abs(closing @ np.asarray(axes, float)) @ np.asarray(extent, float))
    return float(min(width + OPENING_MARGIN, MAX_JAW_OPENING))
