"""Visual meshes (UV-mapped, textured) and collision primitives of v2 instances.

Each shape type has a builder returning its visual meshes with a *role* and its collision
primitives (graspable: convex meshes, boxes, cylinders, capsules; bowls and mugs as rings of
thin boxes like v1, so things rest inside them). :func:`family_parts` then colours the roles
and gives each textured role its procedural texture
(:func:`ipbench.assets.objects.textures.make_texture`, seeded from the instance name).

Texture sizes (H x W): labels 128 x 256, glass and glaze 128 x 128, carton and box prints
256 x 256 — at most 0.2 MB of texture per instance.

Print orientation: a texture's row 0 is the top of its print and its column 0 is u = 0
(:mod:`~ipbench.assets.objects.textures`), and MuJoCo puts row 0 at v = 0. On a lofted or
lathed part v grows with height (rings bottom to top, :mod:`~ipbench.assets.objects.uv_meshes`)
while u runs to the right seen from outside, so the released mapping shows every print mirrored
top to bottom (text in reading order but each line upside down, a picture's sun under its
hills). ``upright_prints`` maps v to 1 - v on every textured part whose v grows with height
(:func:`_upright_texcoords`), which turns the print upright without mirroring it; the images
themselves are the same under both mappings.
"""

from __future__ import annotations

import hashlib

import numpy as np

from ipbench.assets.objects import meshes
from ipbench.assets.objects import primitives as prim
from ipbench.assets.objects import uv_meshes as uvm
from ipbench.assets.objects import v1_geometry as v1
from ipbench.assets.objects.family_shapes import (
    BrikShape,
    FootedBowlShape,
    ProfileMugShape,
    SquareBottleShape,
)
from ipbench.assets.objects.instance import ObjectInstance
from ipbench.assets.objects.params import BottleShape, BowlShape, CartonShape
from ipbench.assets.objects.textures import make_texture

__all__ = ["TEXTURE_SIZES", "family_parts", "visual_bounds"]

TEXTURE_SIZES: dict[str, tuple[int, int]] = {
    "bottle_label": (128, 256),
    "glass": (128, 128),
    "glaze": (128, 128),
    "carton_print": (256, 256),
    "box_print": (256, 256),
}
"""(H, W) of each texture kind."""

_SEG = 24  # lathe segments, as v1
_K = 28  # outline points of the square bottle
# role -> (colour, texture kind or None); "body" and "label" kinds depend on the shape
_PLAIN = {"plain": "rgba", "accent": "accent_rgba", "inner": "accent_rgba"}


def _mug_radius(s: ProfileMugShape, z: float) -> float:
    h2 = s.height / 2
    if z <= h2:
        return s.radius_bottom + (s.radius_middle - s.radius_bottom) * z / h2
    return s.radius_middle + (s.radius_top - s.radius_middle) * (z - h2) / h2


def _cap(s) -> meshes.Mesh:
    rc, ch = s.cap_radius, 0.1 * (s.height - s.cap_bottom)
    prof = [(0, s.cap_bottom), (rc, s.cap_bottom), (rc, s.height - ch), (rc - ch, s.height),
            (0, s.height)]  # fmt: skip
    return meshes.lathe(prof, 16)


def _bottle(s: BottleShape, glass: bool):
    r, rn = s.radius, s.neck_radius
    bevel = min(0.004, 0.1 * r)
    ts = np.linspace(0.25, 1.0, 4)
    rise = s.neck_bottom - s.body_top
    shoulder = [(rn + (r - rn) * np.cos(t * np.pi / 2), s.body_top + t * rise) for t in ts]
    body = [(0, 0), (r - bevel, 0), (r, bevel), (r, s.label_bottom), (r, s.label_top),
            (r, s.body_top), *shoulder, (rn, s.cap_bottom)]  # fmt: skip
    parts = [
        ("body", uvm.lathe_uv(body, _SEG), "glass" if glass else None),
        ("label", uvm.lathe_uv([(r + 2e-4, s.label_bottom), (r + 2e-4, s.label_top)], _SEG),
         "bottle_label"),
        ("cap", (*_cap(s), None), None),
    ]  # fmt: skip
    return parts, None  # collision: v1's hull


