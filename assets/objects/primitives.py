"""Visual parts and collision primitives: what an object's geometry is made of (pure numpy).

A :class:`VisualPart` is one visual mesh (v2: with texture coordinates and a texture); a
:class:`Primitive` one collision shape (box, cylinder, capsule or convex mesh) placed in the
object frame. :func:`box`, :func:`segment` and :func:`mesh_prim` build primitives and
:func:`z_rot` turns them about the vertical, for the catalogues' geometry builders
(:mod:`~ipbench.assets.objects.v1_geometry`, :mod:`~ipbench.assets.objects.family_geometry`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ipbench.assets.objects import meshes

__all__ = ["Primitive", "VisualPart", "box", "mesh_prim", "segment", "z_rot"]


@dataclass(frozen=True, eq=False)
class VisualPart:
    """One visual mesh: ``vertices`` (N, 3) m in the object frame, ``faces`` (M, 3) int.

    v2 parts may carry a texture: ``texcoords`` (N, 2) per-vertex (u, v) in [0, 1] and
    ``texture`` an (H, W, 3) uint8 RGB image (row 0 is v = 0); the material is then white
    so that the texture shows its own colours. v1 parts have neither.
    """

    suffix: str
    vertices: np.ndarray
    faces: np.ndarray
    rgba: tuple[float, float, float, float]
    shiny: bool
    texcoords: np.ndarray | None = None
    texture: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Primitive:
    """A collision shape in the object frame.

    ``kind`` is ``"box"`` (size = 3 half extents), ``"cylinder"`` / ``"capsule"`` (size =
    radius, half length along the local z) or ``"mesh"`` (convex hull of ``mesh``).
    ``pos`` (3,) m and ``rot`` (3, 3) place the local frame; ``density`` is relative.
    """

    kind: str
    pos: np.ndarray
    rot: np.ndarray
    size: tuple[float, ...] = ()
    mesh: meshes.Mesh | None = None
    density: float = 1.0


def z_rot(phi: float) -> np.ndarray:
    """Rotation (3, 3) by ``phi`` (rad) about the z axis."""
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def mesh_prim(mesh: meshes.Mesh, density: float = 1.0) -> Primitive:
    """The convex hull of ``mesh`` as a primitive, in the object frame."""
    return Primitive("mesh", np.zeros(3), np.eye(3), mesh=mesh, density=density)


def box(half, pos, rot=None, density: float = 1.0) -> Primitive:
    """A box of half extents ``half`` (3,) m at ``pos`` (3,), turned by ``rot`` (3, 3)."""
    rot = np.eye(3) if rot is None else rot
    return Primitive("box", np.asarray(pos, float), rot, tuple(map(float, half)), density=density)


def segment(kind: str, p0, p1, radius: float, density: float = 1.0) -> Primitive:
    """Cylinder or capsule whose axis (local z) runs from ``p0`` to ``p1``."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    axis = p1 - p0
    half = float(np.linalg.norm(axis)) / 2
    z = axis / (2 * half)
    x = np.cross([0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    rot = np.column_stack([x, np.cross(z, x), z])
    return Primitive(kind, (p0 + p1) / 2, rot, (float(radius), half), density=density)
