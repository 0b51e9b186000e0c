"""Exploration policies for ``ipbench/Exploration-v0``: where to look, what to report.

Every policy sees the same thing the same way (:func:`~ipbench.policies.stereo_look.look`:
features, multiple same-class instances, stereo correspondence, triangulation) and reports
each object once: a candidate of a class within :func:`same_object_m` of an object already
reported (or queued) as that class is the same object. One report goes out per step, with the
step's gaze (reports are world positions, so the head need not look at the object any more).

- ``active-vision`` — the thesis' macro script (Table 3.1): attend the strongest new object
  hypothesis (fixate its triangulated position with both eyes), verge on it (disparity
  vergence of the fovea, :func:`verge`, until under :data:`VERGENCE_GOAL_PX`), verify it (the
  same class again at the fixation), report it and inhibit its direction; with no hypothesis
  left, saccade to the most salient location not inhibited (unexplained features weighted by
  eccentricity, :mod:`ipbench.perception.saliency`). It halts after :data:`HALT_AFTER`
  consecutive saccades without an object (the thesis' protocol).
- ``active-vision-no-halt`` — an ablation (:data:`EXPLORATION_ABLATIONS`, not in the
  benchmark's default set): ``active-vision`` without its halting rule, exploring to the
  saccade budget; paired with ``active-vision`` over seeds it separates what the halting rule
  costs from what the choice of fixations does.
- ``random-gaze`` — fixates random points of the table; reports what it sees, unverified.
- ``raster-scan`` — sweeps the table in a serpentine grid of :data:`RASTER` fixations, then
  halts.
- ``oracle-gaze`` — reads the database objects' true positions from ``info`` and fixates each
  once (nearest first); the same recognition: the ceiling of gaze alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ipbench.envs.exploration_scene import DATABASE_CLASSES, database_instance
from ipbench.perception.features2d import DEFAULT_MAX_FEATURES
from ipbench.perception.object_database import ObjectDatabase
from ipbench.perception.recognition import RecognitionConfig
from ipbench.perception.saliency import (
    InhibitionMap,
    most_salient,
    pixel_direction,
    salient_locations,
)
from ipbench.perception.vergence import pan_correction, peak_disparity
from ipbench.policies.gaze import aim, pixel_on_table, table_point, verge_right
from ipbench.policies.stereo_look import Candidate, Look, look

__all__ = [
    "EXPLORATION_ABLATIONS",
    "EXPLORATION_POLICIES",
    "EXPLORATION_POLICY_VERSION",
    "HALT_AFTER",
    "RASTER",
    "READS_INFO",
    "VERGENCE_GOAL_PX",
    "ExplorationPolicy",
    "ExplorationPolicyError",
    "make_exploration_policy",
    "same_object_m",
    "verge",
]

EXPLORATION_POLICIES: tuple[str, ...] = (
    "active-vision",
    "random-gaze",
    "raster-scan",
    "oracle-gaze",
)
"""Policy names of the exploration benchmark."""
EXPLORATION_ABLATIONS: tuple[str, ...] = ("active-vision-no-halt",)
"""Variants of a policy with one of its rules removed, run by name only (never by default):
they explain a policy's figures and are not benchmark entries."""
EXPLORATION_POLICY_VERSION = 2
"""Version of what the exploration policies do with an observation (part of a run's
fingerprint: results of other policy code are never mixed with this one's). 2: a candidate
triangulated off the work table is dropped (a false correspondence; version 1 could report a
point outside the env's bounds)."""
READS_INFO: frozenset[str] = frozenset({"oracle-gaze"})
"""The policies that read ``info`` (ground truth)."""
HALT_AFTER = 5
"""Consecutive saccades without an object before the macro script halts (thesis ch. 3)."""
VERGENCE_GOAL_PX = 2.0
"""Vergence ends when the fovea's peak disparity is below this (px)."""
MAX_VERGE_CYCLES = 3
"""Vergence corrections per attended object at the most."""
FOVEA_FRACTION = 0.25
"""The fovea: the central box of this fraction of the image's width and height."""
RASTER = (3, 4)
"""Rows (across the table, y) and columns (along it, x) of the raster scan's fixations."""


class ExplorationPolicyError(ValueError):
    """An unknown policy name or missing input; the message lists the valid options."""


