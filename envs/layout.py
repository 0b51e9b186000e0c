"""Seeded object layouts of the sorting scenes (thesis Table 5.1), without simulation.

A layout says which instance stands where and how: the scene's composition per category
(:mod:`ipbench.envs.sorting_scenes`), instances drawn from the whole catalogue (known and
unknown ones both appear), and poses sampled inside the work table's spawn area from the seed.
*Uncluttered*: upright objects well apart. *Cluttered*: a smaller patch, objects nearly
touching and some lying on their side, so that they occlude each other from the wrist camera.
*Pile* (``Sorting-v2`` only): twenty objects of every family, a tightly packed base layer and
the objects laid on top of it, a harder tier with heavy occlusion
(:data:`~ipbench.envs.sorting_scenes.SCENES`, :func:`_place_pile`).

Every seed lays out. A seed whose scene procedure cannot place its objects (of Sorting-v0/v1's
episode seeds 0-2999 only cluttered 138) gets further attempts from a stream of its own, then,
as a last resort, its objects upright in rows (which fit every draw of the standard scenes;
a pile gets one more attempt from that stream, and an attempt of its almost always succeeds);
every other seed gets the scene procedure's layout, untouched by this fallback.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import mujoco
import numpy as np

from ipbench.assets.objects import (
    CATALOGS,
    CATEGORIES,
    FAMILIES,
    INSTANCES_PER_CATEGORY,
    ObjectInstance,
    RestingPose,
    get_instance,
    instances,
    resting_poses,
)
from ipbench.envs.sorting_scenes import PACKINGS, SCENES, SceneConfig, scenes_for

__all__ = [
    "PlacedObject",
    "Layout",
    "sample_layout",
    "LayoutError",
]


class LayoutError(ValueError):
    """A scene name or configuration that cannot be laid out."""


@dataclass(frozen=True)
class PlacedObject:
    """One object of a layout.

    Attributes
    ----------
    object_id : index in the scene (0 ... n-1); the body is ``object_{object_id:02d}``.
    instance : the catalogue instance.
    resting : the resting pose it was placed in.
    position : (3,) world position of the object frame (m), resting on the table top.
    yaw : rotation about the vertical (rad).
    quat : (4,) world orientation (w, x, y, z).
    """

    object_id: int
    instance: ObjectInstance
    resting: RestingPose
    position: tuple[float, float, float]
    yaw: float
    quat: tuple[float, float, float, float]

    @property
    def body(self) -> str:
        return f"object_{self.object_id:02d}"


@dataclass(frozen=True)
class Layout:
    """A scene's objects for one seed."""

    scene: str
    seed: int
    objects: tuple[PlacedObject, ...]


def _footprint(inst: ObjectInstance, pose: RestingPose) -> tuple[np.ndarray, np.ndarray]:
    """Footprint of the object on the table in a resting pose, before the yaw.

    Returns the (2,) offset of the footprint's centre from the object origin and its (2,)
    half extents (m): the object's bounding box, rotated by the pose, projected on the table.
    """
    half = 0.5 * np.asarray(inst.size)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    corners = np.asarray(inst.center) + signs * half
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, np.asarray(pose.quat, float))
    xy = (corners @ rot.reshape(3, 3).T)[:, :2]
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    return 0.5 * (lo + hi), 0.5 * (hi - lo)