def _square_bottle(s: SquareBottleShape):
    a, rn, k = s.side / 2, s.neck_radius, _K
    sq, rnd = uvm.rounded_square(a, s.corner_radius, k), uvm.circle(1.0, k)
    bevel = min(0.004, 0.1 * a)
    ts = np.linspace(0.25, 1.0, 4)
    blend = 1 - np.cos(ts * np.pi / 2)  # 0 at the body, 1 at the neck, as the round shoulder
    shoulder = [(1 - b) * sq + b * rn * rnd for b in blend]
    zs_sh = s.body_top + ts * (s.neck_bottom - s.body_top)
    body = uvm.loft(
        [np.zeros((k, 2)), sq * (1 - bevel / a), sq, sq, sq, sq, *shoulder, rn * rnd],
        [0.0, 0.0, bevel, s.label_bottom, s.label_top, s.body_top, *zs_sh, s.cap_bottom],
    )
    label = uvm.loft([sq * (1 + 2e-4 / a)] * 2, [s.label_bottom, s.label_top])
    parts = [
        ("body", body, None),
        ("label", label, "bottle_label"),
        ("cap", (*_cap(s), None), None),
    ]
    coarse = uvm.rounded_square(a, s.corner_radius, 16)
    pts = [np.column_stack([coarse, np.full(16, z)]) for z in (0.0, s.body_top)]
    for b, z in zip(blend[:-1], zs_sh[:-1], strict=True):
        ring = (1 - b) * coarse + b * rn * uvm.circle(1.0, 16)
        pts.append(np.column_stack([ring, np.full(16, z)]))
    pts += [np.column_stack([s.cap_radius * uvm.circle(1.0, 12), np.full(12, z)])
            for z in (s.neck_bottom, s.height)]  # fmt: skip
    hull = meshes.convex_polyhedron(np.vstack(pts))
    return parts, (prim.mesh_prim(hull),)


def _carton(s: CartonShape):
    a, hs = s.base / 2, s.shoulder
    ridge = hs + s.gable
    square = np.array([(a, -a), (a, a), (-a, a), (-a, -a)])
    sides = uvm.loft([square, square], [0.0, hs], u=np.linspace(0.0, 1.0, 5))
    bottom = (np.column_stack([square, np.zeros(4)]), np.array([[0, 2, 1], [0, 3, 2]]))
    roof_pts = np.vstack(
        [np.column_stack([square, np.full(4, hs)]), [(-a, 0, ridge), (a, 0, ridge)]]
    )
    rv, rf = meshes.convex_polyhedron(roof_pts)
    normal_z = np.cross(rv[rf[:, 1]] - rv[rf[:, 0]], rv[rf[:, 2]] - rv[rf[:, 0]])[:, 2]
    ft = s.fin_thickness / 2
    fin = [
        (x, y, z) for x in (-a, a) for y in (-ft, ft) for z in (ridge - s.gable / 2, ridge + s.fin)
    ]
    ends = meshes.merge(
        bottom, (rv, rf[normal_z > -1e-12]), meshes.convex_polyhedron(np.array(fin))
    )
    parts = [("sides", sides, "carton_print"), ("ends", (*ends, None), None)]
    return parts, v1._carton(s, _Dummy)[1]


class _Dummy:
    """Stands in for an instance in v1 builders whose colours are not used."""

    rgba = accent_rgba = (1.0, 1.0, 1.0, 1.0)
    specular = False


def _bowl_profiles(rim, foot, h, t, tb, z0=0.0):
    beta = np.arctan2(rim - foot, h - tb)
    c, sn = np.cos(beta), np.sin(beta)
    outer = [(foot, z0 + tb - t * sn), (rim, z0 + h - t * sn), (rim - t * c, z0 + h)]
    inner = [(rim - t * c, z0 + h), (foot - t * c, z0 + tb), (0, z0 + tb)]
    return outer, inner


def _bowl(s: BowlShape):
    outer, inner = _bowl_profiles(s.rim_radius, s.foot_radius, s.height, s.wall, s.bottom)
    parts = [
        ("outer", uvm.lathe_uv([(0, 0), (s.foot_radius, 0), *outer], _SEG), "glaze"),
        ("inner", (*meshes.lathe(inner, _SEG), None), None),
    ]
    return parts, v1._bowl(s, _Dummy)[1]


