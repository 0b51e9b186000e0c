"""Seeded object layouts for the standard scenes (thesis Table 5.1), without simulation.

A layout says which instance stands where and how: the scene's composition per category,
instances drawn from the whole catalogue (known and unknown ones both appear), and poses
sampled inside the work table's spawn area from the seed. *Uncluttered*: upright objects well
apart. *Cluttered*: a smaller patch, objects nearly touching and some lying on their side,
so that they occlude each other from the wrist camera.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ipbench.assets.objects import (
    CATALOGS,
    CATEGORIES,
    INSTANCES_PER_CATEGORY,
    ObjectInstance,
    RestingPose,
    get_instance,
    instances,
    resting_poses,
)

__all__ = ["SceneConfig", "PlacedObject", "Layout", "SCENES", "sample_layout", "LayoutError"]


class LayoutError(ValueError):
    """A scene name or configuration that cannot be laid out."""


@dataclass(frozen=True)
class SceneConfig:
    """A scene's composition and placement rules.

    Attributes
    ----------
    name : scene name.
    counts : objects per category, in bin order (juice bottle, milk carton, bowl, mug, juice box).
    area_fraction : (x, y) fraction of the spawn area used (smaller packs objects closer).
    gap : minimum free space between the footprints of two objects (m).
    lying_fraction : fraction of the objects that can lie on their side that do (rounded;
        which ones is drawn from the seed).
    packing : ``"scatter"`` places each object anywhere in the area; ``"cluster"`` places
        each next to one already placed (``gap`` to 2 ``gap`` away), growing one tight pile.
    """

    name: str
    counts: tuple[int, int, int, int, int]
    area_fraction: tuple[float, float] = (1.0, 1.0)
    gap: float = 0.03
    lying_fraction: float = 0.0
    packing: str = "scatter"

    @property
    def n_objects(self) -> int:
        return sum(self.counts)


SCENES: dict[str, SceneConfig] = {
    # Thesis Table 5.1: 5 juice bottles, 1 milk carton, 4 mugs, well separated.
    "uncluttered": SceneConfig("uncluttered", (5, 1, 0, 4, 0)),
    # 4 juice bottles, 2 milk cartons, 3 bowls, 3 mugs, 2 juice boxes, close together.
    "cluttered": SceneConfig(
        "cluttered", (4, 2, 3, 3, 2), gap=0.0, lying_fraction=0.2, packing="cluster"
    ),
}


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
        category can appear, and at least two splits do).
    """
    if isinstance(scene, SceneConfig) and scene.packing not in ("scatter", "cluster"):
        raise LayoutError(f"unknown packing {scene.packing!r}; valid: scatter, cluster")
    if isinstance(scene, str):
        if scene not in SCENES:
            raise LayoutError(f"unknown scene {scene!r}; valid scenes: {', '.join(SCENES)}")
        scene = SCENES[scene]
    if catalog not in CATALOGS:
        raise LayoutError(f"unknown catalog {catalog!r}; valid: {', '.join(CATALOGS)}")
    rng = np.random.default_rng([seed, 2018])
    # v1 draws its objects once; v2's larger families (2 L cartons, soup bowls) do not always
    # fit one pile: it draws the objects again (from the same seeded stream) when they do not
    draws = 1 if catalog == "v1" else _REDRAWS
    for _ in range(draws):
        picks = _pick_v1(scene, rng) if catalog == "v1" else _pick(scene, rng, catalog)
        for _ in range(restarts if catalog == "v1" else _V2_RESTARTS):
            placed = _place(scene, picks, rng, area_center, area_half, table_height, max_tries)
            if placed is not None:
                return Layout(scene=scene.name, seed=int(seed), objects=placed)
    raise LayoutError(
        f"could not place the {len(picks)} objects of scene {scene.name!r} after {restarts} "
        "attempts; enlarge area_fraction or reduce gap"
    )


_REDRAWS = 50
_V2_RESTARTS = 5
"""How often a v2 layout draws its objects again when they cannot be placed, and how many
placement attempts each draw gets."""


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
    while True:
        picks = [
            pools[cat][int(i)]
            for cat, n in zip(CATEGORIES, scene.counts, strict=True)
            for i in rng.choice(len(pools[cat]), size=n, replace=False)
        ]
        if len({p.split for p in picks}) >= 2 or len(picks) < 2:
            return picks


def _place(scene, picks, rng, area_center, area_half, table_height, max_tries):
    """One attempt at placing ``picks``, largest first; ``None`` if an object did not fit.

    Object ids follow a random order (so an id says nothing about the category)."""
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
    placed: list[PlacedObject] = []
    rects: list[tuple[float, float, float, float, float]] = []
    order_ids = rng.permutation(len(picks))  # object id of each pick
    for k in order:
        inst, pose = picks[k], poses[k]
        offset, (hx, hy) = footprints[k]
        for _ in range(max_tries):
            yaw = float(rng.uniform(-np.pi, np.pi))
            c, s = np.cos(yaw), np.sin(yaw)
            extent = np.array([abs(c) * hx + abs(s) * hy, abs(s) * hx + abs(c) * hy])
            room = half - extent  # the rotated footprint stays inside the area
            if np.any(room < 0):
                continue
            if scene.packing == "cluster" and rects:
                # Next to a placed neighbour: centres between the footprints' inscribed and
                # circumscribed radii apart (plus the gap); the overlap test below decides.
                nx, ny, nhx, nhy, _ = rects[int(rng.integers(len(rects)))]
                angle = rng.uniform(-np.pi, np.pi)
                dist = 0.5 * (max(hx, hy) + np.hypot(hx, hy) + max(nhx, nhy) + np.hypot(nhx, nhy))
                dist += scene.gap * rng.uniform(1.0, 3.0)
                mid = np.array([nx, ny]) + dist * np.array([np.cos(angle), np.sin(angle)])
                if np.any(np.abs(mid - center) > room):
                    continue
            elif scene.packing == "cluster":
                mid = center + rng.uniform(-0.2, 0.2, size=2) * room
            else:
                mid = center + rng.uniform(-1, 1, size=2) * room
            xy = mid - np.array([c * offset[0] - s * offset[1], s * offset[0] + c * offset[1]])
            rect = (mid[0], mid[1], hx, hy, yaw)
            if not _overlaps(rect, np.array(rects).reshape(-1, 5), scene.gap):
                break
        else:
            return None
        rects.append(rect)
        qyaw = np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])
        quat = np.empty(4)
        mujoco.mju_mulQuat(quat, qyaw, np.asarray(pose.quat, float))
        placed.append(
            PlacedObject(
                object_id=int(order_ids[k]),
                instance=inst,
                resting=pose,
                position=(float(xy[0]), float(xy[1]), float(table_height + pose.height)),
                yaw=yaw,
                quat=tuple(float(v) for v in quat / np.linalg.norm(quat)),
            )
        )
    return tuple(sorted(placed, key=lambda o: o.object_id))