def _overlaps(rect, others: np.ndarray, gap: float) -> bool:
    """Whether rectangle ``rect`` = (cx, cy, hx, hy, yaw) overlaps any row of ``others``
    (N, 5) once every rectangle is grown by ``gap``/2 (separating-axis test, vectorised)."""
    if len(others) == 0:
        return False
    g = gap / 2
    ca, sa = np.cos(rect[4]), np.sin(rect[4])
    cb, sb = np.cos(others[:, 4]), np.sin(others[:, 4])
    d = others[:, :2] - np.array(rect[:2])  # (N, 2)
    ua, va = np.array([ca, sa]), np.array([-sa, ca])
    ub, vb = np.stack([cb, sb], 1), np.stack([-sb, cb], 1)  # (N, 2)
    axes = np.stack([np.broadcast_to(ua, ub.shape), np.broadcast_to(va, ub.shape), ub, vb], 1)
    proj = lambda u: np.abs(np.einsum("nkc,nc->nk", axes, np.broadcast_to(u, ub.shape)))  # noqa: E731
    ra = (rect[2] + g) * proj(ua) + (rect[3] + g) * proj(va)
    rb = (others[:, 2:3] + g) * proj(ub) + (others[:, 3:4] + g) * proj(vb)
    separated = np.any(np.abs(np.einsum("nkc,nc->nk", axes, d)) > ra + rb, axis=1)
    return bool(not np.all(separated))


def sample_layout(
    scene: str | SceneConfig,
    seed: int,
    area_center: np.ndarray,
    area_half: np.ndarray,
    table_height: float,
    max_tries: int = 300,
    restarts: int = 50,
    catalog: str = "v1",
) -> Layout:
    """Sample a scene's objects and poses from ``seed``.

    Parameters
    ----------
    scene : a name from :data:`SCENES` or a :class:`SceneConfig`.
    seed : the episode seed (same seed, same layout).
    area_center : (2,) or (3,) world centre of the spawn area (m).
    area_half : (2,) half extents of the spawn area (m).
    table_height : z of the table top (m).
    catalog : the object catalogue the instances come from (``"v1"``: 12 instances per
        category, known and unknown both appear; ``"v2"``: every family and split of each
        category can appear, and at least two splits do). A scene exists in the catalogues
        of its :attr:`SceneConfig.catalogs` only (``"pile"``: v2).
    """
    if isinstance(scene, SceneConfig) and scene.packing not in PACKINGS:
        raise LayoutError(f"unknown packing {scene.packing!r}; valid: {', '.join(PACKINGS)}")
    if isinstance(scene, str):
        if scene not in SCENES:
            raise LayoutError(f"unknown scene {scene!r}; valid scenes: {', '.join(SCENES)}")
        scene = SCENES[scene]
    if catalog not in CATALOGS:
        raise LayoutError(f"unknown catalog {catalog!r}; valid: {', '.join(CATALOGS)}")
    if catalog not in scene.catalogs:
        raise LayoutError(
            f"scene {scene.name!r} does not exist in catalog {catalog!r} (it needs "
            f"{', '.join(scene.catalogs)}); valid scenes of catalog {catalog!r}: "
            f"{', '.join(scenes_for(catalog))}"
        )
    # a pile's placement, also its last resort (the standard scenes': _place, _place_in_rows)
    place = _place_pile if scene.packing == "pile" else _place
    in_rows = _place_pile if scene.packing == "pile" else _place_in_rows
    rng = np.random.default_rng([seed, 2018])
    # v1 draws its objects once; v2's larger families (2 L cartons, soup bowls) do not always
    # fit one pile: it draws the objects again (from the same seeded stream) when they do not
    draws = 1 if catalog == "v1" else _REDRAWS
    for _ in range(draws):
        picks = _pick_v1(scene, rng) if catalog == "v1" else _pick(scene, rng, catalog)
        for _ in range(restarts if catalog == "v1" else _V2_RESTARTS):
            placed = place(scene, picks, rng, area_center, area_half, table_height, max_tries)
            if placed is not None:
                return Layout(scene=scene.name, seed=int(seed), objects=placed)
    # Only seeds the procedure above cannot place come here (of Sorting-v0/v1's episode seeds
    # 0-2999, cluttered 138), so every other seed keeps its layout: more attempts with the
    # same objects from a stream of their own, then rows, which always fit the standard scenes.
    fallback = np.random.default_rng([seed, 2018, 1])
    for _ in range(_FALLBACK_ATTEMPTS):
        placed = place(scene, picks, fallback, area_center, area_half, table_height, max_tries)
        if placed is not None:
            return Layout(scene=scene.name, seed=int(seed), objects=placed)
    placed = in_rows(scene, picks, fallback, area_center, area_half, table_height)
    if placed is not None:
        return Layout(scene=scene.name, seed=int(seed), objects=placed)
    raise LayoutError(
        f"could not place the {len(picks)} objects of scene {scene.name!r}, neither at random "
        f"({_FALLBACK_ATTEMPTS} attempts after the scene's own) nor upright in rows; enlarge "
        "area_fraction, reduce gap or place fewer objects"
    )


