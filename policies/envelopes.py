"""How big the objects the robot sorts can be: the size prior of the merged-segment split.

A robot sorting household objects knows how large such objects get, though not which one it
sees. :func:`object_envelopes` gives, for every instance of both catalogues (the v1 one and
the v2 families, whose dimensions come from real products; see
:mod:`ipbench.assets.objects.params` and :mod:`ipbench.assets.objects.families`) and each of
its resting poses, the box it fills on the table (footprint sides, height). A segment that
fits none of them holds more than one object
(:func:`~ipbench.perception.split.fits_one_object`). The prior says nothing about categories:
every envelope counts for every segment.
"""

from __future__ import annotations

from functools import cache

import mujoco
import numpy as np

from ipbench.assets.objects import CATALOGS, instances, resting_poses
from ipbench.perception.split import ObjectEnvelope

__all__ = ["object_envelopes"]


def _envelope(size, center, quat) -> ObjectEnvelope:
    half = 0.5 * np.asarray(size, dtype=float)
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, np.asarray(quat, dtype=float))
    corners = (np.asarray(center, dtype=float) + signs * half) @ rot.reshape(3, 3).T
    ext = corners.max(axis=0) - corners.min(axis=0)
    long, short = sorted(ext[:2])[::-1]
    return ObjectEnvelope(float(long), float(short), float(ext[2]))


@cache
def object_envelopes() -> tuple[ObjectEnvelope, ...]:
    """The envelope of every instance of every catalogue in each of its resting poses, each
    box once: the instance's bounding box turned into the pose (a yaw about the vertical does
    not change the footprint's own sides, which are what a segment's box is compared with)."""
    boxes = {
        _envelope(inst.size, inst.center, pose.quat)
        for catalog in CATALOGS
        for inst in instances(catalog=catalog)
        for pose in resting_poses(inst)
    }
    return tuple(sorted(boxes, key=lambda e: (e.long, e.short, e.height)))
