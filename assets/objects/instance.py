"""One procedural object of a catalogue: :class:`ObjectInstance`, its identity and dimensions.

The catalogues (:mod:`~ipbench.assets.objects.catalog`) make instances; the geometry builders
(:mod:`~ipbench.assets.objects.geometry`), the resting poses and the MuJoCo builder read them.
"""

from __future__ import annotations

from dataclasses import dataclass

from ipbench.assets.objects.params import Shape

__all__ = ["ObjectInstance"]


@dataclass(frozen=True)
class ObjectInstance:
    """One procedural object.

    Attributes
    ----------
    category : one of :data:`~ipbench.assets.objects.catalog.CATEGORIES`.
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
    shape : the category's dimensions (:mod:`ipbench.assets.objects.params`,
        :mod:`ipbench.assets.objects.family_shapes`), m.
    family : its shape family, a member of ``FAMILIES[category]``.
    split : ``"train"``, ``"similar"`` (unseen instance of a trained family) or ``"novel"``
        (instance of a family held out of training).
    catalog : ``"v1"`` or ``"v2"``; v2 instances carry UV-textured visual meshes.
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
    family: str
    split: str
    catalog: str
