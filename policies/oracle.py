"""The oracles: perfect labels, the same perception and grasping — the manipulation ceiling.

Both perceive and grasp exactly as GP-IPM does (segments of the current view, merged ones
split, grasps checked against the depth image, one object per step, the scene re-perceived
after each) and are the only policies that read ``info`` (ground truth):

- ``oracle`` (:class:`OracleSorter` with ``held=True``) labels the object it *actually
  holds*: it picks (``Sorting-v2``'s ``pick`` command), reads which object is in hand from
  ``info["objects"]`` and puts it into that object's bin. No perception method can do
  better with the same grasps, so it is the upper bound of perception. Without a ``pick``
  command (v0, v1) it labels as ``oracle-scene`` does.
- ``oracle-scene`` (``held=False``) labels each segment with the true category of the object
  owning most of its pixels (``info["wrist_mask"]``) and picks and places in one step: when
  the jaws take a neighbour, that neighbour goes into the aimed object's bin. The gap
  between the two oracles is what wrong-object grasps cost.
"""

from __future__ import annotations

import numpy as np

from ipbench.envs.sorting import COMMANDS, PICK
from ipbench.policies.base import PolicyError, SceneSorter, place_action
from ipbench.policies.perceiver import Detection, Perceiver

__all__ = ["OracleSorter", "true_category", "true_object"]


def true_object(pixels: np.ndarray, info: dict) -> int | None:
    """Id of the object covering most of ``pixels`` (flat indices) in ``info``'s ground-truth
    mask; None when they are all background."""
    ids = info["wrist_mask"].reshape(-1)[np.asarray(pixels, dtype=np.int64)]
    ids = ids[ids >= 0]
    if ids.size == 0:
        return None
    return int(np.bincount(ids).argmax())


def true_category(pixels: np.ndarray, info: dict) -> str | None:
    """Category of the object covering most of ``pixels`` (flat indices) in ``info``'s
    ground-truth mask; None when they are all background."""
    k = true_object(pixels, info)
    return None if k is None else info["objects"][k]["category"]


class OracleSorter(SceneSorter):
    """See the module docstring; ``commands``: the env's ``action["command"]`` meanings
    (``env.unwrapped.commands``), which say whether it can pick first."""

    def __init__(
        self,
        perceiver: Perceiver,
        name: str = "oracle",
        held: bool = True,
        commands: tuple[str, ...] = COMMANDS,
    ) -> None:
        super().__init__(perceiver)
        self.name = name
        self.held = held and PICK in commands
        self._pick = commands.index(PICK) if self.held else None
        self._target = None

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self._target = None

    def act(self, observation: dict, info: dict | None = None) -> dict:
        if info is None:
            raise PolicyError("the oracle needs info (ground truth): call act(observation, info)")
        if self.held:
            in_hand = [k for k, o in info["objects"].items() if o["status"] == "in_hand"]
            picked = any(r["name"] == "pick" and r["success"] for r in info["skills"])
            if self._target is not None and picked:
                # place what the jaws really took (if info names none: the aimed label)
                decision = self.decisions[-1]
                if in_hand:
                    decision.label = info["objects"][in_hand[0]]["category"]
                category = decision.label
                self._last_target = None  # the grasp worked
                target, self._target = self._target, None
                return place_action(target, category)
        self._target = None
        self._steps += 1
        labelled = []
        for d in self.perceive_scene(observation, classify=False):
            category = true_category(d.segment.pixels, info)
            if category is not None:
                probs = np.array([float(c == category) for c in d.classes])
                labelled.append(Detection(d.segment, probs, d.classes, d.viewpoint))
        labelled = self.candidates(labelled)
        self.detections = labelled
        best = min(
            labelled, key=lambda d: (self.patience(d), *self.access(d), -len(d.segment.points))
        )
        self.begin(best)
        target = self.target(best)
        self.grasp(target)
        if self.held:
            self._target = target
            return place_action(target, best.label, self._pick)
        return place_action(target, best.label)