def same_object_m(label: str) -> float:
    """Distance under which two sightings of ``label`` are one object, m: the thinnest side of
    that product (two instances cannot stand closer; the robot knows its database objects)."""
    return float(min(database_instance(label).size))


def _fovea(shape: tuple[int, ...]) -> tuple[float, float, float, float]:
    h, w = shape[:2]
    fx, fy = 0.5 * FOVEA_FRACTION * w, 0.5 * FOVEA_FRACTION * h
    return (w / 2 - fx, h / 2 - fy, w / 2 + fx, h / 2 + fy)


def verge(obs: dict, seen: Look) -> tuple[np.ndarray, float | None]:
    """Selective vergence on the fovea: the gaze with the right PTU turned so that the fovea's
    peak disparity between the eyes' features of ``seen`` goes to zero, and that disparity
    (working-frame px; ``None`` without matches)."""
    gaze = np.asarray(obs["head_qpos"], float)
    v = peak_disparity(seen.left, seen.right, roi=_fovea(seen.size))
    if v is None:
        return gaze, None
    return verge_right(gaze, pan_correction(v, seen.rig.K_right)), v.disparity


@dataclass
class Fixation:
    """One step's decision: ``kind`` of target, the attended ``label`` if any, the left
    camera's optical axis (3,) before the saccade, the fovea's disparity there (px)."""

    kind: str
    label: str | None
    axis: list[float]
    disparity: float | None = None


class ExplorationPolicy:
    """Base: ``reset(seed)``, then ``act(observation, info=None)`` each step (module doc)."""

    name = ""

    def __init__(
        self,
        database: ObjectDatabase,
        recognition: RecognitionConfig | None = None,
        max_features: int = DEFAULT_MAX_FEATURES,
    ) -> None:
        self.database, self.recognition, self.max_features = database, recognition, max_features
        self.reset(0)

    def reset(self, seed: int) -> None:
        self.rng = np.random.default_rng([int(seed), 313])
        self.reported: list[tuple[str, np.ndarray]] = []
        self.queue: list[Candidate] = []
        self.fixations: list[Fixation] = []
        self.halted = False
        self.last_look: Look | None = None

    # -- the step -----------------------------------------------------------------------------
    def act(self, obs: dict, info: dict | None = None) -> dict:
        seen = self.last_look = look(obs, self.database, self.recognition, self.max_features)
        gaze, kind, label, disparity = self.decide(obs, seen, info)
        self.fixations.append(
            Fixation(kind, label, obs["head_left_pose"][:3, 2].tolist(), disparity)
        )
        return self._action(gaze)

    def decide(self, obs: dict, seen: Look, info: dict | None):
        """(next gaze (4,), kind, attended label, disparity): the policy's choice."""
        raise NotImplementedError

    # -- reports ------------------------------------------------------------------------------
    def known(self, c: Candidate) -> bool:
        """Whether ``c`` is an object already reported or queued."""
        near = same_object_m(c.label)
        return any(
            label == c.label and np.linalg.norm(pos - c.position) < near
            for label, pos in [*self.reported, *((q.label, q.position) for q in self.queue)]
        )

    def enqueue(self, candidates) -> int:
        """Queue the new ones for reporting; how many were new."""
        new = [c for c in candidates if not self.known(c)]
        self.queue += new
        return len(new)

    def _action(self, gaze: np.ndarray) -> dict:
        report = {"kind": 0, "label": 0, "position": np.zeros(3)}
        if self.queue:
            c = self.queue.pop(0)
            self.reported.append((c.label, c.position))
            report = {"kind": 1, "label": DATABASE_CLASSES.index(c.label), "position": c.position}
        elif self.halted:
            report["kind"] = 2
        return {"gaze": np.asarray(gaze, float), "report": report}


class RandomGaze(ExplorationPolicy):
    name = "random-gaze"

    def decide(self, obs, seen, info):
        self.enqueue(seen.candidates)
        return aim(table_point(*self.rng.uniform(0, 1, 2))), "random", None, None


class RasterScan(ExplorationPolicy):
    name = "raster-scan"

    def reset(self, seed: int) -> None:
        super().reset(seed)
        rows, cols = RASTER
        self.points = [
            table_point(
                (c + 0.5) / cols if r % 2 == 0 else (cols - c - 0.5) / cols, (r + 0.5) / rows
            )
            for r in range(rows)
            for c in range(cols)
        ]

    def decide(self, obs, seen, info):
        self.enqueue(seen.candidates)
        if not self.points:
            self.halted = True
            return obs["head_qpos"], "halt", None, None
        return aim(self.points.pop(0)), "raster", None, None