def _footed_bowl(s: FootedBowlShape):
    fh, hb = s.foot_height, s.height - s.foot_height
    outer, inner = _bowl_profiles(s.rim_radius, s.bowl_radius, hb, s.wall, s.bottom, fh)
    prof = [(0, 0), (s.foot_radius, 0), (s.foot_radius, fh), (s.bowl_radius, fh), *outer]
    parts = [
        ("outer", uvm.lathe_uv(prof, _SEG), "glaze"),
        ("inner", (*meshes.lathe(inner, _SEG), None), None),
    ]
    bowl = BowlShape(s.rim_radius, s.bowl_radius, hb, s.wall, s.bottom)
    lifted = [
        prim.Primitive(p.kind, p.pos + [0.0, 0.0, fh], p.rot, p.size, p.mesh, p.density)
        for p in v1._bowl(bowl, _Dummy)[1]
    ]
    foot = prim.segment("cylinder", (0, 0, 0), (0, 0, fh), s.foot_radius)
    return parts, (foot, *lifted)


def _plates(p0, p1, t: float, phase: float) -> list:
    """A ring of RING_SEGMENTS boxes whose outer faces lie on the wall line (r, z) p0 -> p1."""
    (r0, z0), (r1, z1) = p0, p1
    beta = np.arctan2(r1 - r0, z1 - z0)
    c, sn = np.cos(beta), np.sin(beta)
    n = v1.RING_SEGMENTS
    half = (max(r0, r1) * np.tan(np.pi / n), 0.5 * np.hypot(r1 - r0, z1 - z0), t / 2)
    centre = (0.5 * (r0 + r1) - 0.5 * t * c, 0.5 * (z0 + z1) + 0.5 * t * sn)
    local = np.array([[0.0, sn, c], [1.0, 0.0, 0.0], [0.0, c, -sn]])
    out = []
    for k in range(n):
        rz = prim.z_rot(2 * np.pi * (k + phase) / n)
        out.append(prim.box(half, rz @ [centre[0], 0.0, centre[1]], rz @ local))
    return out


def _mug(s: ProfileMugShape):
    t, tb, h = s.wall, s.bottom, s.height
    rb, rm, rt = s.radius_bottom, s.radius_middle, s.radius_top
    bevel = 0.002
    outer = [(0, 0), (rb - bevel, 0), (rb, bevel), (rm, h / 2), (rt, h), (rt - t, h)]
    inner = [(rt - t, h), (rm - t, h / 2), (_mug_radius(s, tb) - t, tb), (0, tb)]
    x_top, x_bot = _mug_radius(s, s.handle_top) - t / 2, _mug_radius(s, s.handle_bottom) - t / 2
    reach = max(rb, rm, rt) + s.handle_reach - s.handle_radius
    az, zc = (s.handle_top - s.handle_bottom) / 2, (s.handle_top + s.handle_bottom) / 2
    u = np.linspace(np.pi / 2, -np.pi / 2, 11)
    z = zc + az * np.sign(np.sin(u)) * np.sqrt(np.abs(np.sin(u)))
    x0 = x_bot + (x_top - x_bot) * (z - s.handle_bottom) / (s.handle_top - s.handle_bottom)
    path = np.column_stack([x0 + (reach - x0) * np.sqrt(np.abs(np.cos(u))), np.zeros_like(u), z])
    handle = meshes.tube(path, s.handle_radius, 6)
    hv = np.linspace(0, 1, len(path)).repeat(6)
    hu = np.tile(np.arange(6) / 6, len(path))
    parts = [
        ("outer", uvm.lathe_uv(outer, _SEG), "glaze"),
        ("inner", (*meshes.lathe(inner, _SEG), None), None),
        ("handle", (*handle, np.column_stack([hu, hv])), "glaze"),
    ]
    zl = tb / 2
    walls = _plates((_mug_radius(s, zl), zl), (rm, h / 2), t, 0.5)
    walls += _plates((rm, h / 2), (rt, h), t, 0.5)
    disc = prim.segment("cylinder", (0, 0, 0), (0, 0, tb), rb - 0.0005)
    knots = path[::2]
    grip = [
        prim.segment("capsule", p, q, s.handle_radius)
        for p, q in zip(knots[:-1], knots[1:], strict=True)
    ]
    return parts, (disc, *walls, *grip)


