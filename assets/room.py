"""The lab room around the work cell and the posters on its walls (background clutter).

Sources (no value was chosen on a result):

- **Room**: walls at x_base = +-2.95 m and y_base = +-2.3 m (5.9 x 4.6 m), ceiling 3.0 m, from the
  Glasgow CloPeMa description (``gerac83/ug_bluerobot``, ``urdf/room_ug.urdf.xacro``). The world
  here is the r750 frame, yawed -90 deg from ``base_link`` (x_r750 = -y_base): the front wall stands
  at x = +2.3 m, the back wall at x = -2.3 m, the side walls at y = +-2.95 m. Wall colour is not
  documented: a plain light paint.
- **Posters**: ISO 216 paper sizes A1 (0.594 x 0.841 m) and A2 (0.420 x 0.594 m), portrait,
  hung with their centre 1.45 m above the floor (57 in "on centre", the usual gallery and
  museum hanging height).
- **Prints**: procedural adverts (a brand word, a picture, a badge, small print) from the
  drawing helpers of the product textures, so that the walls carry features of the same kind
  as the products; no poster shows a product of the recognition database.

The walls and posters are visual only (no contacts): nothing in the cell reaches them.
Rendering cost: five boxes and two triangles and one 256 x 362 texture per poster.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ipbench.assets.objects import texture_parts as tp
from ipbench.assets.quads import add_textured_quad

__all__ = [
    "CEILING_HEIGHT",
    "POSTER_CENTRE_HEIGHT",
    "POSTER_SIZES",
    "ROOM_HALF",
    "WALLS",
    "Poster",
    "RoomError",
    "add_room",
    "layout_posters",
    "poster_image",
]

ROOM_HALF = (2.3, 2.95)
"""Half the room's inside extent along world x and y, m (room_ug.urdf.xacro, module doc)."""
CEILING_HEIGHT = 3.0
"""m above the floor (room_ug.urdf.xacro)."""
POSTER_SIZES: dict[str, tuple[float, float]] = {"A1": (0.594, 0.841), "A2": (0.420, 0.594)}
"""(width, height) m of the ISO 216 sizes, portrait."""
POSTER_CENTRE_HEIGHT = 1.45
"""m above the floor (57 in on centre)."""
WALLS: tuple[str, ...] = ("front", "left", "right")
"""Walls that carry posters: the one facing the robot and the two beside the work table."""

_WALL_T = 0.05  # wall thickness (m; outside the room)
_POSTER_GAP = 0.003  # a poster's distance in front of its wall (m)
_POSTER_PX = (362, 256)  # (H, W) texture, the A-series ratio sqrt(2)
_SPACING = 0.10  # free wall between two posters (m)
_MARGIN = 0.30  # free wall at a room corner (m)
_TRIES = 200
_WALL_RGBA = (0.84, 0.84, 0.80, 1.0)
_VISUAL_GROUP = 2


class RoomError(ValueError):
    """A poster that does not fit the room."""


@dataclass(frozen=True)
class Poster:
    """One poster: on ``wall`` (one of :data:`WALLS`), its centre ``along`` the wall (world y
    for the front wall, world x for the side walls, m), ISO ``size`` (a key of
    :data:`POSTER_SIZES`) and the ``seed`` of its print."""

    wall: str
    along: float
    size: str
    seed: int


def _span(wall: str) -> tuple[float, float]:
    """Where a poster's centre line may run along ``wall`` (m), corners left free."""
    hx, hy = ROOM_HALF
    if wall == "front":
        return -hy + _MARGIN, hy - _MARGIN
    return 0.0, hx - _MARGIN  # the side walls' half in front of the robot


def layout_posters(rng: np.random.Generator, n: int) -> tuple[Poster, ...]:
    """``n`` posters on random walls, sizes and places, not overlapping (deterministic in
    ``rng``)."""
    placed: list[Poster] = []
    for _ in range(n):
        for _ in range(_TRIES):
            wall = WALLS[int(rng.integers(len(WALLS)))]
            size = ("A1", "A2")[int(rng.integers(2))]
            half = 0.5 * POSTER_SIZES[size][0]
            lo, hi = _span(wall)
            along = float(rng.uniform(lo + half, hi - half))
            if all(
                p.wall != wall
                or abs(p.along - along) >= half + 0.5 * POSTER_SIZES[p.size][0] + _SPACING
                for p in placed
            ):
                placed.append(Poster(wall, along, size, int(rng.integers(2**31))))
                break
        else:
            raise RoomError(f"{n} posters do not fit on the walls {WALLS}; use fewer")
    return tuple(placed)


