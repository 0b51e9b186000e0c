"""Visual meshes and collision primitives of v1 instances, in their object frame (pure numpy).

Visual parts are low-poly meshes (≤ 800 faces per object). Collision is a set of primitives:
convex shapes use one convex mesh or a box; concave ones (bowl, mug) use a ring of
``RING_SEGMENTS`` thin boxes for the wall, a cylinder for the bottom and capsules for the
mug's handle, so that things can rest inside them. The v2 families reuse the collision of
the shapes they share with v1 (:mod:`~ipbench.assets.objects.family_geometry`).
"""

from __future__ import annotations

import numpy as np

from ipbench.assets.objects import meshes
from ipbench.assets.objects.instance import ObjectInstance
from ipbench.assets.objects.params import (
    BottleShape,
    BowlShape,
    CartonShape,
    JuiceBoxShape,
    MugShape,
)
from ipbench.assets.objects.primitives import Primitive, VisualPart, box, mesh_prim, segment, z_rot

__all__ = ["RING_SEGMENTS", "v1_parts"]

_LATHE_SEGMENTS = 24
RING_SEGMENTS = 16
"""Boxes in the collision wall of bowls and mugs; also the sides of the bottle's hull."""


def _bottle(s: BottleShape, inst: ObjectInstance):
    r, rn = s.radius, s.neck_radius
    bevel = min(0.004, 0.1 * r)
    ts = np.linspace(0.25, 1.0, 4)
    shoulder = [
        (rn + (r - rn) * np.cos(t * np.pi / 2), s.body_top + t * (s.neck_bottom - s.body_top))
        for t in ts
    ]
    lower = [(0, 0), (r - bevel, 0), (r, bevel), (r, s.label_bottom)]
    upper = [(r, s.label_top), (r, s.body_top), *shoulder, (rn, s.cap_bottom)]
    body = meshes.merge(meshes.lathe(lower, _LATHE_SEGMENTS), meshes.lathe(upper, _LATHE_SEGMENTS))
    label = meshes.lathe([(r, s.label_bottom), (r, s.label_top)], _LATHE_SEGMENTS)
    rc, ch = s.cap_radius, 0.1 * (s.height - s.cap_bottom)
    cap = meshes.lathe(
        [
            (0, s.cap_bottom),
            (rc, s.cap_bottom),
            (rc, s.height - ch),
            (rc - ch, s.height),
            (0, s.height),
        ],
        16,
    )
    visual = (
        VisualPart("body", *body, inst.rgba, False),
        VisualPart("label", *label, inst.accent_rgba, False),
        VisualPart("cap", *cap, inst.accent_rgba, False),
    )
    hull = [
        (0, 0),
        (r, 0),
        (r, s.body_top),
        *shoulder,
        (rc, s.cap_bottom),
        (rc, s.height),
        (0, s.height),
    ]
    return visual, (mesh_prim(meshes.lathe(hull, RING_SEGMENTS)),)


def _carton(s: CartonShape, inst: ObjectInstance):
    a, hs = s.base / 2, s.shoulder
    ridge = hs + s.gable
    square = np.array([(-a, -a), (a, -a), (a, a), (-a, a)])
    bottom = (np.column_stack([square, np.zeros(4)]), np.array([[0, 2, 1], [0, 3, 2]]))
    roof_pts = np.vstack(
        [np.column_stack([square, np.full(4, hs)]), [(-a, 0, ridge), (a, 0, ridge)]]
    )
    rv, rf = meshes.convex_polyhedron(roof_pts)
    normal_z = np.cross(rv[rf[:, 1]] - rv[rf[:, 0]], rv[rf[:, 2]] - rv[rf[:, 0]])[:, 2]
    roof = (rv, rf[normal_z > -1e-12])  # drop the hidden base
    ft = s.fin_thickness / 2
    fin_pts = [
        (x, y, z) for x in (-a, a) for y in (-ft, ft) for z in (ridge - s.gable / 2, ridge + s.fin)
    ]
    white = meshes.merge(
        bottom,
        meshes.prism_sides(square, 0.0, s.band_bottom),
        meshes.prism_sides(square, s.band_top, hs),
        roof,
        meshes.convex_polyhedron(np.array(fin_pts)),
    )
    band = meshes.prism_sides(square, s.band_bottom, s.band_top)
    visual = (
        VisualPart("body", *white, inst.rgba, False),
        VisualPart("band", *band, inst.accent_rgba, False),
    )
    top = np.vstack([roof_pts[4:], [(x, y, ridge + s.fin) for x in (-a, a) for y in (-ft, ft)]])
    roof_hull = meshes.convex_polyhedron(np.vstack([roof_pts[:4], top]))
    collision = (box((a, a, hs / 2), (0, 0, hs / 2)), mesh_prim(roof_hull, density=0.1))
    return visual, collision


