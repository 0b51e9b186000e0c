"""GP-IPM, the thesis' interactive perception and manipulation loop (ch. 5 Alg. 1, ch. 6).

Each step: perceive the table; take the most confident object (among those whose grasp the
depth image shows to be free, if any: the others wait, see
:meth:`~ipbench.policies.base.SceneSorter.access`); if its confidence reaches the
threshold, put it into the bin of its predicted class; otherwise *inspect* it — in the hand
(presented to the wrist camera) or in the inspection area — turning it by ``turn_deg`` between
views until ``n_views`` views are classified, fuse them (:mod:`ipbench.policies.fusion`) and
put it into the bin of the fused class (in-hand views are classified by the perceiver's
in-hand model). The scene is perceived again after every removal.
With an SVM model instead of the GP this is SVM-IPM; the loop does not change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ipbench.policies.base import (
    Decision,
    PolicyError,
    SceneSorter,
    place_action,
)
from ipbench.policies.fusion import FUSIONS, fuse
from ipbench.policies.grasping.segments import GraspTarget, grasp_target
from ipbench.policies.perceiver import Detection, Perceiver

__all__ = ["INSPECTIONS", "InteractiveConfig", "InteractiveSorter"]

INSPECTIONS: dict[str, int] = {"hand": 2, "area": 1}
"""Inspection mode -> the env's command (``inspect_in_hand``, ``inspect_in_area``)."""
_EMPTY_HAND = 0.004  # m; jaws closer than this hold nothing


@dataclass(frozen=True)
class InteractiveConfig:
    """Settings of :class:`InteractiveSorter`.

    Attributes
    ----------
    threshold : confidence at or above which an object is sorted without inspection (0: never
        inspect, 1: inspect everything short of certainty).
    inspection : ``"hand"`` or ``"area"``.
    n_views : inspection views fused per object (thesis: at least 3).
    turn_deg : rotation between inspection views (deg; thesis: 30).
    fusion : ``"majority"`` (thesis) or ``"bayes"``.
    max_view_attempts : inspection steps per object before it is sorted with what is known.
    """

    threshold: float = 0.5
    inspection: str = "hand"
    n_views: int = 3
    turn_deg: float = 30.0
    fusion: str = "majority"
    max_view_attempts: int = 5

    def __post_init__(self) -> None:
        if not 0.0 <= self.threshold <= 1.0:
            raise PolicyError(f"threshold must be in [0, 1], got {self.threshold!r}")
        if self.inspection not in INSPECTIONS:
            raise PolicyError(f"inspection {self.inspection!r}; valid: {', '.join(INSPECTIONS)}")
        if self.fusion not in FUSIONS:
            raise PolicyError(f"fusion {self.fusion!r}; valid: {', '.join(FUSIONS)}")
        if self.n_views < 1 or self.max_view_attempts < self.n_views:
            raise PolicyError("need n_views >= 1 and max_view_attempts >= n_views")


@dataclass
class _Inspection:
    decision: Decision
    target: GraspTarget
    views: list[np.ndarray]
    labels: list[str]
    attempts: int = 0


def _area_grasp(detection) -> GraspTarget:
    """The grasp of the object the area view shows, where it lies now. The env re-picks an
    object it set down in the area by itself (``position`` ignored), but after a failed
    re-pick it grasps at ``position``: aiming there, not at the object's old place on the
    table, keeps a neighbour that moved into that place from being taken instead."""
    return grasp_target(detection.segment, np.zeros((0, 3)), 0, detection.viewpoint)


class InteractiveSorter(SceneSorter):
    """GP-IPM (or SVM-IPM, with an SVM model); see the module docstring."""

    def __init__(
        self, perceiver: Perceiver, config: InteractiveConfig = InteractiveConfig(), name="gp-ipm"
    ) -> None:
        super().__init__(perceiver)
        self.config = config
        self.name = name
        self._inspection: _Inspection | None = None
        self._info: dict | None = None

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self._inspection = None

    def inspects(self, detection: Detection, info: dict | None) -> bool:
        """Whether ``detection`` (the object just chosen) is inspected: its confidence is below
        the threshold (at threshold 1, every object is)."""
        return self.config.threshold >= 1.0 or detection.confidence < self.config.threshold

    def act(self, observation: dict, info: dict | None = None) -> dict:
        self._steps += 1
        self._info = info
        if self._inspection is not None:
            return self._continue_inspection(observation)
        detections = self.candidates(self.perceive_scene(observation))
        best = min(
            detections,
            key=lambda d: (self.patience(d), self.access(d)[0], -d.confidence, self.access(d)[1]),
        )
        decision = self.begin(best)
        target = self.target(best)
        self.grasp(target)
        if not self.inspects(best, info):
            return place_action(target, best.label)
        decision.kind = "inspect"
        self._inspection = _Inspection(decision, target, [], [])
        return place_action(target, best.label, INSPECTIONS[self.config.inspection])

    def _view(self, observation: dict):
        if self.config.inspection == "hand":
            q = observation["qpos"]
            if self.perceiver.kinematics.jaw_opening(q) < _EMPTY_HAND:
                return None, False  # the grasp failed or the object slipped out
            return self.perceiver.in_hand(observation), True
        return self.perceiver.in_area(observation), True

    def _continue_inspection(self, observation: dict) -> dict:
        ins = self._inspection
        ins.attempts += 1
        detection, holding = self._view(observation)
        if not holding:  # nothing in hand: the observation shows the table again
            self._inspection = None
            self._steps -= 1
            return self.act(observation, self._info)
        self._last_target = None  # the grasp worked
        self.detections = [detection] if detection is not None else []
        if detection is not None:
            ins.views.append(detection.probs)
            ins.labels.append(detection.label)
            if self.config.inspection == "area":
                ins.target = _area_grasp(detection)
        if len(ins.views) < self.config.n_views and ins.attempts < self.config.max_view_attempts:
            turn = math.radians(self.config.turn_deg)
            if self.config.inspection == "area":  # the jaws as planned on the area view
                turn_target = GraspTarget(ins.target.position, turn, ins.target.opening)
            else:  # held: position and opening are ignored
                turn_target = GraspTarget(ins.target.position, turn)
            return place_action(
                turn_target, ins.decision.first_label, INSPECTIONS[self.config.inspection]
            )
        d = ins.decision
        if ins.views:
            k, conf = fuse(np.array(ins.views), self.config.fusion)
            d.label, d.confidence = self.perceiver.classes[k], conf
        d.views, d.view_labels = len(ins.views), tuple(ins.labels)
        self._inspection = None
        return place_action(ins.target, d.label)
