"""A sorting policy of your own: the largest object first, into the bin of its label.

Run it beside random sorting (from the repository's root folder)::

    ipbench eval sorting --policies random,examples.my_policy:LargestFirst --seeds 0:5

The evaluation builds the policy as ``LargestFirst(perceiver, name)`` once per episode, calls
``reset(seed)``, then ``act(observation, None)`` until the episode ends, and reads
``decisions`` after every step (the protocol: ``docs/custom.md``). Subclassing
:class:`~ipbench.policies.base.SceneSorter` gives ``reset``, ``decisions`` and ``detections``,
and the helpers every built-in policy uses: perceive the table, skip objects given up after
failed grasps, plan a grasp checked against the neighbours, and log a decision.
"""

from __future__ import annotations

from ipbench.policies.base import SceneSorter, place_action
from ipbench.policies.perceiver import Perceiver

__all__ = ["LargestFirst"]


class LargestFirst(SceneSorter):
    """Each step: perceive the table, take the object seen with the most points (among those
    whose grasp is free, if any), put it into the bin of the classifier's label. No
    inspection, no confidence threshold."""

    def __init__(self, perceiver: Perceiver, name: str = "largest-first") -> None:
        super().__init__(perceiver)  # sets detections and decisions
        self.name = name

    def act(self, observation: dict, info: dict | None = None) -> dict:
        self._steps += 1
        # the segments on the table with their class probabilities; NothingToSort when none
        # is left, which ends the episode
        detections = self.candidates(self.perceive_scene(observation))
        chosen = min(
            detections,
            # objects that failed twice wait; blocked grasps wait; then the largest
            key=lambda d: (self.patience(d), self.access(d)[0], -len(d.points)),
        )
        self.begin(chosen)  # logs the decision (label and confidence of this view)
        target = self.target(chosen)  # where the jaws go, in the world frame (m, rad)
        self.grasp(target)  # remembered: a segment still there next step is a failed grasp
        return place_action(target, chosen.label)  # command 0: into the bin of the label
