"""The oracle: perfect labels, the same manipulation — the manipulation-only ceiling.

It perceives and grasps exactly as GP-IPM does (segments of the current view, one object per
step, scene re-perceived after each), but each segment's label is the ground-truth category
of the object owning most of its pixels (``info["wrist_mask"]``). It is the only policy that
reads ``info``.
"""

from __future__ import annotations

import numpy as np

from ipbench.policies.base import PolicyError, SceneSorter, place_action
from ipbench.policies.perceiver import Detection, Perceiver

__all__ = ["OracleSorter", "true_category"]


def true_category(pixels: np.ndarray, info: dict) -> str | None:
    """Category of the object covering most of ``pixels`` (flat indices) in ``info``'s
    ground-truth mask; None when they are all background."""
    ids = info["wrist_mask"].reshape(-1)[np.asarray(pixels, dtype=np.int64)]
    ids = ids[ids >= 0]
    if ids.size == 0:
        return None
    k = int(np.bincount(ids).argmax())
    return info["objects"][k]["category"]


class OracleSorter(SceneSorter):
    """See the module docstring."""

    def __init__(self, perceiver: Perceiver, name: str = "oracle") -> None:
        super().__init__(perceiver)
        self.name = name

    def act(self, observation: dict, info: dict | None = None) -> dict:
        if info is None:
            raise PolicyError("the oracle needs info (ground truth): call act(observation, info)")
        self._steps += 1
        labelled = []
        for d in self.perceive_scene(observation):
            category = true_category(d.segment.pixels, info)
            if category is not None:
                probs = np.array([float(c == category) for c in d.classes])
                labelled.append(Detection(d.segment, probs, d.classes, d.viewpoint))
        labelled = self.candidates(labelled)
        self.detections = labelled
        best = min(labelled, key=lambda d: (self.patience(d), -len(d.segment.points)))
        self.begin(best)
        target = self.target(best)
        self.grasp(target)
        return place_action(target, best.label)
