"""The object catalogues: deterministic instances of five categories, and their splits.

Two catalogues (:data:`CATALOGS`); a released one never changes.

* ``"v1"``: 12 instances per category, one shape family each. An instance is a pure function
  of ``(category, index)``: its random generator is seeded from the SHA-256 of
  ``"ipbench.objects/<category>/<index>"`` (stable across runs and Python versions, unlike
  ``hash()``). **Known / unknown split (fixed rule):** indices ``0 .. KNOWN_INSTANCES - 1``
  (0-7) of every category are *known* (split ``"train"``); indices 8-11 are *unknown* (split
  ``"similar"``: new instances of the trained family).
* ``"v2"``: :data:`~ipbench.assets.objects.families.FAMILIES` (>= 3 real product types per
  category), 8 instances each: index ``i`` is instance ``i % 8`` of family
  ``FAMILIES[category][i // 8]``, named ``f"{category}_{family}_{i % 8}"`` and seeded from
  the SHA-256 of ``"ipbench.objects/v2/<category>/<family>/<i>"``. **Split rule (fixed):** the
  last family of each category is *novel* (never trained on); in the others instances 0-5
  are *train* and 6-7 *similar*. ``known == (split == "train")``.

Object frame: origin at the centre of the bottom face of the upright object, +z up. The mug's
handle points to +x, the juice box's straw is on its +y face, the carton's ridge runs along x.
"""

from __future__ import annotations

import hashlib
from dataclasses import fields
from functools import cache

import numpy as np

from ipbench.assets.objects.families import (
    FAMILIES,
    INSTANCES_PER_FAMILY,
    SPLITS,
    V1_FAMILY,
    family_split,
)
from ipbench.assets.objects.family_geometry import visual_bounds
from ipbench.assets.objects.family_samplers import sample_family
from ipbench.assets.objects.instance import ObjectInstance
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
    "CATALOGS",
    "CATEGORIES",
    "INSTANCES_PER_CATEGORY",
    "KNOWN_INSTANCES",
    "ObjectCatalogError",
    "get_instance",
    "instances",
    "find_instance",
]

CATALOGS: tuple[str, ...] = ("v1", "v2")
"""Object catalogues; ``"v1"`` is the released one of ``Sorting-v1``."""

CATEGORIES: tuple[str, ...] = ("juice_bottle", "milk_carton", "bowl", "mug", "juice_box")
"""Category names, in the bin order of the benchmark."""

INSTANCES_PER_CATEGORY: int = 12
"""Instances per category (indices 0-11)."""

KNOWN_INSTANCES: int = 8
"""Indices below this are known (training); the others are unknown (held out)."""


class ObjectCatalogError(ValueError):
    """Root exception of :mod:`ipbench.assets.objects` (bad category, index, name...)."""


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


def _check_category(category: str) -> None:
    if category not in CATEGORIES:
        raise ObjectCatalogError(
            f"unknown category {category!r}; valid categories: {', '.join(CATEGORIES)}"
        )


def _check_catalog(catalog: str) -> None:
    if catalog not in CATALOGS:
        raise ObjectCatalogError(
            f"unknown catalog {catalog!r}; valid catalogs: {', '.join(CATALOGS)}"
        )


def _count(category: str, catalog: str) -> int:
    if catalog == "v1":
        return INSTANCES_PER_CATEGORY
    return INSTANCES_PER_FAMILY * len(FAMILIES[category])


def _check(category: str, index: int, catalog: str = "v1") -> None:
    _check_catalog(catalog)
    if category not in CATEGORIES:
        raise ObjectCatalogError(
            f"unknown category {category!r}; valid categories: {', '.join(CATEGORIES)}"
        )
    if isinstance(index, bool) or not isinstance(index, int | np.integer):
        raise ObjectCatalogError(f"index must be an int, got {type(index).__name__}")
    n = _count(category, catalog)
    if not 0 <= index < n:
        raise ObjectCatalogError(
            f"index {index} out of range; valid indices ({catalog}, {category}): 0..{n - 1}"
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
        family=V1_FAMILY[category],
        split="train" if index < KNOWN_INSTANCES else "similar",
        catalog="v1",
    )