_REDRAWS = 50
_V2_RESTARTS = 5
"""How often a v2 layout draws its objects again when they cannot be placed, and how many
placement attempts each draw gets."""
_FALLBACK_ATTEMPTS = 100
"""Placement attempts of a seed whose scene procedure fails, before the rows."""


def _pick_v1(scene: SceneConfig, rng: np.random.Generator) -> list[ObjectInstance]:
    """Sorting-v0/v1's draw (kept exactly): known and unknown instances both appear."""
    while True:
        picks = [
            get_instance(cat, int(i))
            for cat, n in zip(CATEGORIES, scene.counts, strict=True)
            for i in rng.choice(INSTANCES_PER_CATEGORY, size=n, replace=False)
        ]
        if len({p.known for p in picks}) == 2 or len(picks) < 2:
            return picks


def _pick(scene: SceneConfig, rng: np.random.Generator, catalog: str) -> list[ObjectInstance]:
    """Instances from the whole catalogue of each category (every family and split can
    appear, without repeats); redrawn until at least two splits appear."""
    every = instances(catalog=catalog)
    pools = {cat: [inst for inst in every if inst.category == cat] for cat in CATEGORIES}
    if scene.every_family:
        return _pick_every_family(scene, rng, pools)
    while True:
        picks = [
            pools[cat][int(i)]
            for cat, n in zip(CATEGORIES, scene.counts, strict=True)
            for i in rng.choice(len(pools[cat]), size=n, replace=False)
        ]
        if len({p.split for p in picks}) >= 2 or len(picks) < 2:
            return picks


def _pick_every_family(
    scene: SceneConfig, rng: np.random.Generator, pools: dict[str, list[ObjectInstance]]
) -> list[ObjectInstance]:
    """One instance of every family of each category (which one drawn from its family), then
    the category's remaining count from its other instances, without repeats. Every split
    appears (each category's last family is the novel one)."""
    picks = []
    for cat, n in zip(CATEGORIES, scene.counts, strict=True):
        families = FAMILIES[cat]
        if n < len(families):
            raise LayoutError(
                f"scene {scene.name!r} draws every family but has {n} {cat} for its "
                f"{len(families)} families ({', '.join(families)}); give it at least "
                f"{len(families)}"
            )
        chosen = []
        for family in families:
            members = [k for k, inst in enumerate(pools[cat]) if inst.family == family]
            chosen.append(members[int(rng.integers(len(members)))])
        rest = [k for k in range(len(pools[cat])) if k not in chosen]
        chosen += [rest[int(i)] for i in rng.choice(len(rest), size=n - len(chosen), replace=False)]
        picks += [pools[cat][k] for k in chosen]
    return picks


