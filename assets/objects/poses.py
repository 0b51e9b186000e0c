"""Stable resting poses of an instance on a horizontal table.

Poses are computed from the collision primitives: the height is the distance from the object
origin to the lowest collision point, and a "side" pose is the roll about the object's own
axis (after tipping it over about x) that puts the centre of mass lowest. For a mug that is
the body lying with the handle touching the table; for a juice box, lying on its back face
with the straw up.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from ipbench.assets.objects.geometry import object_geometry
from ipbench.assets.objects.instance import ObjectInstance
from ipbench.assets.objects.primitives import Primitive

__all__ = ["RestingPose", "resting_poses"]

_SIDE = ("juice_bottle", "milk_carton", "mug", "juice_box")
_UPSIDE_DOWN = ("bowl", "mug")


@dataclass(frozen=True)
class RestingPose:
    """A way the object rests on a horizontal table.

    Attributes
    ----------
    name : ``"upright"``, ``"side"`` or ``"upside_down"``.
    quat : (4,) rotation object -> world (w, x, y, z) for that rest (any yaw about the world
        z axis may be applied on top: ``q_world = q_yaw * quat``).
    height : z of the object-frame origin above the table top, m.
    """

    name: str
    quat: tuple[float, float, float, float]
    height: float


def _lowest(prims: tuple[Primitive, ...], rots: np.ndarray) -> np.ndarray:
    """(K,) lowest z of the collision shapes for each of the (K, 3, 3) rotations, m."""
    low = np.full(len(rots), np.inf)
    for p in prims:
        if p.kind == "mesh":
            z = np.einsum("kj,nj->kn", rots[:, 2, :], p.mesh[0]).min(axis=1)
        else:
            cz = rots[:, 2, :] @ p.pos
            axes_z = rots[:, 2, :] @ p.rot  # (K, 3) z components of the local axes
            if p.kind == "box":
                z = cz - np.abs(axes_z) @ np.asarray(p.size)
            else:
                r, hl = p.size
                az = np.abs(axes_z[:, 2])
                radial = np.sqrt(np.clip(1 - az * az, 0, 1)) if p.kind == "cylinder" else 1.0
                z = cz - hl * az - r * radial
        low = np.minimum(low, z)
    return low


def _rot_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _side_rots(phi: np.ndarray) -> np.ndarray:
    """(K, 3, 3) rotations Rx(90 deg) @ Rz(phi): roll phi about the own axis, then tip over."""
    c, s = np.cos(phi), np.sin(phi)
    rz = np.zeros((len(phi), 3, 3))
    rz[:, 0, 0], rz[:, 0, 1], rz[:, 1, 0], rz[:, 1, 1], rz[:, 2, 2] = c, -s, s, c, 1.0
    return _rot_x(np.pi / 2) @ rz


def _to_quat(rot: np.ndarray) -> tuple[float, float, float, float]:
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(rot).as_quat()
    q = np.array([w, x, y, z])
    q = q if q[0] >= 0 else -q
    q[np.abs(q) < 1e-12] = 0.0
    return tuple(float(v) for v in q / np.linalg.norm(q))


def _pose(name: str, rot: np.ndarray, prims: tuple[Primitive, ...]) -> RestingPose:
    height = float(np.round(-_lowest(prims, rot[None])[0], 12)) + 0.0  # no -0.0
    return RestingPose(name, _to_quat(rot), height)


def _side(prims: tuple[Primitive, ...], com: np.ndarray) -> np.ndarray:
    """Rotation of the side rest that minimises the height of the centre of mass."""

    def com_height(phi: np.ndarray) -> np.ndarray:
        rots = _side_rots(phi)
        return rots[:, 2, :] @ com - _lowest(prims, rots)

    step = 2 * np.pi / 720
    grid = np.arange(720) * step
    heights = com_height(grid)
    best = grid[int(np.flatnonzero(heights <= heights.min() + 1e-9)[0])]
    lo, hi = best - step, best + step
    for _ in range(60):  # golden-section search for the kink of the minimum
        m1, m2 = hi - 0.618 * (hi - lo), lo + 0.618 * (hi - lo)
        if com_height(np.array([m1]))[0] <= com_height(np.array([m2]))[0]:
            hi = m2
        else:
            lo = m1
    return _side_rots(np.array([(lo + hi) / 2]))[0]


def _conical(inst: ObjectInstance) -> bool:
    """A v2 mug whose wall tapers: lying down its axis tilts, which the side search (axis
    horizontal) does not model, so it gets no "side" pose."""
    s = inst.shape
    return getattr(s, "radius_bottom", None) is not None and s.radius_bottom != s.radius_top


@cache
def resting_poses(inst: ObjectInstance) -> tuple[RestingPose, ...]:
    """The stable resting poses of ``inst``, ``"upright"`` first.

    ``"side"`` for juice bottles, milk cartons, mugs (not the tapered v2 ones) and juice
    boxes; ``"upside_down"`` for bowls and mugs.

    Returns
    -------
    tuple of :class:`RestingPose`; place the object at ``(x, y, table_z + pose.height)``
    with ``pose.quat`` (optionally pre-multiplied by a yaw about world z).
    """
    geo = object_geometry(inst)
    prims = geo.collision
    poses = [_pose("upright", np.eye(3), prims)]
    if inst.category in _SIDE and not _conical(inst):
        poses.append(_pose("side", _side(prims, geo.com), prims))
    if inst.category in _UPSIDE_DOWN:
        poses.append(_pose("upside_down", _rot_x(np.pi), prims))
    return tuple(poses)
