"""Whether the depth image shows a grasp to be free: the jaws' volumes against the cloud.

A top-down parallel-jaw grasp at ``position`` (the TCP's target, world m) with the jaws
closing along ``(cos yaw, sin yaw)`` and pre-shaped to ``opening`` sweeps three volumes, all
reaching down to the finger tips (:func:`tip_height`):

- each finger's *landing* box, where it comes down: the finger's cross-section
  (:class:`~ipbench.perception.segmentation.GripperGeometry`) just outside ``opening / 2``,
  grown by ``margin``; a point of *any* segment (the target too: the jaws are opened too
  little) or of the table in it stops the guarded descent on top of something;
- the *closing* box between the pads, as wide as the fingers: a point of *another* segment
  in it is squeezed, pushed or lifted together with the target;
- the *palm* box, the gripper's 27 cm wide body over the fingers, from its bottom
  (``palm`` bottom 13.5 cm above the TCP) up: a point of another segment under it (a tall
  neighbour beside a short target, within 13.5 cm along the jaws) stops the descent with the
  pads still above the target.

:func:`check_grasp` reports whether the grasp is free and its ``clearance``, the horizontal
distance (m) from the landing boxes to the nearest other segment's point above the finger
tips (capped at ``max_clearance``): the margin a centring error or an unseen back of a
neighbour has. Only points and the robot's known geometry are used, never the simulator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ipbench.envs.skills import SkillConfig
from ipbench.perception.segmentation import GripperGeometry

__all__ = [
    "GRASP_DEPTH",
    "FreeGraspConfig",
    "GraspCheck",
    "check_grasp",
    "palm_height",
    "tcp_height",
    "tip_height",
]

_SKILLS = SkillConfig()
_GRIPPER = GripperGeometry()
GRASP_DEPTH = _SKILLS.grasp_depth
"""How far below a pick's position the skill takes the TCP (m; every Sorting version's)."""


@dataclass(frozen=True)
class FreeGraspConfig:
    """Margins of the check (m).

    ``margin``: the landing boxes grow by this on every side (the segment's extent and the
    arm's position are good to about a centimetre); ``tip_margin``: a point counts as an
    obstacle when it is higher than the finger tips minus this (depth noise, a few mm at 1 m);
    ``max_clearance``: clearances above this count as equal (far enough is far enough).
    """

    margin: float = 0.01
    tip_margin: float = 0.005
    max_clearance: float = 0.03


DEFAULT_FREE_GRASP = FreeGraspConfig()


@dataclass(frozen=True)
class GraspCheck:
    """Outcome of :func:`check_grasp`: ``free`` (no obstacle in the jaws' volumes),
    ``landing_hits`` points in the landing boxes (any segment), ``closing_hits`` points of other
    segments between the pads, ``clearance`` (m, see the module docstring), ``palm_hits``
    points of other segments under the palm."""

    free: bool
    landing_hits: int
    closing_hits: int
    clearance: float
    palm_hits: int = 0

    @property
    def hits(self) -> int:
        """Points in the way, all volumes together."""
        return self.landing_hits + self.closing_hits + self.palm_hits


def tcp_height(position_z: float, table_z: float) -> float:
    """World z (m) the TCP descends to for a grasp at ``position_z``: the skill goes
    ``grasp_depth`` below it, no lower than ``min_grasp_height`` above the table
    (:class:`~ipbench.envs.skills.SkillConfig`)."""
    return max(position_z - GRASP_DEPTH, table_z + _SKILLS.min_grasp_height)


def tip_height(position_z: float, table_z: float) -> float:
    """World z (m) the finger tips reach for a grasp at ``position_z``: :func:`tcp_height`
    less the fingers' reach past the TCP
    (:class:`~ipbench.perception.segmentation.GripperGeometry`)."""
    return tcp_height(position_z, table_z) - (_GRIPPER.finger_z[1] - _GRIPPER.tcp_offset)


def palm_height(position_z: float, table_z: float) -> float:
    """World z (m) of the palm's bottom for a grasp at ``position_z`` (the palm box's end
    nearest the fingers tips, :class:`~ipbench.perception.segmentation.GripperGeometry`)."""
    bottom = _GRIPPER.palm_center[2] + _GRIPPER.palm_half[2]
    return tcp_height(position_z, table_z) + (_GRIPPER.tcp_offset - bottom)


def _local(points: np.ndarray, position: np.ndarray, yaw: float) -> np.ndarray:
    """(N, 2) horizontal coordinates of ``points`` in the jaw frame: x along the closing
    direction, y across it, origin at ``position``."""
    c, s = np.cos(yaw), np.sin(yaw)
    d = points[:, :2] - position[:2]
    return np.column_stack([d @ np.array([c, s]), d @ np.array([-s, c])])


def check_grasp(
    position: np.ndarray,
    yaw: float,
    opening: float,
    target: np.ndarray,
    others: np.ndarray,
    table_z: float,
    config: FreeGraspConfig = DEFAULT_FREE_GRASP,
) -> GraspCheck:
    """Check the grasp of the module docstring.

    ``target``: (N, 3) world points of the segment to grasp; ``others``: (M, 3) points of every
    other segment (m); ``table_z``: the table top's world z (m).
    """
    position = np.asarray(position, dtype=float)
    tip = tip_height(float(position[2]), table_z) - config.tip_margin
    half_y = _GRIPPER.finger_half_y
    inner = 0.5 * opening
    outer = inner + _GRIPPER.finger_x[1] - _GRIPPER.finger_x[0]
    reach = outer + config.margin + config.max_clearance

    def near(points: np.ndarray) -> np.ndarray:
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        points = points[points[:, 2] > tip]
        local = _local(points, position, yaw)
        return local[np.all(np.abs(local) <= reach + half_y, axis=1)]

    mine, theirs = near(target), near(others)

    def in_landing(local: np.ndarray) -> np.ndarray:
        ax, ay = np.abs(local[:, 0]), np.abs(local[:, 1])
        m = config.margin
        return (ax >= inner - m) & (ax <= outer + m) & (ay <= half_y + m)

    landing = int(in_landing(mine).sum() + in_landing(theirs).sum())
    between = (np.abs(theirs[:, 0]) < inner) & (np.abs(theirs[:, 1]) <= half_y)
    closing = int(between.sum())
    # the palm: other segments' points above its bottom within its footprint (margin around)
    others = np.asarray(others, dtype=float).reshape(-1, 3)
    high = others[others[:, 2] > palm_height(float(position[2]), table_z) - config.tip_margin]
    palm = _local(high, position, yaw)
    m = config.margin
    palm_hits = int(
        np.sum(
            (np.abs(palm[:, 0]) <= _GRIPPER.palm_half[0] + m)
            & (np.abs(palm[:, 1]) <= _GRIPPER.palm_half[1] + m)
        )
    )
    clearance = config.max_clearance
    if len(theirs):
        # distance from each finger's box [inner, outer] x [-half_y, half_y] (both sides)
        dx = np.maximum(np.maximum(inner - np.abs(theirs[:, 0]), np.abs(theirs[:, 0]) - outer), 0)
        dy = np.maximum(np.abs(theirs[:, 1]) - half_y, 0.0)
        clearance = float(min(clearance, np.hypot(dx, dy).min()))
    free = landing == 0 and closing == 0 and palm_hits == 0
    return GraspCheck(free, landing, closing, clearance, palm_hits)