def _place(scene, picks, rng, area_center, area_half, table_height, max_tries, poses=None):
    """One attempt at placing ``picks``, largest first; ``None`` if an object did not fit.

    Object ids follow a random order (so an id says nothing about the category). The draws
    and the arithmetic of every stored value are those of Sorting-v0's procedure; the free-space
    test is :func:`_is_free` (the same rectangles, scalar and with bounding-circle shortcuts:
    most tries of a dense pile fail, so the test dominates the time). ``poses``: the picks'
    resting poses, chosen by the caller (a pile's base layer); by default drawn here."""
    if poses is None:
        poses = [resting_poses(inst)[0] for inst in picks]
        can_lie = [
            k for k, inst in enumerate(picks) if any(p.name == "side" for p in resting_poses(inst))
        ]
        for k in rng.permutation(can_lie)[: int(round(scene.lying_fraction * len(can_lie)))]:
            poses[k] = next(p for p in resting_poses(picks[k]) if p.name == "side")
    footprints = [_footprint(inst, pose) for inst, pose in zip(picks, poses, strict=True)]
    order = sorted(rng.permutation(len(picks)), key=lambda k: -np.prod(footprints[k][1]))
    half = np.asarray(area_half[:2], float) * np.asarray(scene.area_fraction)
    center = np.asarray(area_center[:2], float)
    # Python floats from here on: the same IEEE arithmetic as NumPy's scalars, faster
    (half_x, half_y), (cx, cy) = half.tolist(), center.tolist()
    g, gap, cluster = scene.gap / 2, scene.gap, scene.packing == "cluster"
    uniform, integers, cos, sin = rng.uniform, rng.integers, np.cos, np.sin
    placed: list[PlacedObject] = []
    rects: list[tuple] = []  # (x, y, hx, hy, yaw) of each placed footprint (m, rad)
    reaches: list[tuple] = []  # (max(hx, hy), hypot(hx, hy)) of each (m)
    grown: list[tuple] = []  # each footprint grown by gap / 2 (see _is_free)
    order_ids = rng.permutation(len(picks))  # object id of each pick
    for k in order:
        inst, pose = picks[k], poses[k]
        offset, (hx, hy) = footprints[k][0], footprints[k][1].tolist()
        reach = (max(hx, hy), float(np.hypot(hx, hy)))
        gx, gy = hx + g, hy + g  # grown by the gap, and the circles around and inside (m)
        r_out, r_in = math.hypot(gx, gy), min(gx, gy)
        for _ in range(max_tries):
            yaw = float(uniform(-np.pi, np.pi))
            c, s = float(cos(yaw)), float(sin(yaw))
            # the rotated footprint stays inside the area
            room_x = half_x - (abs(c) * hx + abs(s) * hy)
            room_y = half_y - (abs(s) * hx + abs(c) * hy)
            if room_x < 0 or room_y < 0:
                continue
            if cluster and rects:
                # Next to a placed neighbour: centres between the footprints' inscribed and
                # circumscribed radii apart (plus the gap); the overlap test below decides.
                j = int(integers(len(rects)))
                angle = uniform(-np.pi, np.pi)
                dist = 0.5 * (reach[0] + reach[1] + reaches[j][0] + reaches[j][1])
                dist += gap * uniform(1.0, 3.0)
                mx = rects[j][0] + dist * float(cos(angle))
                my = rects[j][1] + dist * float(sin(angle))
                if abs(mx - cx) > room_x or abs(my - cy) > room_y:
                    continue
            else:
                spread = 0.2 if cluster else 1.0
                mid = center + uniform(-spread, spread, size=2) * np.array([room_x, room_y])
                mx, my = mid.tolist()
            box = (mx, my, gx, gy, c, s, r_out, r_in)
            if _is_free(box, grown):
                break
        else:
            return None
        rects.append((mx, my, hx, hy, yaw))
        reaches.append(reach)
        grown.append(box)
        xy = np.array([mx, my]) - np.array(
            [c * offset[0] - s * offset[1], s * offset[0] + c * offset[1]]
        )
        placed.append(_placed(int(order_ids[k]), inst, pose, xy, yaw, table_height))
    return tuple(sorted(placed, key=lambda o: o.object_id))


def _placed(object_id, inst, pose, xy, yaw, table_height) -> PlacedObject:
    """``inst`` in resting ``pose`` with its origin at ``xy`` (m) on the table, turned by
    ``yaw`` (rad) about the vertical."""
    qyaw = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
    quat = np.empty(4)
    mujoco.mju_mulQuat(quat, qyaw, np.asarray(pose.quat, float))
    return PlacedObject(
        object_id=object_id,
        instance=inst,
        resting=pose,
        position=(float(xy[0]), float(xy[1]), float(table_height + pose.height)),
        yaw=yaw,
        quat=tuple(float(v) for v in quat / np.linalg.norm(quat)),
    )


