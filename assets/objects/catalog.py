"""The object catalogue: five categories x 12 deterministic instances, and the known split.

An instance is a pure function of ``(category, index)``: its random generator is seeded from
the SHA-256 of ``"ipbench.objects/<category>/<index>"`` (stable across runs and Python
versions, unlike ``hash()``).

**Known / unknown split (fixed rule):** indices ``0 .. KNOWN_INSTANCES - 1`` (0-7) of every
category are *known* (perception may be trained on them); indices 8-11 are *unknown* (held out
for evaluation).

Object frame: origin at the centre of the bottom face of the upright object, +z up. The mug's
handle points to +x, the juice box's straw is on its +y face, the carton's ridge runs along x.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, fields
from functools import cache

import numpy as np

from ipbench.assets.objects.params import (
    BottleShape,
    BowlShape,
    CartonShape,
    JuiceBoxShape,
    MugShape,
    Shape,
    sample_shape,
)

__all__ = [
    "CATEGORIES",
    "INSTANCES_PER_CATEGORY",
    "KNOWN_INSTANCES",
    "ObjectCatalogError",
    "ObjectInstance",
    "get_instance",
    "instances",
]

CATEGORIES: tuple[str, ...] = ("juice_bottle", "milk_carton", "bowl", "mug", "juice_box")
"""Category names, in the bin order of the benchmark."""

INSTANCES_PER_CATEGORY: int = 12
"""Instances per category (indices 0-11)."""

KNOWN_INSTANCES: int = 8
"""Indices below this are known (training); the others are unknown (held out)."""


class ObjectCatalogError(ValueError):
    """Root exception of :mod:`ipbench.assets.objects` (bad category, index, name...)."""


@dataclass(frozen=True)
class ObjectInstance:
    """One procedural object.

    Attributes
    ----------
    category : one of :data:`CATEGORIES`.
    index : 0 .. INSTANCES_PER_CATEGORY - 1.
    name : ``f"{category}_{index:02d}"``.
    known : ``index < KNOWN_INSTANCES``.
    mass : total mass, kg.
    size : (3,) extents (x, y, z) of the axis-aligned bounding box of the visual geometry in
        the object frame, m.
    center : (3,) centre of that bounding box in the object frame, m (``(0, 0, size_z / 2)``
        except for the mug, whose handle is on +x, and the juice box, whose straw is on +y).
    rgba : (4,) main colour (juice tint, carton white, glaze, box print).
    accent_rgba : (4,) second colour (bottle cap and label, carton band, inside glaze of
        bowls and mugs, juice-box straw).
    specular : glazed, shiny surface (depth sensors lose depth on it). In the model such
        geoms get a material with ``specular >= SPECULAR_THRESHOLD`` (0.5), the others < 0.3.
    shape : the category's dimensions (:mod:`ipbench.assets.objects.params`), m.
    """

    category: str
    index: int
    name: str
    known: bool
    mass: float
    size: tuple[float, float, float]
    center: tuple[float, float, float]
    rgba: tuple[float, float, float, float]
    accent_rgba: tuple[float, float, float, float]
    specular: bool
    shape: Shape


def _seed(category: str, index: int) -> int:
    digest = hashlib.sha256(f"ipbench.objects/{category}/{index}".encode()).digest()
    return int.from_bytes(digest[:8], "little")


def _plain(value: object) -> object:
    """numpy scalars -> Python bool / float (clean, hashable, comparable fields)."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    return float(value)


def _bounds(shape: Shape) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """(size, center) of the visual bounding box, m."""
    if isinstance(shape, BottleShape):
        d = 2 * shape.radius
        return (d, d, shape.height), (0.0, 0.0, shape.height / 2)
    if isinstance(shape, CartonShape):
        h = shape.shoulder + shape.gable + shape.fin
        return (shape.base, shape.base, h), (0.0, 0.0, h / 2)
    if isinstance(shape, BowlShape):
        d = 2 * shape.rim_radius
        return (d, d, shape.height), (0.0, 0.0, shape.height / 2)
    if isinstance(shape, MugShape):
        d = 2 * shape.radius
        return (d + shape.handle_reach, d, shape.height), (
            shape.handle_reach / 2,
            0.0,
            shape.height / 2,
        )
    if isinstance(shape, JuiceBoxShape):
        straw = 2 * shape.straw_radius
        size = (shape.width, shape.depth + straw, shape.height)
        return size, (0.0, straw / 2, shape.height / 2)
    raise TypeError(f"unknown shape {type(shape).__name__}")


def _check(category: str, index: int) -> None:
    if category not in CATEGORIES:
        raise ObjectCatalogError(
            f"unknown category {category!r}; valid categories: {', '.join(CATEGORIES)}"
        )
    if isinstance(index, bool) or not isinstance(index, int | np.integer):
        raise ObjectCatalogError(f"index must be an int, got {type(index).__name__}")
    if not 0 <= index < INSTANCES_PER_CATEGORY:
        raise ObjectCatalogError(
            f"index {index} out of range; valid indices: 0..{INSTANCES_PER_CATEGORY - 1}"
        )


@cache
def _make(category: str, index: int) -> ObjectInstance:
    sample = sample_shape(category, index, np.random.default_rng(_seed(category, index)))
    shape = sample.shape
    shape = type(shape)(**{f.name: _plain(getattr(shape, f.name)) for f in fields(shape)})
    size, center = _bounds(shape)
    return ObjectInstance(
        category=category,
        index=index,
        name=f"{category}_{index:02d}",
        known=index < KNOWN_INSTANCES,
        mass=sample.mass,
        size=tuple(float(v) for v in size),
        center=tuple(float(v) for v in center),
        rgba=sample.rgba,
        accent_rgba=sample.accent_rgba,
        specular=sample.specular,
        shape=shape,
    )


def get_instance(category: str, index: int) -> ObjectInstance:
    """The instance ``index`` (0-11) of ``category`` (one of :data:`CATEGORIES`).

    Raises
    ------
    ObjectCatalogError
        If the category or the index is not valid (the message lists the valid ones).
    """
    _check(category, index)
    return _make(category, int(index))


def instances(known: bool | None = None) -> tuple[ObjectInstance, ...]:
    """All instances in category then index order, or only the known / unknown ones.

    Parameters
    ----------
    known : None for all 60, True for indices < KNOWN_INSTANCES, False for the others.
    """
    return tuple(
        get_instance(c, i)
        for c in CATEGORIES
        for i in range(INSTANCES_PER_CATEGORY)
        if known is None or (i < KNOWN_INSTANCES) == bool(known)
    )
