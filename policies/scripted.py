"""A scripted sorter that reads ground truth from ``info``: the manipulation-only reference.

It uses only the public contract: each object's ``center`` from ``info["objects"]`` as the
grasp position, its category as the bin, and a jaw yaw across the object's narrower
horizontal side (from its pose and bounding box). It is the demo's policy and the check that
the world and the skills can sort a scene; perception-based policies replace ``info`` by
what the camera sees.
"""

from __future__ import annotations

import numpy as np

from ipbench.assets.objects import CATEGORIES, find_instance
from ipbench.policies.grasping.boxes import (
    ROUND,
    clearest_yaw,
    grasp_point,
    grasp_yaws,
    jaw_span,
)

__all__ = ["GroundTruthSorter"]


class GroundTruthSorter:
    """Puts the objects on the table into their bins, the gripper's side first.

    After a failed grasp it tries the object's next candidate yaw; an object that failed twice
    waits until every other object has had as many tries.
    """

    def __init__(self, jaw_opening: bool = True) -> None:
        self.jaw_opening = jaw_opening
        """Whether actions carry ``opening`` (``Sorting-v1``; v0 has no such key)."""
        self.failures: dict[int, int] = {}
        self._last: int | None = None

    def reset(self, seed: int | None = None) -> None:
        self.failures.clear()
        self._last = None

    def act(self, observation: dict, info: dict) -> dict:
        objects = info["objects"]
        if self._last is not None and objects[self._last]["status"] == "on_table":
            self.failures[self._last] = self.failures.get(self._last, 0) + 1
        todo = {k: o for k, o in objects.items() if o["status"] == "on_table"}
        if not todo:
            raise ValueError("no object left on the table")
        k = min(todo, key=lambda i: (self.failures.get(i, 0) // 2, -todo[i]["center"][1]))
        self._last = k
        obj = todo[k]
        size = find_instance(obj["instance"]).size
        yaws = grasp_yaws(obj["pose"][3:], size, round_=obj["category"] in ROUND)
        others = [o["center"] for i, o in todo.items() if i != k]
        best = clearest_yaw(obj["center"], yaws, others)
        yaw = best + self.failures.get(k, 0) * np.pi / 2 if len(yaws) > 1 else best
        action = {
            "command": 0,
            "position": grasp_point(obj["center"], obj["pose"][3:], size).astype(np.float32),
            "yaw": np.array([(yaw + np.pi) % (2 * np.pi) - np.pi], np.float32),
            "bin": CATEGORIES.index(obj["category"]),
        }
        if self.jaw_opening:
            action["opening"] = np.array([jaw_span(obj["pose"][3:], size, yaw)], np.float32)
        return action