_SURE = 1e-9
"""Margin (m) by which bounding circles must clear (or overlap) for :func:`_is_free` to
decide without the separating-axis test."""


def _is_free(box: tuple[float, ...], others: list[tuple[float, ...]]) -> bool:
    """Whether rectangle ``box`` overlaps none of ``others``.

    Each rectangle is (x, y, hx, hy, cos yaw, sin yaw, r_out, r_in): centre, half extents (m)
    already grown by half the gap, orientation, and the radii of its circumscribed and
    inscribed circles (m).

    The test of :func:`_overlaps` (separating axes), one rectangle at a time in scalar
    arithmetic: rectangles whose circumscribed circles are apart are free, those whose
    inscribed circles overlap are not; only the others go through the four axes."""
    ax, ay, ahx, ahy, ca, sa, a_out, a_in = box
    for bx, by, bhx, bhy, cb, sb, b_out, b_in in others:
        dx, dy = bx - ax, by - ay
        d2 = dx * dx + dy * dy
        if d2 > (a_out + b_out + _SURE) ** 2:
            continue
        if d2 < (a_in + b_in - _SURE) ** 2:
            return False
        for lx, ly in ((ca, sa), (-sa, ca), (cb, sb), (-sb, cb)):
            ra = ahx * abs(lx * ca + ly * sa) + ahy * abs(lx * -sa + ly * ca)
            rb = bhx * abs(lx * cb + ly * sb) + bhy * abs(lx * -sb + ly * cb)
            if abs(lx * dx + ly * dy) > ra + rb:
                break  # a separating axis
        else:
            return False
    return True


@cache
def _slot(category: str, catalog: str) -> tuple[float, float]:
    """Half extents (m) of the footprint that holds every upright instance of ``category`` in
    ``catalog`` at yaw 0 (the largest half extent along x and along y)."""
    halves = [
        _footprint(inst, resting_poses(inst)[0])[1]
        for inst in instances(catalog=catalog)
        if inst.category == category
    ]
    hx, hy = np.max(halves, axis=0)
    return float(hx), float(hy)


def _place_in_rows(scene, picks, rng, area_center, area_half, table_height):
    """The last resort of :func:`sample_layout`: every object upright, in rows; ``None`` if
    the rows do not fit the area.

    Each object stands at the centre of its category's slot (:func:`_slot`), turned so that
    the slot's long side runs along the row; whether the rows fit thus depends on the
    scene's counts and catalogue only. Slots are packed ``gap`` apart, deepest first (the
    order among equal ones and the object ids drawn from ``rng``), in rows along x or, if
    those do not fit, along y; the block of rows is centred in the area."""
    n = len(picks)
    halves = [_slot(inst.category, inst.catalog) for inst in picks]
    width = [2 * max(h) for h in halves]  # along the row (m)
    depth = [2 * min(h) for h in halves]  # across it (m)
    half = np.asarray(area_half[:2], float) * np.asarray(scene.area_fraction)
    center = np.asarray(area_center[:2], float)
    gap = scene.gap
    order = sorted(rng.permutation(n), key=lambda k: -depth[k])
    order_ids = rng.permutation(n)  # object id of each pick
    for along in (0, 1):  # rows along x, then along y
        rows: list[list[int]] = [[]]
        for k in order:  # next fit: a new row when the slot does not fit the current one
            row = rows[-1]
            if row and sum(width[j] + gap for j in row) + width[k] > 2 * half[along]:
                rows.append([])
            rows[-1].append(k)
        lengths = [sum(width[k] for k in row) + gap * (len(row) - 1) for row in rows]
        depths = [max(depth[k] for k in row) for row in rows]
        total = sum(depths) + gap * (len(rows) - 1)
        if max(lengths) > 2 * half[along] or total > 2 * half[1 - along]:
            continue
        placed = []
        across = -0.5 * total  # the row's side towards -(the other axis) (m from the centre)
        for row, length, row_depth in zip(rows, lengths, depths, strict=True):
            pos = -0.5 * length
            for k in row:
                mid = np.empty(2)
                mid[along] = center[along] + pos + 0.5 * width[k]
                mid[1 - along] = center[1 - along] + across + 0.5 * row_depth
                pos += width[k] + gap
                # the slot's long side (its x when hx >= hy) along the row
                long_x = halves[k][0] >= halves[k][1]
                yaw = 0.0 if long_x == (along == 0) else np.pi / 2
                pose = resting_poses(picks[k])[0]
                offset, _ = _footprint(picks[k], pose)
                c, s = np.cos(yaw), np.sin(yaw)
                xy = mid - np.array([c * offset[0] - s * offset[1], s * offset[0] + c * offset[1]])
                placed.append(_placed(int(order_ids[k]), picks[k], pose, xy, yaw, table_height))
            across += row_depth + gap
        return tuple(sorted(placed, key=lambda o: o.object_id))
    return None


