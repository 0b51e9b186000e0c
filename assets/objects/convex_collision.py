"""Hollow objects (bowls, mugs) as a few convex pieces each (``ObjectModel(hollow_collision=
"convex")``, ``Sorting-v3``).

The released model builds the wall of a v2 bowl or mug as rings of 16 thin boxes per straight
wall section (:mod:`~ipbench.assets.objects.family_geometry`): 17 collision geoms per bowl, 18
per footed bowl, 38 per mug, and an object touching a wall meets several boxes at once. Here a
wall of revolution is cut into :data:`SECTORS` angular sectors per straight section, each piece
the convex hull of its sector of the visual wall (:func:`wall_pieces`); the released bottom
cylinder (and a footed bowl's foot ring) becomes a prism on the visual 24-gon
(:func:`disc_piece`), and a mug's handle :data:`HANDLE_PIECES` hulls of its visual tube.
Pieces: 9 per bowl, 10 per footed bowl, 12 per mug, 20 per barrel mug (its wall has two
sections). Every piece is a convex mesh: MuJoCo gives two polytopes that touch along an edge or
a face a contact at each corner of the touch (multi-point convex collision, on by default in
MuJoCo 4 and enabled in the work cell's MJCF), but a box's edge on a cylinder's flat face one
contact only, about which a cube leaning against a footed bowl's wall keeps rocking.

A wall or handle piece's points are vertices of the visual meshes (the wall profile's outer
corners and its inner top corner at the visual lathe's angles, its inner bottom corner at the
sector's two ends; the handle tube's rings), so the pieces lie inside the visual bounds, and
the outer wall, the rim and the handle are the visual ones exactly (a sector spans
``24 / SECTORS`` facets of the visual 24-gon; each facet of a conical wall is a plane
trapezoid). Only the cavity side differs: a sector's inner facets become one chord plane,
which stands into the cavity by at most ``r_in (cos(pi / 24) - cos(pi / SECTORS))`` beyond
the visual inner wall (``r_in``: the inner radius at the rim). Over the v2 catalogue, with 8
sectors: 4.4-6.1 mm in bowls (walls 4.5-5.5 mm), 2.2-2.9 mm in mugs; the cavity loses
8.9-9.4 % of its volume, the wall gains 26-50 %. A sector's side faces are plane (the profile
in its half-plane), so neighbouring pieces share a face and do not overlap. The handle's hulls
fill the inside of the D's bends by at most 3.6 mm (its opening: 15-25 mm).

Why 8 sectors: the pieces must be few (every pair of touching pieces is one narrow-phase
collision with up to several contacts), the outer surface must be the visual one (the jaws
close on it), and a sector must span whole facets of the visual 24-gon (6, 8, 12 or 24
sectors). 6 sectors cut up to 11.3 mm into a bowl's cavity (twice the wall) and take 16 % of
its cross-section; 8 cut 6.1 mm (about one wall) and take 8.9 %; 12 cut 2.3 mm and take 3.4 %,
at 1.5 x the wall pieces and, over drop tests on two instances of every family (cubes and a
juice box into them, one onto another, lying on the side), 17 % more contacts per step than 8
(6: 14 % fewer).

Mass, centre of mass and inertia do not come from these pieces
(:func:`~ipbench.assets.objects.geometry.object_geometry` computes them from the released
primitives first).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ipbench.assets.objects import family_geometry as fg
from ipbench.assets.objects import meshes
from ipbench.assets.objects import primitives as prim
from ipbench.assets.objects.family_shapes import FootedBowlShape, ProfileMugShape
from ipbench.assets.objects.instance import ObjectInstance
from ipbench.assets.objects.params import BowlShape

__all__ = ["HANDLE_PIECES", "SECTORS", "convex_collision", "disc_piece", "wall_pieces"]

SECTORS: int = 8
"""Angular sectors of a wall of revolution (a divisor of the visual lathe's 24 facets)."""

HANDLE_PIECES: tuple[tuple[int, int], ...] = ((0, 3), (3, 7), (7, 10))
"""Rings (first, last; inclusive) of the visual handle tube's 11 whose hull is one piece: the
upper arm, the grip and the lower arm of the D."""

_COLLINEAR = 1e-7  # m: a mug profile's middle point this close to the chord lies on it


def wall_pieces(
    outer: Sequence[tuple[float, float]],
    inner: Sequence[tuple[float, float]],
    sectors: int = SECTORS,
    z_lift: float = 0.0,
) -> list[prim.Primitive]:
    """One convex piece per angular sector of a straight wall section.

    Parameters
    ----------
    outer : (r, z) ends of the outer wall line, bottom then top, m.
    inner : (r, z) ends of the inner wall line, bottom then top, m.
    sectors : number of sectors, a divisor of the visual lathe's 24 segments.
    z_lift : added to every z, m.

    Returns
    -------
    ``sectors`` mesh primitives in the object frame; sector ``k`` spans the angles
    ``2 pi [k, k + 1] / sectors`` (a sector boundary on +x, where a mug's handle is). Each is
    the hull of the outer line's ends and the inner line's top at every visual lathe angle of
    the sector (so a bowl's sloping rim is the visual one) and of the inner line's bottom at
    the sector's two ends.
    """
    if sectors < 3 or fg._SEG % sectors:
        raise ValueError(f"sectors must be a divisor of {fg._SEG} from 3 up, got {sectors}")
    per = fg._SEG // sectors
    (rb, zb), top = inner
    out = []
    for k in range(sectors):
        phi = 2 * np.pi * np.arange(k * per, (k + 1) * per + 1) / fg._SEG
        pts = [(r * np.cos(p), r * np.sin(p), z + z_lift) for r, z in (*outer, top) for p in phi]
        pts += [(rb * np.cos(p), rb * np.sin(p), zb + z_lift) for p in phi[[0, -1]]]
        out.append(prim.mesh_prim(meshes.convex_polyhedron(np.array(pts))))
    return out


def disc_piece(radius: float, z0: float, z1: float) -> prim.Primitive:
    """The released bottom cylinder (``radius``, from ``z0`` to ``z1``, m) as the prism on the
    visual lathe's 24-gon: a polytope, so that an object resting on it on an edge gets a
    contact at each end of the edge (MuJoCo's multi-point convex collision), as on the walls."""
    phi = 2 * np.pi * np.arange(fg._SEG) / fg._SEG
    ring = np.column_stack([radius * np.cos(phi), radius * np.sin(phi)])
    pts = np.vstack([np.column_stack([ring, np.full(fg._SEG, z)]) for z in (z0, z1)])
    return prim.mesh_prim(meshes.convex_polyhedron(pts))


def _bowl(s: BowlShape, z0: float = 0.0) -> list[prim.Primitive]:
    outer, inner = fg._bowl_profiles(s.rim_radius, s.foot_radius, s.height, s.wall, s.bottom)
    disc = disc_piece(s.foot_radius, z0, z0 + s.bottom)
    return [disc, *wall_pieces(outer[:2], inner[1::-1], z_lift=z0)]


def _footed_bowl(s: FootedBowlShape) -> list[prim.Primitive]:
    fh = s.foot_height
    bowl = BowlShape(s.rim_radius, s.bowl_radius, s.height - fh, s.wall, s.bottom)
    return [disc_piece(s.foot_radius, 0.0, fh), *_bowl(bowl, fh)]


def _mug_sections(s: ProfileMugShape) -> list[list[tuple[float, float]]]:
    """The outer wall line's straight sections, from half the bottom's thickness (where the
    released walls start, so that upright only the bottom disc meets the table) to the rim:
    one for straight and tapered mugs, two (lower, upper) for a barrel."""
    heights = (s.bottom / 2, s.height / 2, s.height)
    (r0, z0), (r1, z1), (r2, z2) = [(fg._mug_radius(s, z), z) for z in heights]
    bend = abs((r1 - r0) * (z2 - z0) - (r2 - r0) * (z1 - z0)) / np.hypot(r2 - r0, z2 - z0)
    if bend > _COLLINEAR:
        return [[(r0, z0), (r1, z1)], [(r1, z1), (r2, z2)]]
    return [[(r0, z0), (r2, z2)]]


def _mug(s: ProfileMugShape) -> list[prim.Primitive]:
    walls = [
        piece
        for sec in _mug_sections(s)
        for piece in wall_pieces(sec, [(r - s.wall, z) for r, z in sec])
    ]
    disc = disc_piece(s.radius_bottom - 0.0005, 0.0, s.bottom)  # the released disc
    verts, faces, _ = next(mesh for role, mesh, _ in fg._parts(s)[0] if role == "handle")
    sides = len(verts) - len(faces) // 2  # meshes.tube: K rings of n, 2 n (K - 1) faces
    rings = verts.reshape(-1, sides, 3)
    if len(rings) != HANDLE_PIECES[-1][1] + 1:
        raise ValueError(f"the handle tube has {len(rings)} rings, HANDLE_PIECES cuts 11")
    grip = [
        prim.mesh_prim(meshes.convex_polyhedron(rings[a : b + 1].reshape(-1, 3)))
        for a, b in HANDLE_PIECES
    ]
    return [disc, *walls, *grip]


def convex_collision(
    inst: ObjectInstance, released: tuple[prim.Primitive, ...]
) -> tuple[prim.Primitive, ...]:
    """The collision pieces of ``inst``: convex pieces for a v2 bowl or mug (see the module
    docstring), ``released`` (its released primitives, returned as they are) for every other
    instance, v1 bowls and mugs included."""
    if inst.catalog != "v2":
        return released
    s = inst.shape
    if isinstance(s, BowlShape):
        return tuple(_bowl(s))
    if isinstance(s, FootedBowlShape):
        return tuple(_footed_bowl(s))
    if isinstance(s, ProfileMugShape):
        return tuple(_mug(s))
    return released