def poster_image(seed: int) -> np.ndarray:
    """The print of a poster: (362, 256, 3) uint8 RGB, deterministic in ``seed``."""
    rng = np.random.default_rng([int(seed), 216])
    h, w = _POSTER_PX
    base = rng.uniform(0.55, 1.0, 3)
    pal = tp.Palette(rng, base, rng.uniform(0.0, 1.0, 3))
    img = tp.background(tp.fork(rng), h, w, pal.base, 0.08)
    tp.put_text(img, tp.brand_word(rng), (w / 2, 0.12 * h), (0.85 * w, 0.14 * h), pal.accent,
                tp.FONTS[int(rng.integers(len(tp.FONTS)))], outline=pal.ink)  # fmt: skip
    sky = tp.mix(pal.pop, (255, 255, 255), 0.6)
    tp.landscape(img, tp.fork(rng), (int(0.08 * w), int(0.24 * h), int(0.84 * w), int(0.42 * h)),
                 (sky, pal.accent, pal.pop))  # fmt: skip
    tp.logo(img, rng, (0.78 * w, 0.74 * h), 0.1 * w, pal.accent, pal.base)
    tp.put_text(img, tp.words(rng, 2), (0.38 * w, 0.74 * h), (0.6 * w, 0.06 * h), pal.ink)
    tp.text_block(img, tp.fork(rng), (int(0.08 * w), int(0.82 * h), int(0.84 * w), int(0.15 * h)),
                  pal.ink, 0.035 * h)  # fmt: skip
    return np.ascontiguousarray(img)


def _frame(poster: Poster) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(centre (3,), right (3,), inward normal (3,)) of a poster, world: ``right`` is the
    print's +u seen from inside the room."""
    hx, hy = ROOM_HALF
    z = POSTER_CENTRE_HEIGHT
    if poster.wall == "front":  # x = +hx, seen looking +x: right is -y
        return (
            np.array([hx - _POSTER_GAP, poster.along, z]),
            np.array([0, -1.0, 0]),
            np.array([-1.0, 0, 0]),
        )
    if poster.wall == "left":  # y = +hy, seen looking +y: right is +x
        return (
            np.array([poster.along, hy - _POSTER_GAP, z]),
            np.array([1.0, 0, 0]),
            np.array([0, -1.0, 0]),
        )
    if poster.wall == "right":  # y = -hy, seen looking -y: right is -x
        return (
            np.array([poster.along, -hy + _POSTER_GAP, z]),
            np.array([-1.0, 0, 0]),
            np.array([0, 1.0, 0]),
        )
    raise RoomError(f"unknown wall {poster.wall!r}; valid: {', '.join(WALLS)}")


def add_room(spec: mujoco.MjSpec, posters: tuple[Poster, ...] = ()) -> None:
    """Add the room's walls and ceiling and ``posters`` to ``spec``'s world (visual only)."""
    hx, hy, t, top = *ROOM_HALF, _WALL_T, CEILING_HEIGHT
    spec.add_material(name="room_wall", rgba=list(_WALL_RGBA), specular=0.0)
    boxes = {
        "front": ((hx + t / 2, 0, top / 2), (t / 2, hy + t, top / 2)),
        "back": ((-hx - t / 2, 0, top / 2), (t / 2, hy + t, top / 2)),
        "left": ((0, hy + t / 2, top / 2), (hx + t, t / 2, top / 2)),
        "right": ((0, -hy - t / 2, top / 2), (hx + t, t / 2, top / 2)),
        "ceiling": ((0, 0, top + t / 2), (hx + t, hy + t, t / 2)),
    }
    for name, (pos, half) in boxes.items():
        spec.worldbody.add_geom(
            name=f"room_{name}", type=mujoco.mjtGeom.mjGEOM_BOX, pos=list(pos), size=list(half),
            material="room_wall", contype=0, conaffinity=0, group=_VISUAL_GROUP, mass=0.0,
        )  # fmt: skip
    for k, poster in enumerate(posters):
        if poster.size not in POSTER_SIZES:
            raise RoomError(f"unknown poster size {poster.size!r}; valid: {list(POSTER_SIZES)}")
        centre, right, normal = _frame(poster)
        w, h = POSTER_SIZES[poster.size]
        up = np.array([0.0, 0.0, 1.0])
        corners = [centre + (su * w / 2) * right + (sv * h / 2) * up for su, sv in
                   ((-1, 1), (1, 1), (1, -1), (-1, -1))]  # fmt: skip
        add_textured_quad(spec, spec.worldbody, f"room_poster_{k:02d}",
                          poster_image(poster.seed), corners, normal, _VISUAL_GROUP)  # fmt: skip