def _bowl(s: BowlShape, inst: ObjectInstance):
    t, tb, rim, foot, h = s.wall, s.bottom, s.rim_radius, s.foot_radius, s.height
    beta = np.arctan2(rim - foot, h - tb)  # wall angle from the vertical
    c, sn = np.cos(beta), np.sin(beta)
    outer = [(0, 0), (foot, 0), (foot, tb - t * sn), (rim, h - t * sn), (rim - t * c, h)]
    inner = [(rim - t * c, h), (foot - t * c, tb), (0, tb)]
    visual = (
        VisualPart("outer", *meshes.lathe(outer, _LATHE_SEGMENTS), inst.rgba, inst.specular),
        VisualPart("inner", *meshes.lathe(inner, _LATHE_SEGMENTS), inst.accent_rgba, inst.specular),
    )
    # Wall plates: outer face on the outer line, from the foot to the rim.
    centre_r = 0.5 * (foot + rim) - 0.5 * t * c
    centre_z = 0.5 * (tb + h) - 0.5 * t * sn
    half = (rim * np.tan(np.pi / RING_SEGMENTS), 0.5 * (h - tb) / c, t / 2)
    local = np.array(
        [[0.0, sn, c], [1.0, 0.0, 0.0], [0.0, c, -sn]]
    )  # columns: tangent, up-slope, normal
    plates = []
    for k in range(RING_SEGMENTS):
        rz = z_rot(2 * np.pi * k / RING_SEGMENTS)
        plates.append(box(half, rz @ [centre_r, 0.0, centre_z], rz @ local))
    disc = segment("cylinder", (0, 0, 0), (0, 0, tb), foot)
    return visual, (disc, *plates)


def _mug(s: MugShape, inst: ObjectInstance):
    r, t, tb, h = s.radius, s.wall, s.bottom, s.height
    bevel = 0.002
    outer = [(0, 0), (r - bevel, 0), (r, bevel), (r, h), (r - t, h)]
    inner = [(r - t, h), (r - t, tb), (0, tb)]
    # D-shaped handle: half a superellipse (exponent 4) from the top to the bottom attachment.
    x0, rh = r - t / 2, s.handle_radius
    ax, az = r + s.handle_reach - rh - x0, (s.handle_top - s.handle_bottom) / 2
    zc = (s.handle_top + s.handle_bottom) / 2
    u = np.linspace(np.pi / 2, -np.pi / 2, 11)
    cu, su = np.cos(u), np.sin(u)
    path = np.column_stack(
        [
            x0 + ax * np.sqrt(np.abs(cu)),
            np.zeros_like(u),
            zc + az * np.sign(su) * np.sqrt(np.abs(su)),
        ]
    )
    visual = (
        VisualPart("outer", *meshes.lathe(outer, _LATHE_SEGMENTS), inst.rgba, inst.specular),
        VisualPart("inner", *meshes.lathe(inner, _LATHE_SEGMENTS), inst.accent_rgba, inst.specular),
        VisualPart("handle", *meshes.tube(path, rh, 6), inst.rgba, inst.specular),
    )
    half = (t / 2, r * np.tan(np.pi / RING_SEGMENTS), (h - tb / 2) / 2)
    walls = []
    for k in range(RING_SEGMENTS):
        rz = z_rot(2 * np.pi * (k + 0.5) / RING_SEGMENTS)  # a seam, not a face, faces the handle
        walls.append(box(half, rz @ [r - t / 2, 0.0, (h + tb / 2) / 2], rz))
    disc = segment("cylinder", (0, 0, 0), (0, 0, tb), r - 0.0005)
    knots = path[::2]
    handle = [segment("capsule", p, q, rh) for p, q in zip(knots[:-1], knots[1:], strict=True)]
    return visual, (disc, *walls, *handle)


def _juice_box(s: JuiceBoxShape, inst: ObjectInstance):
    w, d, h, rs, m = s.width / 2, s.depth / 2, s.height, s.straw_radius, s.straw_margin
    corners = np.array([(x, y, z) for x in (-w, w) for y in (-d, d) for z in (0.0, h)])
    sign = -1.0 if s.straw_mirror else 1.0
    p0, p1 = (-sign * (w - m), d + rs, m), (sign * (w - m), d + rs, h - m)
    visual = (
        VisualPart("box", *meshes.convex_polyhedron(corners), inst.rgba, False),
        VisualPart("straw", *meshes.cylinder_between(p0, p1, rs, 8), inst.accent_rgba, False),
    )
    straw = segment("capsule", p0, p1, rs, density=0.05)
    return visual, (box((w, d, h / 2), (0, 0, h / 2)), straw)


_BUILDERS = {
    BottleShape: _bottle,
    CartonShape: _carton,
    BowlShape: _bowl,
    MugShape: _mug,
    JuiceBoxShape: _juice_box,
}


def v1_parts(inst: ObjectInstance) -> tuple[tuple[VisualPart, ...], tuple[Primitive, ...]]:
    """Visual parts and collision primitives of a v1 instance."""
    return _BUILDERS[type(inst.shape)](inst.shape, inst)
