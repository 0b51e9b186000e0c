"""Where the objects an episode did not find were lost.

An object the policy never reported may have failed at any stage of the exploration: it was
never in view, it was in view but never recognised, recognised but never attended, attended
but not verified. Which stage loses the most objects says what to improve — recognition, or
the choice of where to look. Per look (after the policy's ``act``), the evaluation follows
every database instance of the scene (ground truth from ``info``, read here by the
evaluation only):

- *in view*: visible in the left head image (``info["head_left_mask"]``);
- *recognised*: the look triangulated a candidate of its class within
  :func:`~ipbench.policies.exploration.same_object_m` of its centre (as
  :mod:`~ipbench.eval.exploration.sightings` counts it);
- each recognising candidate is *taken for a reported object* when an object of its class
  already reported or queued by the policy (before this look) lay within ``same_object_m`` of
  it — the policy counts it as that object; otherwise it is *inhibited* when the policy keeps
  an inhibition-of-return map (``active-vision``) and the candidate's direction lay in it when
  the policy chose its next fixation; otherwise it was *new*;
- *attended*: the policy's attended hypothesis (``active-vision``'s ``attending``) after the
  look is a candidate of its class within ``same_object_m`` of it.

An instance not found at the end takes the first of :data:`MISSED_CAUSES` that holds.
Episode records carry ``missed`` (``{cause: instances}``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ipbench.policies.exploration import same_object_m

__all__ = ["MISSED_CAUSES", "InstanceHistory", "MissedTracker", "known_objects"]

MISSED_CAUSES: dict[str, str] = {
    "wrong_class": "reported as another class, never as its own",
    "never_in_view": "in no look's left image",
    "never_recognised": "in view, recognised at no look",
    "attended_not_verified": "attended as a hypothesis, not verified at the fixation",
    "inhibited": "recognised but never attended, and inside inhibition of return at some look",
    "not_attended": "recognised as a new object, never attended nor reported",
    "taken_for_reported": "recognised only where an object of its class was already reported",
}
"""Causes, in the order an instance not found is assigned to them (the first that holds)."""


@dataclass
class InstanceHistory:
    """What the looks of an episode saw of one database instance (counts of looks)."""

    in_view: int = 0
    recognised: int = 0
    as_new: int = 0
    inhibited: int = 0
    taken_for_reported: int = 0
    attended: int = 0

    def cause(self, mistaken: bool) -> str:
        """The cause of missing this instance (:data:`MISSED_CAUSES`); ``mistaken``: a report
        took it for another class."""
        if mistaken:
            return "wrong_class"
        if not self.in_view:
            return "never_in_view"
        if not self.recognised:
            return "never_recognised"
        if self.attended:
            return "attended_not_verified"
        if self.inhibited:
            return "inhibited"
        if self.as_new:
            return "not_attended"
        return "taken_for_reported"


def known_objects(policy) -> list[tuple[str, np.ndarray]]:
    """``(label, position)`` of every object ``policy`` has reported or queued: call it before
    the policy's ``act`` to know what a look's candidates could be taken for."""
    return [
        *((label, np.asarray(p, float)) for label, p in policy.reported),
        *((q.label, np.asarray(q.position, float)) for q in policy.queue),
    ]


def _near(label: str, position: np.ndarray, objects: Iterable[tuple[str, np.ndarray]]) -> bool:
    near = same_object_m(label)
    return any(lbl == label and np.linalg.norm(p - position) < near for lbl, p in objects)


def _inhibited_at_choice(policy, direction: np.ndarray) -> bool:
    """Whether ``direction`` lay in ``policy``'s inhibition map when it chose its fixation:
    a saccade to a salient place inhibits that place after the choice, so it is left out."""
    inhibition = getattr(policy, "inhibition", None)
    if inhibition is None or not len(inhibition):
        return False
    dirs = inhibition.directions
    if policy.fixations and policy.fixations[-1].kind == "salient":
        dirs = dirs[:-1]
    if not len(dirs):
        return False
    unit = direction / np.linalg.norm(direction)
    return bool(np.any(dirs @ unit >= np.cos(inhibition.radius_rad)))


@dataclass
class MissedTracker:
    """Follows every database instance of ``objects`` (``info["objects"]`` at reset) over an
    episode's looks (module docstring)."""

    objects: Mapping[str, Mapping]
    history: dict[str, InstanceHistory] = field(init=False)

    def __post_init__(self) -> None:
        self.history = {
            name: InstanceHistory() for name, o in self.objects.items() if o["class"] is not None
        }

    def look(
        self, policy, obs: Mapping, info: Mapping, known: Sequence[tuple[str, np.ndarray]]
    ) -> None:
        """Count one look: ``policy`` has just acted on ``obs`` (its ``last_look``), ``info``
        is that observation's, ``known`` what :func:`known_objects` gave before the act."""
        origin = np.asarray(obs["head_left_pose"], float)[:3, 3]
        mask = np.asarray(info["head_left_mask"])
        visible = set(np.unique(mask[mask >= 0]).tolist())
        candidates = [] if policy.last_look is None else list(policy.last_look.candidates)
        attending = getattr(policy, "attending", None)
        for k, (name, obj) in enumerate(self.objects.items()):
            if name not in self.history or k not in visible:
                continue
            h = self.history[name]
            h.in_view += 1
            label, centre = obj["class"], np.asarray(obj["position"], float)
            near = same_object_m(label)
            hits = [
                c
                for c in candidates
                if c.label == label and np.linalg.norm(np.asarray(c.position) - centre) < near
            ]
            if not hits:
                continue
            h.recognised += 1
            fresh = [c for c in hits if not _near(label, np.asarray(c.position, float), known)]
            if not fresh:
                h.taken_for_reported += 1
            elif all(_inhibited_at_choice(policy, np.asarray(c.position) - origin) for c in fresh):
                h.inhibited += 1
            else:
                h.as_new += 1
            if (
                attending is not None
                and attending.label == label
                and np.linalg.norm(np.asarray(attending.position) - centre) < near
            ):
                h.attended += 1

    def missed(self, found: Iterable[str], mistaken: Iterable[str]) -> dict[str, int]:
        """``{cause: instances}`` over the instances not in ``found`` (every cause, in
        :data:`MISSED_CAUSES`' order); ``mistaken``: instances a report took for another
        class."""
        found, mistaken = set(found), set(mistaken)
        out = dict.fromkeys(MISSED_CAUSES, 0)
        for name, h in self.history.items():
            if name not in found:
                out[h.cause(name in mistaken)] += 1
        return out