# -- the pile ---------------------------------------------------------------------------------
PILE_TABLE_TRIES = 256
"""Positions a base object of a pile draws on the table (half of them next to an object
already there); it takes the free one nearest the centre of the area, or, with none free, is
laid on the pile instead."""
PILE_TOP_TRIES = 128
"""Poses an object laid on the pile draws; it takes the lowest."""
PILE_TOP_ROUNDS = 4
"""Draws of :data:`PILE_TOP_TRIES` poses an object laid on the pile gets to find one at most
:data:`PILE_MAX_LIFT` high."""
PILE_TOP_AREA = 0.8
"""Fraction of the area (in x and y), around its centre, that the footprints of objects laid
on the pile stay inside: one that slides off the pile still stops on the table."""
PILE_MAX_LIFT = 0.25
"""Highest (m above the table) an object may be laid on the pile (lower poses are taken when
there are any): the pile stays a heap two or three objects high, every object's centre below
the 0.35 m above the table that counts as on it (:func:`~ipbench.envs.world.object_status`);
an attempt with an object that finds no pose this low fails."""
PILE_CLEARANCE = 0.003
"""Gap (m) between the lowest point of an object laid on the pile and the highest top under it
(bounding boxes): no object starts inside another; the settling at reset brings it down."""
_BASE_ONLY = ("juice_bottle", "bowl")
"""Categories not drawn to be laid on the pile: a bottle on a heap rolls off (round) or
topples (standing), a bowl on it rocks on its rim; they stand or lie on the table."""
_LIE_ON_PILE = ("milk_carton", "juice_box")
"""Categories that lie on their side when laid on the pile (flat faces: they stay put); mugs
stand on it."""


_pile_footprint = cache(_footprint)
""":func:`_footprint`, cached (every pile attempt needs those of its objects)."""


@cache
def _top(inst: ObjectInstance, pose: RestingPose) -> float:
    """Height (m) of the top of ``inst``'s bounding box above the table in resting ``pose``
    (any yaw)."""
    half = 0.5 * np.asarray(inst.size)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    corners = np.asarray(inst.center) + signs * half
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, np.asarray(pose.quat, float))
    return float(pose.height + (corners @ rot.reshape(3, 3).T)[:, 2].max())


