"""What every sorting policy shares: the interface, the decision log, and scene handling.

A policy is used on ``gymnasium.make("ipbench/Sorting-v1")`` episodes::

    policy.reset(seed)
    obs, info = env.reset(seed=seed)
    while not done:
        obs, reward, terminated, truncated, info = env.step(policy.act(obs))

``act(observation, info=None)`` returns an action of the env's action space. Perception-based
policies read only the observation; the oracle alone reads ``info`` (ground truth), which is
why the argument exists. Every policy keeps ``detections`` (what it currently sees, for the
videos' semantic overlay) and ``decisions`` (one :class:`Decision` per object selection —
an object whose grasp failed is selected again — for the evaluation).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from ipbench.assets.objects import CATEGORIES
from ipbench.policies.grasping.segments import FailureMemory, GraspTarget, grasp_target
from ipbench.policies.perceiver import Detection, Perceiver

__all__ = ["Decision", "NothingToSort", "Policy", "PolicyError", "SceneSorter", "place_action"]


class PolicyError(ValueError):
    """Bad policy name or settings; the message lists the valid options."""


class NothingToSort(RuntimeError):
    """Raised by ``act`` when the policy sees nothing it could act on (e.g. the remaining
    objects are out of view); the evaluation ends the episode there."""


@runtime_checkable
class Policy(Protocol):
    """The interface of every sorting policy."""

    name: str
    detections: list[Detection]
    decisions: list[Decision]

    def reset(self, seed: int | None = None) -> None: ...

    def act(self, observation: dict, info: dict | None = None) -> dict: ...


@dataclass
class Decision:
    """How one object was sorted (filled in as the policy goes).

    ``first_*``: the scene view that selected it; ``label``/``confidence``: what decided its
    bin (after fusing ``views`` inspection views, or the first view when ``views == 0``);
    ``pixels``: the selecting segment's flat pixel indices in that observation (the evaluation
    maps them to the ground truth); ``kind``: ``"place"`` or ``"inspect"``; ``free_grasp``: the
    depth image showed its grasp to be free (False: taken although blocked, nothing free was
    left).
    """

    step: int
    first_label: str
    first_confidence: float
    pixels: np.ndarray
    kind: str = "place"
    label: str = ""
    confidence: float = float("nan")
    views: int = 0
    view_labels: tuple[str, ...] = ()
    true_category: str | None = None
    free_grasp: bool = True

    def record(self) -> dict:
        """JSON-ready fields (no pixels)."""
        return {
            "step": self.step,
            "kind": self.kind,
            "label": self.label,
            "confidence": round(self.confidence, 4),
            "first_label": self.first_label,
            "first_confidence": round(self.first_confidence, 4),
            "views": self.views,
            "view_labels": list(self.view_labels),
            "true_category": self.true_category,
            "free_grasp": self.free_grasp,
        }


def place_action(target: GraspTarget, label: str, command: int = 0) -> dict:
    """The env action that takes the object at ``target`` (``command`` 0 = into the bin of
    ``label``, 1 = to the inspection area, 2 = into the hand for inspection)."""
    return {
        "command": int(command),
        "position": target.position.astype(np.float32),
        "yaw": np.array([target.yaw], np.float32),
        "bin": CATEGORIES.index(label),
        "opening": np.array([target.opening], np.float32),
    }


class SceneSorter:
    """Shared scene handling: perceive, remember failed grasps, aim grasps (checked against
    the other segments of the view, :meth:`target`; blocked ones wait, :meth:`access`).

    After an action that should have removed the object at ``position``, a segment still
    there in the next scene view counts as a failed grasp; the next attempt there turns the
    jaws by 90°, and a place that failed twice waits until the others had as many tries. After
    ``max_attempts`` failures at one place the object there is given up (left on the table).
    """

    name = "scene-sorter"
    max_attempts = 6

    def __init__(self, perceiver: Perceiver) -> None:
        self.perceiver = perceiver
        self.failures = FailureMemory(radius=0.04)
        self.detections: list[Detection] = []
        self.decisions: list[Decision] = []
        self._steps = 0
        self._last_target: GraspTarget | None = None
        self._targets: dict[int, GraspTarget] = {}

    def reset(self, seed: int | None = None) -> None:
        self.failures.clear()
        self.detections = []
        self.decisions = []
        self._steps = 0
        self._last_target = None
        self._targets = {}

    def perceive_scene(self, observation: dict, classify: bool = True) -> list[Detection]:
        """Segments on the table now (``classify``: with class probabilities); records whether
        the last grasp failed."""
        scene = self.perceiver.scene
        self.detections = scene(observation) if classify else scene(observation, classify=False)
        self._targets = {}
        if self._last_target is not None:
            p = self._last_target.position
            if any(
                np.linalg.norm(d.segment.box_center[:2] - p[:2]) <= self.failures.radius
                for d in self.detections
            ):
                self.failures.record(p)
            self._last_target = None
        return self.detections

    def candidates(self, detections: list[Detection]) -> list[Detection]:
        """``detections`` not yet given up; :class:`NothingToSort` when none is left."""
        keep = [
            d for d in detections if self.failures.count(d.segment.box_center) < self.max_attempts
        ]
        if not keep:
            raise NothingToSort(
                "no object segmented on the table"
                if not detections
                else f"{len(detections)} object(s) left, each after "
                f"{self.max_attempts} failed grasps"
            )
        return keep

    def target(self, detection: Detection) -> GraspTarget:
        """Where to grasp ``detection`` (turned after failures there), checked against every
        other segment of the current view
        (:func:`~ipbench.policies.grasping.segments.grasp_target`); computed once per view."""
        key = id(detection.segment)
        if key not in self._targets:
            others = [d.points for d in self.detections if d.segment is not detection.segment]
            turn = self.failures.count(detection.segment.box_center)
            points = np.concatenate(others) if others else np.zeros((0, 3))
            self._targets[key] = grasp_target(detection.segment, points, turn, detection.viewpoint)
        return self._targets[key]

    def access(self, detection: Detection) -> tuple[bool, float]:
        """Sort key of accessibility: ``(no free grasp, -clearance)`` — objects whose grasp the
        depth image shows to be blocked wait, the most accessible goes first."""
        target = self.target(detection)
        return (not target.free, -round(target.clearance, 3))

    def patience(self, detection: Detection) -> int:
        """Sort key: 0 until an object failed twice, then 1 (it waits), and so on."""
        return self.failures.count(detection.segment.box_center) // 2

    def begin(self, detection: Detection) -> Decision:
        """Log the decision about ``detection`` (its first view)."""
        decision = Decision(
            self._steps,
            detection.label,
            detection.confidence,
            detection.segment.pixels,
            label=detection.label,
            confidence=detection.confidence,
            free_grasp=self.target(detection).free,
        )
        self.decisions.append(decision)
        return decision

    def grasp(self, target: GraspTarget) -> None:
        """Remember the grasp about to be tried (checked in the next scene view)."""
        self._last_target = target
