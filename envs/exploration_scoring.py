"""Scoring of exploration reports against ground truth (thesis ch. 3, Tables 3.2 and 3.3).

A policy reports ``(class, point)``: a database class it recognised and a 3-D world point
(m) on the object. Rules, applied to each report in order:

* **true positive**: the point lies within the *hit radius* of an instance of the reported
  class that has not been reported yet (the instance's bounding sphere: centre = centre of
  its bounding box, radius = half its diagonal; i.e. the report points at that object). If
  several qualify, the nearest is taken.
* **false positive**: anything else, with a reason: ``"wrong_class"`` (the point hits only
  objects of other classes, or distractors), ``"already_reported"`` (it hits only instances
  of that class already reported) or ``"nothing_there"`` (it hits no object).
* **not found**: instances of database classes present in the scene and never reported.
  Distractors and background objects (class ``None``) never count as not found.

Performance = TP / (TP + FP + not found) (the thesis' measure, e.g. Table 3.2's
56 / (56 + 5 + 7) = 82.4 %); 1.0 when there is nothing to find and nothing was reported.
Pure python/numpy: no simulation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "FP_REASONS",
    "GroundTruthObject",
    "ReportOutcome",
    "Score",
    "Scorer",
    "ScoringError",
    "performance",
]

FP_REASONS: tuple[str, ...] = ("wrong_class", "already_reported", "nothing_there")
"""Why a report is a false positive (see the module docstring)."""


class ScoringError(ValueError):
    """Bad ground truth or report (names, shapes); the message says what is valid."""


@dataclass(frozen=True)
class GroundTruthObject:
    """One object in the scene.

    Attributes
    ----------
    name : unique name in the scene (e.g. ``"object_03"``).
    label : its database class, or ``None`` for a distractor or background object.
    position : (3,) world centre of its bounding box, m.
    radius : hit radius (half the bounding-box diagonal), m.
    """

    name: str
    label: str | None
    position: tuple[float, float, float]
    radius: float


@dataclass(frozen=True)
class ReportOutcome:
    """What one report scored: ``kind`` ``"true_positive"`` or ``"false_positive"``,
    ``instance`` the name of the object it found (TP) or hit (FP of a wrong class / already
    reported; ``None`` when nothing is there), ``reason`` (FP only, one of
    :data:`FP_REASONS`)."""

    kind: str
    instance: str | None
    reason: str | None = None


@dataclass(frozen=True)
class Score:
    """Counts so far: true positives, false positives, not found (database instances not yet
    reported), and :func:`performance`."""

    true_positives: int
    false_positives: int
    not_found: int

    @property
    def performance(self) -> float:
        return performance(self.true_positives, self.false_positives, self.not_found)

    def as_dict(self) -> dict:
        return {
            "true_positives": self.true_positives,
            "false_positives": self.false_positives,
            "not_found": self.not_found,
            "performance": self.performance,
        }


def performance(true_positives: int, false_positives: int, not_found: int) -> float:
    """TP / (TP + FP + not found); 1.0 when all three are 0."""
    total = true_positives + false_positives + not_found
    return 1.0 if total == 0 else true_positives / total


class Scorer:
    """Scores a sequence of reports against ``objects`` (a sequence of
    :class:`GroundTruthObject`); ``labels`` are the valid report classes."""

    def __init__(self, objects, labels) -> None:
        self.objects = tuple(objects)
        self.labels = tuple(labels)
        names = [o.name for o in self.objects]
        if len(set(names)) != len(names):
            raise ScoringError(f"object names must be unique, got {names}")
        bad = [o.label for o in self.objects if o.label is not None and o.label not in labels]
        if bad:
            raise ScoringError(f"unknown object label(s) {bad}; valid: {', '.join(labels)}")
        self._pos = np.array([o.position for o in self.objects], float).reshape(-1, 3)
        self._radius = np.array([o.radius for o in self.objects], float)
        self._found = np.zeros(len(self.objects), bool)
        self._tp = self._fp = 0

    def report(self, label: str, point) -> ReportOutcome:
        """Score one report of class ``label`` at world ``point`` (3,) m (see the rules)."""
        if label not in self.labels:
            raise ScoringError(f"unknown report label {label!r}; valid: {', '.join(self.labels)}")
        p = np.asarray(point, float)
        if p.shape != (3,) or not np.isfinite(p).all():
            raise ScoringError(f"a report's point is 3 finite floats (m), got {point!r}")
        dist = np.linalg.norm(self._pos - p, axis=1)
        hit = dist <= self._radius
        same = np.array([o.label == label for o in self.objects], bool)
        candidates = np.flatnonzero(hit & same & ~self._found)
        if candidates.size:
            k = int(candidates[np.argmin(dist[candidates])])
            self._found[k] = True
            self._tp += 1
            return ReportOutcome("true_positive", self.objects[k].name)
        self._fp += 1
        if not hit.any():
            return ReportOutcome("false_positive", None, "nothing_there")
        hits = np.flatnonzero(hit)
        k = int(hits[np.argmin(dist[hits])])
        reason = "already_reported" if (hit & same).any() else "wrong_class"
        if reason == "already_reported":
            k = int(np.flatnonzero(hit & same)[np.argmin(dist[hit & same])])
        return ReportOutcome("false_positive", self.objects[k].name, reason)

    @property
    def score(self) -> Score:
        """The counts now (not found: database instances not reported so far)."""
        wanted = np.array([o.label is not None for o in self.objects], bool)
        return Score(self._tp, self._fp, int(np.sum(wanted & ~self._found)))
