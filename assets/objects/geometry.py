"""An instance's geometry: its visual parts, collision primitives and inertia (pure numpy).

The parts come from the instance's catalogue builder (v1:
:mod:`~ipbench.assets.objects.v1_geometry`; v2, UV-mapped and textured:
:mod:`~ipbench.assets.objects.family_geometry`); the inertia assumes the collision
primitives filled with uniform (relative) density (:func:`object_geometry`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from ipbench.assets.objects import meshes
from ipbench.assets.objects.convex_collision import convex_collision
from ipbench.assets.objects.family_geometry import family_parts
from ipbench.assets.objects.instance import ObjectInstance
from ipbench.assets.objects.object_model import RELEASED_MODEL, ObjectModel
from ipbench.assets.objects.primitives import Primitive, VisualPart
from ipbench.assets.objects.v1_geometry import v1_parts

__all__ = ["ObjectGeometry", "object_geometry"]


@dataclass(frozen=True, eq=False)
class ObjectGeometry:
    """Visual parts, collision primitives and inertia (com (3,) m, inertia (3, 3) kg m^2)."""

    visual: tuple[VisualPart, ...]
    collision: tuple[Primitive, ...]
    com: np.ndarray
    inertia: np.ndarray


def _unit_properties(p: Primitive) -> tuple[float, np.ndarray, np.ndarray]:
    """Volume (m^3), centroid (3,) and unit-density inertia (3, 3) in the object frame."""
    if p.kind == "mesh":
        vol, centroid, inertia = meshes.mass_properties(*meshes.convex_polyhedron(p.mesh[0]))
        return vol, centroid, inertia
    if p.kind == "box":
        a, b, c = p.size
        vol = 8 * a * b * c
        local = vol / 3 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])
    else:
        r, hl = p.size
        vc = np.pi * r * r * 2 * hl
        axial, perp = vc * r * r / 2, vc * (3 * r * r + 4 * hl * hl) / 12
        vol = vc
        if p.kind == "capsule":
            vs = 4 / 3 * np.pi * r**3
            vol += vs
            axial += 0.4 * vs * r * r
            perp += vs * (83 / 320 * r * r + (hl + 3 * r / 8) ** 2)
        local = np.diag([perp, perp, axial])
    return vol, p.pos, p.rot @ local @ p.rot.T


def _inertia(prims: tuple[Primitive, ...], mass: float) -> tuple[np.ndarray, np.ndarray]:
    props = [(_unit_properties(p), p.density) for p in prims]
    weights = np.array([vol * rho for (vol, _, _), rho in props])
    scale = mass / weights.sum()
    com = sum(w * c for w, ((_, c, _), _) in zip(weights, props, strict=True)) / weights.sum()
    total = np.zeros((3, 3))
    for w, ((_, c, inertia), rho) in zip(weights, props, strict=True):
        dvec = c - com
        total += scale * (rho * inertia + w * (dvec @ dvec * np.eye(3) - np.outer(dvec, dvec)))
    return com, total


@cache
def object_geometry(inst: ObjectInstance, model: ObjectModel = RELEASED_MODEL) -> ObjectGeometry:
    """Visual parts, collision primitives and inertia of ``inst`` under ``model`` (cached).

    The inertia assumes the thin-wall collision primitives of the released model filled with
    uniform (relative) density, scaled so that the mass is exactly ``inst.mass``; it is the
    same under every :class:`~ipbench.assets.objects.object_model.ObjectModel` (a model changes
    how an object collides and looks, not how it is built).
    """
    if inst.catalog == "v1":
        visual, collision = v1_parts(inst)
    else:
        visual, collision = family_parts(inst, upright_prints=model.upright_prints)
    com, inertia = _inertia(collision, inst.mass)
    if model.hollow_collision == "convex":
        collision = convex_collision(inst, collision)
    return ObjectGeometry(tuple(visual), tuple(collision), com, inertia)
