"""Random sorting, the thesis' baseline (Table 5.1).

One-shot perception of the scene, then the objects are removed in random order, each into the
bin of its predicted class; confidence is not used. An object whose grasp the depth image
shows to be blocked waits for the free ones of its round (the grasp planning every policy
shares, :mod:`ipbench.policies.grasping.free`). When every object of that view has had
its turn and some remain (failed grasps, merged segments), the scene is perceived again — a new
one-shot view — and the next round starts.
"""

from __future__ import annotations

import numpy as np

from ipbench.policies.base import SceneSorter, place_action
from ipbench.policies.perceiver import Detection, Perceiver

__all__ = ["RandomSorter"]


class RandomSorter(SceneSorter):
    """See the module docstring. ``reset(seed)`` seeds the order."""

    def __init__(self, perceiver: Perceiver, name: str = "random") -> None:
        super().__init__(perceiver)
        self.name = name
        self._queue: list[Detection] = []
        self._rng = np.random.default_rng()

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self._queue = []
        self._rng = np.random.default_rng(seed)

    def act(self, observation: dict, info: dict | None = None) -> dict:
        self._steps += 1
        if not self._queue:
            detections = self.candidates(self.perceive_scene(observation))
            self._queue = [detections[i] for i in self._rng.permutation(len(detections))]
        else:
            self._last_target = None  # one-shot: no new view to check the last grasp with
        # an object whose grasp the depth image shows blocked waits for the free ones
        # (its view's grasps are checked against that view's segments)
        free = [k for k, d in enumerate(self._queue) if self.target(d).free]
        chosen = self._queue.pop(free[0] if free else 0)
        self.begin(chosen)
        target = self.target(chosen)
        self.grasp(target)
        return place_action(target, chosen.label)
