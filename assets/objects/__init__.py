"""Procedural household objects: five categories x 12 deterministic instances.

Categories, in bin order: ``juice_bottle, milk_carton, bowl, mug, juice_box``. Instances
0-7 of each category are *known* (perception may train on them), 8-11 *unknown* (held out).

>>> inst = get_instance("mug", 3)
>>> pose = resting_poses(inst)[0]  # "upright"
>>> body = add_object(spec, inst, "obj0", pos=(x, y, table_z + pose.height), quat=pose.quat)

Modules: :mod:`.catalog` (instances, split rule), :mod:`.params` (category dimensions and
their real-world ranges), :mod:`.meshes` (numpy mesh builders), :mod:`.geometry` (visual
meshes, collision primitives, inertia), :mod:`.poses` (resting poses), :mod:`.builder`
(:func:`add_object`).
"""

from ipbench.assets.objects.builder import (
    COLLISION_GROUP,
    FRICTION,
    SPECULAR_THRESHOLD,
    VISUAL_GROUP,
    add_object,
)
from ipbench.assets.objects.catalog import (
    CATEGORIES,
    INSTANCES_PER_CATEGORY,
    KNOWN_INSTANCES,
    ObjectCatalogError,
    ObjectInstance,
    get_instance,
    instances,
)
from ipbench.assets.objects.poses import RestingPose, resting_poses

__all__ = [
    "CATEGORIES",
    "INSTANCES_PER_CATEGORY",
    "KNOWN_INSTANCES",
    "ObjectCatalogError",
    "ObjectInstance",
    "get_instance",
    "instances",
    "RestingPose",
    "resting_poses",
    "add_object",
    "SPECULAR_THRESHOLD",
    "FRICTION",
    "VISUAL_GROUP",
    "COLLISION_GROUP",
]
