"""Gaze geometry of the stereo head, as the robot knows it: where to point the PTUs.

The robot's kinematic model of its head (:func:`ipbench.envs.exploration_scene.aim_head`,
forward kinematics of the work cell's PTUs) turns a world point into the four PTU angles that
fixate it with both cameras (kinematic vergence on that point). A pixel of the left image is
turned into a world point by intersecting its viewing ray with the work table's plane (the
table is part of the cell's model). :func:`verge_right` applies a disparity vergence
correction (:func:`ipbench.perception.vergence.pan_correction`) to the right PTU's pan.

Gaze vectors are ``(left pan, left tilt, right pan, right tilt)`` rad
(:data:`~ipbench.envs.exploration_scene.GAZE_JOINTS`).
"""

from __future__ import annotations

import numpy as np

from ipbench.envs.exploration_scene import FRONT_AREA, aim_head, table_height, table_top
from ipbench.envs.ptu import ptu_spec

__all__ = [
    "OBJECT_HEIGHT_M",
    "TABLE_AREA",
    "aim",
    "clip_gaze",
    "on_table",
    "pixel_on_table",
    "table_point",
    "verge_right",
]

TABLE_AREA = FRONT_AREA
"""((x0, x1), (y0, y1)) world m: the part of the work table the scenes use (the cell's model)."""
OBJECT_HEIGHT_M = 0.5
"""Nothing on the table stands higher than this above it (m): the catalogue's tallest products,
2 L cartons and bottles, are about 0.3 m."""


def clip_gaze(gaze: np.ndarray) -> np.ndarray:
    """``gaze`` (4,) inside the PTU limits (the environment rejects a command outside them)."""
    spec = ptu_spec()
    lower, upper = np.tile(spec.lower, 2), np.tile(spec.upper, 2)
    return np.clip(np.asarray(gaze, float), lower, upper)


def aim(point: np.ndarray) -> np.ndarray:
    """(4,) gaze fixating the world ``point`` (3,) m with both cameras."""
    return clip_gaze(aim_head(np.asarray(point, float)))


def table_point(u: float, v: float) -> np.ndarray:
    """(3,) the table-top point at fractions ``u``, ``v`` in [0, 1] of :data:`TABLE_AREA`."""
    (x0, x1), (y0, y1) = TABLE_AREA
    return np.array([x0 + u * (x1 - x0), y0 + v * (y1 - y0), table_height()])


def pixel_on_table(xy: np.ndarray, K: np.ndarray, pose: np.ndarray) -> np.ndarray | None:
    """(3,) where the viewing ray of pixel ``xy`` (camera ``K``, world-from-camera ``pose``)
    meets the table's plane, or ``None`` when it points above the horizon."""
    ray = np.asarray(pose, float)[:3, :3] @ np.linalg.solve(
        np.asarray(K, float), np.array([*np.asarray(xy, float).reshape(2), 1.0])
    )
    origin = np.asarray(pose, float)[:3, 3]
    if ray[2] >= -1e-9:
        return None
    return origin + ray * (table_height() - origin[2]) / ray[2]


def verge_right(gaze: np.ndarray, correction: float) -> np.ndarray:
    """``gaze`` with the right camera turned by ``correction`` rad towards its image +x (the
    sense of :func:`~ipbench.perception.vergence.pan_correction`). The PTU's pan turns the
    camera's optical axis towards image -x for a positive angle (the camera's x axis is the
    tilt link's -y: ``assets/head/ptu_d46.xml``), hence the minus."""
    out = np.array(gaze, float)
    out[2] -= correction
    return clip_gaze(out)


def on_table(point: np.ndarray, margin: float = 0.05) -> bool:
    """Whether world ``point`` (3,) can be on an object on the work table: over the table's top
    (grown by ``margin`` m) and between its surface and :data:`OBJECT_HEIGHT_M` above it. A
    triangulated point elsewhere comes from a false left/right correspondence."""
    centre, half = table_top()
    p = np.asarray(point, float) - centre
    return bool(np.all(np.abs(p[:2]) <= half[:2] + margin) and -margin <= p[2] <= OBJECT_HEIGHT_M)
