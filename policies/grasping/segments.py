"""Where and how to grasp a perceived segment, and remembering grasps that failed.

The camera sees only an object's front, so the box of its points is short along the line of
sight; the footprint is completed by assuming the unseen back is as deep as the object is wide
(:func:`completed_footprint`: a cylinder's or a box's centre moves back by half the missing
depth). The grasp point is that footprint's centre, lowered for short objects to just under the top
(a bowl is held by its rim, as in :func:`ipbench.policies.grasping.boxes.grasp_point`); a short
round object is centred on the circle fitted to its rim (:func:`rim_circle`), which a wide bowl
in 21 cm jaws needs to within about a centimetre. The jaws
close across the box's narrower horizontal side unless the depth image shows that grasp to be
blocked (:mod:`ipbench.policies.grasping.free`: a finger would land on something, or another
object is between the pads), in which case a wider opening, the other side or a diagonal is
taken (:func:`grasp_target`). After a failed grasp the next attempt at the same place turns
the first choice by 90°.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ipbench.envs.sorting import MAX_JAW_OPENING
from ipbench.perception.segmentation import Segment, grasp_yaw
from ipbench.policies.grasping.boxes import SHORT, TOP_MARGIN, opening_across
from ipbench.policies.grasping.free import (
    DEFAULT_FREE_GRASP,
    GRASP_DEPTH,
    FreeGraspConfig,
    check_grasp,
)

__all__ = [
    "FailureMemory",
    "GraspTarget",
    "completed_footprint",
    "grasp_target",
    "jaw_opening",
    "rim_circle",
]

SQUARE = 1.2
"""Footprints whose sides differ by less than this ratio are near-square (round objects)."""
BOX_TURNS = (0.0, np.pi / 2, np.pi / 4, -np.pi / 4)
"""Jaw turns tried from the first choice (rad), in order of preference."""
ROUND_TURNS = (0.0, np.pi / 2, np.pi / 6, -np.pi / 6, np.pi / 3, -np.pi / 3)
"""The same for near-square footprints, whose width is about the same across any turn."""
MAX_COMPLETION = 0.05
"""Most the footprint is deepened along the line of sight (m)."""
RIM_BAND = 0.008
"""A short round segment's rim: its points within this of its top (m)."""
RIM_FIT_RMS = 0.004
"""Largest RMS distance (m) of the rim points from their fitted circle for the fit to count
(a ring of a bowl's or a mug's rim fits within depth noise; a flat top does not)."""
RIM_MAX_SHIFT = 0.04
"""Largest move (m) of the footprint's centre to the rim circle's (a fit further off is
taken for a wrong one)."""


@dataclass(frozen=True)
class GraspTarget:
    """``position`` (3,) world m, jaw ``yaw`` (rad, in [-pi, pi)) and jaw ``opening`` (m: the
    object's completed width across the jaws plus ``OPENING_MARGIN``) for the env's action;
    ``free``: the depth image shows the jaws' volumes clear, ``clearance`` (m) to spare
    (:mod:`ipbench.policies.grasping.free`)."""

    position: np.ndarray
    yaw: float
    opening: float = MAX_JAW_OPENING
    free: bool = True
    clearance: float = float("inf")


def _wrap(a: float) -> float:
    return float((a + np.pi) % (2 * np.pi) - np.pi)


