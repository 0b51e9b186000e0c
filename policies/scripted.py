"""A scripted sorter that reads ground truth from ``info``: the manipulation-only reference.

It uses only the public contract: each object's ``center`` from ``info["objects"]`` as the
grasp position, its category as the bin, and a jaw yaw across the object's narrower
horizontal side (from its pose and bounding box). It is the demo's policy and the check that
the world and the skills can sort a scene; perception-based policies replace ``info`` by
what the camera sees.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ipbench.assets.objects import CATEGORIES, get_instance

__all__ = ["GroundTruthSorter", "grasp_yaws", "clearest_yaw", "ROUND"]

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


class GroundTruthSorter:
    """Puts the objects on the table into their bins, nearest to the gripper's side first."""

    def reset(self, seed: int | None = None) -> None:
        pass

    def act(self, observation: dict, info: dict) -> dict:
        todo = {k: o for k, o in info["objects"].items() if o["status"] == "on_table"}
        if not todo:
            raise ValueError("no object left on the table")
        k = max(todo, key=lambda i: todo[i]["center"][1])  # left (gripper side) first
        obj = todo[k]
        size = get_instance(obj["category"], int(obj["instance"].rsplit("_", 1)[1])).size
        yaws = grasp_yaws(obj["pose"][3:], size, round_=obj["category"] in ROUND)
        others = [o["center"] for i, o in todo.items() if i != k]
        yaw = clearest_yaw(obj["center"], yaws, others)
        return {
            "command": 0,
            "position": np.asarray(obj["center"], np.float32),
            "yaw": np.array([(yaw + np.pi) % (2 * np.pi) - np.pi], np.float32),
            "bin": CATEGORIES.index(obj["category"]),
        }