def _brik(s: BrikShape):
    w, d, h = s.width / 2, s.depth / 2, s.height
    outline = uvm.octagon(s.width, s.depth, s.chamfer)
    sides = uvm.loft([outline, outline], [0.0, h], u=uvm.octagon_u(s.width, s.depth, s.chamfer))
    ends = meshes.merge(uvm.polygon_fan(outline, 0.0, False), uvm.polygon_fan(outline, h, True))
    parts = [("box", sides, "box_print"), ("ends", (*ends, None), None)]
    if s.chamfer > 0:
        pts = np.vstack([np.column_stack([outline, np.full(len(outline), z)]) for z in (0.0, h)])
        collision = [prim.mesh_prim(meshes.convex_polyhedron(pts))]
    else:
        collision = [prim.box((w, d, h / 2), (0, 0, h / 2))]
    if s.straw_radius > 0:
        rs, m = s.straw_radius, s.straw_margin
        sign = -1.0 if s.straw_mirror else 1.0
        xm = w - m - s.chamfer
        p0, p1 = (-sign * xm, d + rs, m), (sign * xm, d + rs, h - m)
        parts.append(("straw", (*meshes.cylinder_between(p0, p1, rs, 8), None), None))
        collision.append(prim.segment("capsule", p0, p1, rs, density=0.05))
    if s.cap_height > 0:
        x = w - s.cap_radius - 0.006 - s.chamfer / 2
        cap = meshes.cylinder_between((x, 0, h), (x, 0, h + s.cap_height), s.cap_radius, 12)
        parts.append(("cap", (*cap, None), None))
        collision.append(
            prim.segment("cylinder", (x, 0, h), (x, 0, h + s.cap_height), s.cap_radius, 0.3)
        )
    return parts, tuple(collision)


def _parts(shape, family: str = ""):
    if isinstance(shape, BottleShape):
        return _bottle(shape, glass=family == "glass_short")
    if isinstance(shape, SquareBottleShape):
        return _square_bottle(shape)
    if isinstance(shape, CartonShape):
        return _carton(shape)
    if isinstance(shape, BowlShape):
        return _bowl(shape)
    if isinstance(shape, FootedBowlShape):
        return _footed_bowl(shape)
    if isinstance(shape, ProfileMugShape):
        return _mug(shape)
    if isinstance(shape, BrikShape):
        return _brik(shape)
    raise TypeError(f"no v2 geometry for {type(shape).__name__}")


def visual_bounds(shape) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(size, center) of the axis-aligned bounding box of the visual meshes of ``shape``, m."""
    pts = np.vstack([mesh[0] for _, mesh, _ in _parts(shape)[0]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    size, center = hi - lo, (hi + lo) / 2
    return tuple(float(v) for v in size), tuple(float(v) + 0.0 for v in center)


def _texture(inst: ObjectInstance, kind: str) -> np.ndarray:
    digest = hashlib.sha256(f"ipbench.objects/v2/texture/{inst.name}/{kind}".encode()).digest()
    seed = int.from_bytes(digest[:8], "little")
    base, accent = inst.rgba[:3], inst.accent_rgba[:3]
    if kind == "bottle_label":
        base, accent = accent, base
    return np.ascontiguousarray(make_texture(kind, seed, base, accent, TEXTURE_SIZES[kind]))


def _upright_texcoords(vertices: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Texture coordinates (N, 2) that put a print's row 0 (its top) at the top of the part:
    ``uv`` with v mapped to 1 - v where v grows with height (``vertices`` (N, 3) m), else
    ``uv`` as it is (a mug handle's v already runs down from its top)."""
    v, z = uv[:, 1], vertices[:, 2]
    if np.mean((v - v.mean()) * (z - z.mean())) <= 0:
        return uv
    return np.column_stack([uv[:, 0], 1.0 - v])


def family_parts(
    inst: ObjectInstance, upright_prints: bool = False
) -> tuple[tuple[prim.VisualPart, ...], tuple[prim.Primitive, ...]]:
    """Visual parts (with textures) and collision primitives of a v2 instance
    (``upright_prints``: see :class:`~ipbench.assets.objects.object_model.ObjectModel`)."""
    parts, collision = _parts(inst.shape, inst.family)
    if collision is None:  # round bottles: the v1 hull
        collision = v1._bottle(inst.shape, inst)[1]
    textures: dict[str, np.ndarray] = {}
    visual = []
    for suffix, (v, f, uv), kind in parts:
        rgba = inst.accent_rgba if suffix in ("inner", "cap", "straw") else inst.rgba
        shiny = inst.specular and suffix in ("outer", "inner", "handle")
        if kind is None:
            visual.append(prim.VisualPart(suffix, v, f, rgba, shiny))
            continue
        if kind not in textures:
            textures[kind] = _texture(inst, kind)
        uv = np.asarray(uv, float)
        if upright_prints:
            uv = _upright_texcoords(np.asarray(v, float), uv)
        visual.append(prim.VisualPart(suffix, v, f, rgba, shiny, uv, textures[kind]))
    return tuple(visual), tuple(collision)