def completed_footprint(segment: Segment, viewpoint: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centre (2,) and side lengths (2,) along the box's x and y axes of the object's
    footprint on the table, its unseen back completed (see the module docstring)."""
    axes = np.asarray(segment.box_rotation, dtype=float)[:2, :2]  # columns: box x, y (xy part)
    ext = np.asarray(segment.box_extent[:2], dtype=float).copy()
    centre = np.asarray(segment.box_center[:2], dtype=float).copy()
    sight = centre - np.asarray(viewpoint, dtype=float)[:2]
    if np.linalg.norm(sight) < 1e-6:
        return centre, ext
    sight /= np.linalg.norm(sight)
    along = int(np.argmax(np.abs(axes.T @ sight)))  # the box side closest to the sight line
    missing = min(max(ext[1 - along] - ext[along], 0.0), MAX_COMPLETION)
    if missing > 0:
        direction = axes[:, along] * np.sign(axes[:, along] @ sight)
        centre += 0.5 * missing * direction
        ext[along] += missing
    return centre, ext


def rim_circle(segment: Segment) -> tuple[np.ndarray, float] | None:
    """Centre (2,) and radius (m) of a short round object's rim, fitted to the segment's
    points within :data:`RIM_BAND` of its top (an algebraic least-squares circle, Kasa 1976):
    a bowl shows its rim's near and far arcs, whose circle finds the object's axis where the
    box of its points is pulled by depth gaps and neighbours' occlusions. None when the points
    do not lie on a circle (:data:`RIM_FIT_RMS`), or lie on too short an arc to fit one."""
    pts = np.asarray(segment.points, dtype=float)
    rim = pts[pts[:, 2] > float(segment.top) - RIM_BAND][:, :2]
    if len(rim) < 20:
        return None
    origin = rim.mean(axis=0)
    xy = rim - origin
    # x^2 + y^2 = 2 a x + 2 b y + c, linear in (a, b, c)
    design = np.column_stack([2 * xy, np.ones(len(xy))])
    (a, b, c), *_ = np.linalg.lstsq(design, (xy**2).sum(axis=1), rcond=None)
    r2 = c + a * a + b * b
    if r2 <= 0:
        return None
    radius = float(np.sqrt(r2))
    dist = np.hypot(xy[:, 0] - a, xy[:, 1] - b)
    if np.sqrt(np.mean((dist - radius) ** 2)) > RIM_FIT_RMS:
        return None
    angles = np.sort(np.arctan2(xy[:, 1] - b, xy[:, 0] - a))
    gaps = np.diff(np.r_[angles, angles[0] + 2 * np.pi])
    if 2 * np.pi - gaps.max() < np.pi / 2:  # the points span less than a quarter circle
        return None
    return origin + np.array([a, b]), radius


def grasp_target(
    segment: Segment,
    others: np.ndarray | list = (),
    turn: int = 0,
    viewpoint: np.ndarray | None = None,
    config: FreeGraspConfig = DEFAULT_FREE_GRASP,
) -> GraspTarget:
    """The grasp of ``segment`` seen from ``viewpoint`` (3,) (None: no completion), checked
    against ``others``, the (M, 3) world points of every other segment (m); ``turn`` is the
    number of failed attempts here (each turns the first choice by a further 90°).

    Candidates, in order of preference: the jaws across the footprint's narrower side (turned
    by ``turn`` x 90°), opened 2 cm wider, across the other side, then turned 45° either way
    (a near-square footprint, e.g. a round object: every 30°, :data:`ROUND_TURNS`).
    The first one that is free with ``max_clearance`` to spare is taken; else the free one
    with the most clearance; else (``free=False``) the one with the fewest points in the way.
    """
    top = float(segment.top)
    height = float(segment.height)
    # the pick skill takes the TCP ``grasp_depth`` below the position it is given (to hold
    # tall objects under their centroid): a short object's position is raised by as much, so
    # that the pads close TOP_MARGIN under its top, on a bowl's rim
    z = top - TOP_MARGIN + GRASP_DEPTH if height < SHORT else top - 0.5 * height
    if viewpoint is None:
        centre, ext = np.asarray(segment.box_center[:2]), np.asarray(segment.box_extent[:2])
    else:
        centre, ext = completed_footprint(segment, viewpoint)
    lo, hi = np.sort(ext)
    round_ = hi < SQUARE * max(lo, 1e-6)
    if round_ and height < SHORT:
        rim = rim_circle(segment)
        if rim is not None and np.linalg.norm(rim[0] - centre) <= RIM_MAX_SHIFT:
            centre = rim[0]
    position = np.array([centre[0], centre[1], z])
    yaw = grasp_yaw(segment)  # across the box's y side
    if ext[0] < ext[1]:
        yaw += np.pi / 2
    first = yaw + turn * np.pi / 2
    candidates = []
    turns = ROUND_TURNS if round_ else BOX_TURNS
    for k, dyaw in enumerate(turns):
        opening = jaw_opening(segment, ext, first + dyaw)
        candidates.append((_wrap(first + dyaw), opening))
        if k == 0:
            candidates.append((_wrap(first), min(opening + 0.02, MAX_JAW_OPENING)))
    table_z = top - height
    target_points = np.asarray(segment.points, dtype=float)
    other_points = np.asarray(others, dtype=float).reshape(-1, 3)
    # only what the jaws can reach matters: a window around the grasp, above the table
    window = 0.5 * MAX_JAW_OPENING + 0.1
    other_points = other_points[
        (np.abs(other_points[:, :2] - position[:2]).max(axis=1) <= window)
        & (other_points[:, 2] > table_z)
    ]
    checks = [
        check_grasp(position, y, o, target_points, other_points, table_z, config)
        for y, o in candidates
    ]
    roomy = (k for k, c in enumerate(checks) if c.free and c.clearance >= config.max_clearance)
    best = next(roomy, None)
    if best is None:
        free = [k for k, c in enumerate(checks) if c.free]
        if free:
            best = max(free, key=lambda k: checks[k].clearance)
        else:
            best = min(
                range(len(checks)),
                key=lambda k: (checks[k].hits, k),
            )
    yaw, opening = candidates[best]
    return GraspTarget(position, yaw, opening, checks[best].free, checks[best].clearance)


def jaw_opening(segment: Segment, extent: np.ndarray, yaw: float) -> float:
    """Jaw opening (m) for closing along ``yaw`` on ``segment``'s footprint of side lengths
    ``extent`` (2,) (along the box's x and y): the footprint's width along the closing
    direction plus ``OPENING_MARGIN``, at most the full opening."""
    return opening_across(np.asarray(segment.box_rotation, dtype=float)[:2, :2], extent, yaw)


@dataclass
class FailureMemory:
    """Failed grasp attempts by table position (xy within ``radius`` m is the same place)."""

    radius: float = 0.05
    places: list[np.ndarray] = field(default_factory=list)
    counts: list[int] = field(default_factory=list)

    def _index(self, xy: np.ndarray) -> int | None:
        for i, p in enumerate(self.places):
            if np.linalg.norm(p - xy) <= self.radius:
                return i
        return None

    def count(self, position: np.ndarray) -> int:
        """Failed attempts recorded at ``position``'s place."""
        i = self._index(np.asarray(position, dtype=float)[:2])
        return 0 if i is None else self.counts[i]

    def record(self, position: np.ndarray) -> None:
        """One more failed attempt at ``position``'s place."""
        xy = np.asarray(position, dtype=float)[:2]
        i = self._index(xy)
        if i is None:
            self.places.append(xy)
            self.counts.append(1)
        else:
            self.counts[i] += 1

    def clear(self) -> None:
        self.places.clear()
        self.counts.clear()