def _overlap_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(T, N) whether rectangle ``a[t]`` overlaps (or touches) rectangle ``b[n]``; rows are
    (x, y, hx, hy, cos yaw, sin yaw): centre (m), half extents (m), orientation. The
    separating-axis test of :func:`_overlaps`, over every pair at once."""
    ax, ay, ahx, ahy, ac, as_ = (a[:, i, None] for i in range(6))
    bx, by, bhx, bhy, bc, bs = (b[None, :, i] for i in range(6))
    dx, dy = bx - ax, by - ay
    cos_d = np.abs(ac * bc + as_ * bs)  # |cos| and |sin| of the yaw difference
    sin_d = np.abs(as_ * bc - ac * bs)
    separated = (
        (np.abs(ac * dx + as_ * dy) > ahx + bhx * cos_d + bhy * sin_d)
        | (np.abs(-as_ * dx + ac * dy) > ahy + bhx * sin_d + bhy * cos_d)
        | (np.abs(bc * dx + bs * dy) > bhx + ahx * cos_d + ahy * sin_d)
        | (np.abs(-bs * dx + bc * dy) > bhy + ahx * sin_d + ahy * cos_d)
    )
    return ~separated


def _place_pile(scene, picks, rng, area_center, area_half, table_height, max_tries=None):
    """One attempt at a pile (``packing="pile"``); ``None`` if an object laid on the pile
    found no pose at most :data:`PILE_MAX_LIFT` high (about one attempt in four).

    ``scene.on_top`` objects drawn from ``rng`` (no juice bottle or bowl) are laid on the
    pile; the others form the base layer on the table, ``scene.lying_fraction`` of those
    that can lie there on their side (rounded; which ones drawn from ``rng``). Every object
    turns by a yaw drawn from ``rng`` and has its footprint inside the area.

    Base objects, juice bottles and bowls first (they are not drawn for the pile), each group
    largest footprint first (ties in an order drawn from ``rng``), draw
    :data:`PILE_TABLE_TRIES` positions and take the free one (overlapping no footprint placed
    before) nearest the centre of the area, which packs them tightly, like ``"cluster"``; one
    with none free is laid on the pile too. Milk cartons and juice boxes laid on the pile lie
    on their side, mugs stand. Each, largest first, draws :data:`PILE_TOP_TRIES` poses (its
    footprint's centre over the middle half of a base object's footprint, the footprint inside
    :data:`PILE_TOP_AREA` of the area; up to :data:`PILE_TOP_ROUNDS` draws until one is at most
    :data:`PILE_MAX_LIFT` high) and takes the lowest, as an object dropped on a heap settles
    low: its lowest point :data:`PILE_CLEARANCE` above the highest top (bounding boxes) of the
    objects under its footprint, base objects and those laid before. Object ids are drawn from
    ``rng``.

    The layout stays free of simulation: no object starts inside another, and the gentle
    settling at reset (:attr:`SceneConfig.gentle_settle`) brings those laid on the pile down
    onto the others. ``max_tries`` is not used (the tries above are the pile's)."""
    n = len(picks)
    can_top = [k for k in range(n) if picks[k].category not in _BASE_ONLY]
    drawn = rng.choice(len(can_top), size=min(scene.on_top, len(can_top)), replace=False)
    on_top = {can_top[int(i)] for i in drawn}
    poses = [resting_poses(inst)[0] for inst in picks]
    sides = [next((p for p in resting_poses(inst) if p.name == "side"), None) for inst in picks]
    can_lie = [k for k in range(n) if sides[k] is not None and k not in on_top]
    for k in rng.permutation(can_lie)[: int(round(scene.lying_fraction * len(can_lie)))]:
        poses[k] = sides[k]
    footprints = [_pile_footprint(i, p) for i, p in zip(picks, poses, strict=True)]
    order = sorted(
        rng.permutation(n),
        key=lambda k: (picks[k].category not in _BASE_ONLY, -np.prod(footprints[k][1])),
    )
    half = np.asarray(area_half[:2], float) * np.asarray(scene.area_fraction)
    center = np.asarray(area_center[:2], float)
    rects = np.empty((0, 6))  # (x, y, hx, hy, cos yaw, sin yaw) of every object placed
    tops = np.empty(0)  # and the height of its top above the table (m)
    where: dict[int, tuple[np.ndarray, float, float]] = {}  # k -> footprint centre, yaw, lift

    def candidates(k: int, mid: np.ndarray, yaw: np.ndarray, room: np.ndarray) -> np.ndarray:
        """(T, 6) rectangles of pick ``k`` centred at ``mid`` (T, 2) turned by ``yaw`` (T,),
        without those whose footprint leaves the area of half extents ``room`` (m)."""
        hx, hy = footprints[k][1]
        c, s = np.cos(yaw), np.sin(yaw)
        extent = np.stack([np.abs(c) * hx + np.abs(s) * hy, np.abs(s) * hx + np.abs(c) * hy], 1)
        inside = np.all(np.abs(mid - center) <= room - extent, axis=1)
        rows = np.column_stack([mid, np.full(len(yaw), hx), np.full(len(yaw), hy), c, s])
        return rows[inside]

    def put(k: int, rect: np.ndarray, lift: float) -> None:
        nonlocal rects, tops
        rects = np.vstack([rects, rect])
        tops = np.append(tops, lift + _top(picks[k], poses[k]))
        where[k] = (rect[:2], math.atan2(rect[5], rect[4]), lift)

    later = [k for k in order if k in on_top]
    for k in order:
        if k in on_top:
            continue
        yaw = rng.uniform(-np.pi, np.pi, PILE_TABLE_TRIES)
        mid = center + rng.uniform(-1.0, 1.0, (PILE_TABLE_TRIES, 2)) * half
        if len(rects):  # half of them next to a placed object (centres between touching radii)
            m = PILE_TABLE_TRIES // 2
            nb = rects[rng.integers(len(rects), size=m)]
            angle = rng.uniform(-np.pi, np.pi, m)
            hx, hy = footprints[k][1]
            r_in = min(hx, hy) + np.minimum(nb[:, 2], nb[:, 3])
            r_out = math.hypot(hx, hy) + np.hypot(nb[:, 2], nb[:, 3])
            dist = r_in + rng.uniform(0.0, 1.0, m) * (r_out - r_in)
            mid[:m] = nb[:, :2] + dist[:, None] * np.stack([np.cos(angle), np.sin(angle)], 1)
        cand = candidates(k, mid, yaw, half)
        if len(rects):
            cand = cand[~_overlap_matrix(cand, rects).any(axis=1)]
        if len(cand):
            put(k, cand[np.argmin(np.hypot(*(cand[:, :2] - center).T))], 0.0)
        else:
            later.append(k)  # no room on the table: on the pile
    n_base = len(rects)
    if not n_base:
        return None
    for k in later:
        if picks[k].category in _LIE_ON_PILE and sides[k] is not None:
            poses[k] = sides[k]
            footprints[k] = _pile_footprint(picks[k], poses[k])
    for k in sorted(later, key=lambda k: -np.prod(footprints[k][1])):
        for _ in range(PILE_TOP_ROUNDS):
            support = rects[rng.integers(n_base, size=PILE_TOP_TRIES)]
            yaw = rng.uniform(-np.pi, np.pi, PILE_TOP_TRIES)
            u, v = (rng.uniform(-0.5, 0.5, (PILE_TOP_TRIES, 2)) * support[:, 2:4]).T
            mid = support[:, :2] + np.stack(
                [support[:, 4] * u - support[:, 5] * v, support[:, 5] * u + support[:, 4] * v], 1
            )
            cand = candidates(k, mid, yaw, PILE_TOP_AREA * half)
            under = np.where(_overlap_matrix(cand, rects), tops, 0.0).max(axis=1)
            if len(cand) and under.min() <= PILE_MAX_LIFT:
                break
        else:
            return None
        best = int(np.argmin(under))
        put(k, cand[best], float(under[best]) + PILE_CLEARANCE)
    ids = rng.permutation(n)  # object id of each pick
    placed = []
    for k, (mid, yaw, lift) in where.items():
        offset = footprints[k][0]
        c, s = math.cos(yaw), math.sin(yaw)
        xy = mid - [c * offset[0] - s * offset[1], s * offset[0] + c * offset[1]]
        placed.append(_placed(int(ids[k]), picks[k], poses[k], xy, yaw, table_height + lift))
    return tuple(sorted(placed, key=lambda o: o.object_id))