def _seed_v2(category: str, family: str, index: int) -> int:
    text = f"ipbench.objects/v2/{category}/{family}/{index}"
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "little")


@cache
def _make_v2(category: str, index: int) -> ObjectInstance:
    family, k = FAMILIES[category][index // INSTANCES_PER_FAMILY], index % INSTANCES_PER_FAMILY
    rng = np.random.default_rng(_seed_v2(category, family, index))
    sample = sample_family(category, family, k, rng)
    shape = type(sample.shape)(
        **{f.name: _plain(getattr(sample.shape, f.name)) for f in fields(sample.shape)}
    )
    size, center = visual_bounds(shape)
    split = family_split(category, family, k)
    return ObjectInstance(
        category=category,
        index=index,
        name=f"{category}_{family}_{k}",
        known=split == "train",
        mass=float(sample.mass),
        size=size,
        center=center,
        rgba=sample.rgba,
        accent_rgba=sample.accent_rgba,
        specular=bool(sample.specular),
        shape=shape,
        family=family,
        split=split,
        catalog="v2",
    )


def get_instance(category: str, index: int, catalog: str = "v1") -> ObjectInstance:
    """The instance ``index`` of ``category`` (one of :data:`CATEGORIES`) in ``catalog``.

    v1: indices 0-11. v2: ``0 .. 8 * len(FAMILIES[category]) - 1``, family
    ``FAMILIES[category][index // 8]``.

    Raises
    ------
    ObjectCatalogError
        If the catalogue, category or index is not valid (the message lists the valid ones).
    """
    _check(category, index, catalog)
    if catalog == "v1":
        return _make(category, int(index))
    return _make_v2(category, int(index))


def instances(
    known: bool | None = None,
    *,
    catalog: str = "v1",
    split: str | None = None,
    family: str | None = None,
) -> tuple[ObjectInstance, ...]:
    """All instances of ``catalog`` in category then index order, optionally filtered.

    Parameters
    ----------
    known : None for all, True for the known (train) ones, False for the others.
    catalog : ``"v1"`` (60 instances) or ``"v2"``.
    split : only this split (``"train"``, ``"similar"``, ``"novel"``).
    family : only this family (a member of some ``FAMILIES[category]``).

    Raises
    ------
    ObjectCatalogError
        For an unknown catalogue, split or family (the message lists the valid ones).
    """
    _check_catalog(catalog)
    if split is not None and split not in SPLITS:
        raise ObjectCatalogError(f"unknown split {split!r}; valid splits: {', '.join(SPLITS)}")
    every = sorted({f for fams in FAMILIES.values() for f in fams})
    if family is not None and family not in every:
        raise ObjectCatalogError(f"unknown family {family!r}; valid families: {', '.join(every)}")
    out = []
    for c in CATEGORIES:
        for i in range(_count(c, catalog)):
            inst = get_instance(c, i, catalog)
            if known is not None and inst.known != bool(known):
                continue
            if (split is None or inst.split == split) and (family in (None, inst.family)):
                out.append(inst)
    return tuple(out)


def find_instance(name: str) -> ObjectInstance:
    """The instance called ``name`` in any catalogue (v1 ``mug_03``, v2 ``mug_barrel_3``).

    Raises
    ------
    ObjectCatalogError
        If no instance has that name.
    """
    for catalog in CATALOGS:
        for c in CATEGORIES:
            if isinstance(name, str) and name.startswith(c + "_"):
                for i in range(_count(c, catalog)):
                    if get_instance(c, i, catalog).name == name:
                        return get_instance(c, i, catalog)
    raise ObjectCatalogError(
        f"no instance called {name!r}; names are <category>_<index:02d> (v1) or "
        f"<category>_<family>_<0-7> (v2), categories: {', '.join(CATEGORIES)}"
    )
