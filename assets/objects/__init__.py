"""Procedural household objects: five categories in two deterministic catalogues.

Categories, in bin order: ``juice_bottle, milk_carton, bowl, mug, juice_box``. Catalogue
``"v1"`` (``Sorting-v1``): 12 instances per category, one shape family; instances 0-7 are
*known* (perception may train on them), 8-11 *unknown* (held out). Catalogue ``"v2"``:
:data:`FAMILIES` (>= 3 real product types per category, sources in :mod:`.families`), 8
textured instances each; the last family of a category is *novel* (held out entirely), in the
others instances 0-5 are *train* and 6-7 *similar*.

>>> inst = get_instance("mug", 3)
>>> pose = resting_poses(inst)[0]  # "upright"
>>> body = add_object(spec, inst, "obj0", pos=(x, y, table_z + pose.height), quat=pose.quat)

Modules: :mod:`.catalog` (instances, split rule), :mod:`.instance` (:class:`ObjectInstance`),
:mod:`.params` (category dimensions and their real-world ranges), :mod:`.meshes` (numpy mesh
builders), :mod:`.primitives` (visual parts, collision primitives), :mod:`.v1_geometry` (v1
meshes and collision), :mod:`.geometry` (an instance's parts and inertia), :mod:`.poses`
(resting poses), :mod:`.builder` (:func:`add_object`); v2: :mod:`.families` (families,
sources, split rule), :mod:`.family_shapes`, :mod:`.family_samplers`, :mod:`.uv_meshes`,
:mod:`.family_geometry` (UV-mapped, textured meshes), :mod:`.textures`; v3:
:mod:`.convex_collision` (bowls and mugs as a few convex pieces each).
"""

from ipbench.assets.objects.builder import (
    COLLISION_GROUP,
    FRICTION,
    SPECULAR_THRESHOLD,
    VISUAL_GROUP,
    add_object,
)
from ipbench.assets.objects.catalog import (
    CATALOGS,
    CATEGORIES,
    INSTANCES_PER_CATEGORY,
    KNOWN_INSTANCES,
    ObjectCatalogError,
    find_instance,
    get_instance,
    instances,
)
from ipbench.assets.objects.families import FAMILIES, SPLITS
from ipbench.assets.objects.instance import ObjectInstance
from ipbench.assets.objects.poses import RestingPose, resting_poses

__all__ = [
    "CATALOGS",
    "CATEGORIES",
    "FAMILIES",
    "SPLITS",
    "INSTANCES_PER_CATEGORY",
    "KNOWN_INSTANCES",
    "ObjectCatalogError",
    "ObjectInstance",
    "get_instance",
    "instances",
    "find_instance",
    "RestingPose",
    "resting_poses",
    "add_object",
    "SPECULAR_THRESHOLD",
    "FRICTION",
    "VISUAL_GROUP",
    "COLLISION_GROUP",
]
