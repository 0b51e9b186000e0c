"""How an instance is modelled in MuJoCo: :class:`ObjectModel`, the version of its collision
geometry and of its printed textures.

The catalogues fix what an object *is* (its dimensions, mass, colours and prints); an object
model fixes how the simulator represents it. ``ObjectModel()`` is the model every released id
runs (``Sorting-v0`` to ``-v2``, ``Exploration-v0``): hollow objects collide as rings of thin
boxes and printed textures are mapped as they were released. ``Sorting-v3`` runs
:data:`~ipbench.envs.sorting_config.V3`'s model: hollow objects as a few convex pieces each, prints
upright. Mass, centre of mass and inertia are the same under every model (computed from the
thin-wall primitives, :func:`~ipbench.assets.objects.geometry.object_geometry`).
"""

from __future__ import annotations

from dataclasses import dataclass

from ipbench.assets.objects.catalog import ObjectCatalogError

__all__ = ["HOLLOW_COLLISIONS", "RELEASED_MODEL", "ObjectModel"]

HOLLOW_COLLISIONS: tuple[str, ...] = ("box_rings", "convex")
"""Collision models of hollow objects (bowls, mugs): ``"box_rings"``, walls as rings of 16
thin boxes per wall section (v1, v2); ``"convex"``, a few convex pieces per object."""


@dataclass(frozen=True)
class ObjectModel:
    """How instances become MuJoCo bodies.

    Attributes
    ----------
    hollow_collision : one of :data:`HOLLOW_COLLISIONS`; the collision geometry of bowls and
        mugs (every other object has the same collision geometry under both).
    upright_prints : printed textures (labels, carton and box prints, glaze) read upright, as
        on the real product; ``False`` keeps the released mapping, which shows them mirrored
        top to bottom (image row 0 at the part's bottom).
    """

    hollow_collision: str = "box_rings"
    upright_prints: bool = False

    def __post_init__(self) -> None:
        if self.hollow_collision not in HOLLOW_COLLISIONS:
            raise ObjectCatalogError(
                f"unknown hollow_collision {self.hollow_collision!r}; "
                f"valid: {', '.join(HOLLOW_COLLISIONS)}"
            )
        if not isinstance(self.upright_prints, bool):
            raise ObjectCatalogError(
                f"upright_prints must be True or False, got {self.upright_prints!r}"
            )


RELEASED_MODEL = ObjectModel()
"""The model of every released id: hollow objects as box rings, prints as released."""