class OracleGaze(ExplorationPolicy):
    name = "oracle-gaze"

    def reset(self, seed: int) -> None:
        super().reset(seed)
        self.targets: list[np.ndarray] | None = None

    def decide(self, obs, seen, info):
        if info is None:
            raise ExplorationPolicyError("oracle-gaze reads info: call act(observation, info)")
        self.enqueue(seen.candidates)
        if self.targets is None:
            self.targets = [
                np.asarray(o["position"], float)
                for o in info["objects"].values()
                if o["class"] is not None
            ]
        if not self.targets:
            self.halted = True
            return obs["head_qpos"], "halt", None, None
        here = obs["head_left_pose"][:3, 3]
        axis = obs["head_left_pose"][:3, 2]
        # nearest to the current line of sight first
        off = [np.linalg.norm(np.cross(t - here, axis)) for t in self.targets]
        return aim(self.targets.pop(int(np.argmin(off)))), "oracle", None, None


class ActiveVision(ExplorationPolicy):
    name = "active-vision"
    halt_after: int | None = HALT_AFTER
    """Consecutive saccades without an object before it halts; ``None``: it never halts."""

    def reset(self, seed: int) -> None:
        super().reset(seed)
        self.inhibition = InhibitionMap()
        self.attending: Candidate | None = None
        self.verges = 0
        self.misses = 0

    def decide(self, obs, seen, info):
        K, pose = seen.rig.K_left, obs["head_left_pose"]  # noqa: N806  (working frame)
        disparity, verified = None, self.attending is not None
        if self.attending is not None:
            gaze, disparity = verge(obs, seen)
            if (
                disparity is not None
                and abs(disparity) >= VERGENCE_GOAL_PX
                and self.verges < MAX_VERGE_CYCLES
            ):
                self.verges += 1
                return gaze, "verge", self.attending.label, disparity
            a, self.attending = self.attending, None
            same = [
                c
                for c in seen.candidates
                if c.label == a.label
                and np.linalg.norm(c.position - a.position) < same_object_m(a.label)
            ]
            found = self.enqueue(same[:1])
            self.misses = 0 if found else self.misses + 1
            self.inhibition.add(a.position - pose[:3, 3])
        new = [
            c
            for c in seen.candidates
            if not self.known(c) and not self.inhibition.is_inhibited(c.position - pose[:3, 3])
        ]
        if not verified and self.fixations:  # after a saccade to a salient or random place
            self.misses = 0 if new else self.misses + 1
        if self.halt_after is not None and self.misses >= self.halt_after and not self.queue:
            self.halted = True
            return obs["head_qpos"], "halt", None, disparity
        if new:
            self.attending, self.verges = new[0], 0
            return aim(new[0].position), "object", new[0].label, disparity
        spots = salient_locations(seen.unexplained_left, seen.size, (K[0, 2], K[1, 2]))
        spot = most_salient(spots, K, pose, self.inhibition)
        point = None if spot is None else pixel_on_table(spot.xy, K, pose)
        if point is not None:
            self.inhibition.add(pixel_direction(spot.xy, K, pose))
            return aim(point), "salient", None, disparity
        return aim(table_point(*self.rng.uniform(0, 1, 2))), "random", None, disparity


class ActiveVisionNoHalt(ActiveVision):
    """``active-vision`` without the halting rule (an ablation): the same fixations, to the
    saccade budget."""

    name = "active-vision-no-halt"
    halt_after = None


_POLICIES = {
    p.name: p for p in (ActiveVision, RandomGaze, RasterScan, OracleGaze, ActiveVisionNoHalt)
}


def make_exploration_policy(name: str, database: ObjectDatabase, **kwargs) -> ExplorationPolicy:
    """The policy called ``name`` (one of :data:`EXPLORATION_POLICIES` or
    :data:`EXPLORATION_ABLATIONS`) on ``database``."""
    if name not in _POLICIES:
        valid = ", ".join((*EXPLORATION_POLICIES, *EXPLORATION_ABLATIONS))
        raise ExplorationPolicyError(f"unknown exploration policy {name!r}; valid: {valid}")
    return _POLICIES[name](database, **kwargs)
