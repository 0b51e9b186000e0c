"""The sorting task's scenes (thesis Table 5.1): each one's composition and placement rules.

A scene (:class:`SceneConfig`) says how many objects of each category it holds and how they
are laid out: spread apart, clustered, or piled; :data:`SCENES` names every scene and
:func:`scenes_for` the ones an object catalogue has. :func:`~ipbench.envs.layout.sample_layout`
turns a scene and a seed into a :class:`~ipbench.envs.layout.Layout`.
"""

from __future__ import annotations

from dataclasses import dataclass

from ipbench.assets.objects import CATALOGS

__all__ = [
    "PACKINGS",
    "SCENES",
    "STANDARD_SCENES",
    "SceneConfig",
    "scenes_for",
]


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
        each next to one already placed (``gap`` to 2 ``gap`` away), growing one tight pile;
        ``"pile"`` packs a base layer on the table as tightly and lays the objects that do
        not fit, and ``on_top`` more, on top of it (:func:`~ipbench.envs.layout._place_pile`).
    on_top : objects laid on the pile whether or not they would fit on the table
        (``"pile"`` only); ``lying_fraction`` is then the base layer's.
    gentle_settle : longest physics time (s) of a gentle settling at reset, before the
        environment's ``settle_time``: the objects' motion damped until they are at rest
        (0: none; a pile's objects come down onto the others that way, see
        :func:`~ipbench.envs.settling.settle_gently`).
    every_family : the draw holds every family of each category at least once (each
        category's count must be at least its number of families; v2 catalogue).
    catalogs : the object catalogues the scene exists in (a scene built for the v2 families
        is not one of the released ``Sorting-v0``/``-v1``'s).
    """

    name: str
    counts: tuple[int, int, int, int, int]
    area_fraction: tuple[float, float] = (1.0, 1.0)
    gap: float = 0.03
    lying_fraction: float = 0.0
    packing: str = "scatter"
    on_top: int = 0
    gentle_settle: float = 0.0
    every_family: bool = False
    catalogs: tuple[str, ...] = CATALOGS

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
    # Pile: a harder tier than cluttered, with heavy mutual occlusion from the wrist
    # camera. 4 of each category: 20 objects, every bin equally often the right one, and the
    # fewest equal counts that hold all families of every category (3 or 4 each) in every
    # pile. In cluttered's spawn area (the robot reaches it) their footprints cover about all
    # the area: about 10 form a base layer on the table, half of those that can lie on their
    # side lying, and the others (6 to 12, at least 3) are laid on top of them, hiding parts
    # of them. They come to rest there in a gentle settling at reset (at most 6 s of physics,
    # 2.7 s on average: the objects of the other scenes start at rest and settle in 0.3 s).
    # v2 catalogue only (its families).
    "pile": SceneConfig(
        "pile",
        (4, 4, 4, 4, 4),
        gap=0.0,
        lying_fraction=0.5,
        packing="pile",
        on_top=3,
        gentle_settle=6.0,
        every_family=True,
        catalogs=("v2",),
    ),
}
"""Every scene, by name. :data:`STANDARD_SCENES` are the released ones (thesis Table 5.1),
on every id; ``"pile"`` exists on ``Sorting-v2`` only (:func:`scenes_for`)."""

STANDARD_SCENES: tuple[str, ...] = ("uncluttered", "cluttered")
"""The thesis's scenes (Table 5.1), the released ids' only ones: what the released
evaluation's validation episodes, perception scores and stage digests iterate over."""

PACKINGS: tuple[str, ...] = ("scatter", "cluster", "pile")
"""The valid :attr:`SceneConfig.packing` values."""


def scenes_for(catalog: str) -> tuple[str, ...]:
    """The names of the scenes that exist in object catalogue ``catalog`` (``"v1"``: the
    standard scenes; ``"v2"``: also ``"pile"``), in :data:`SCENES` order."""
    return tuple(name for name, config in SCENES.items() if catalog in config.catalogs)
