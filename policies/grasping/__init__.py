"""Grasp geometry: where a top-down parallel-jaw grasp goes, how it turns and how wide it opens.

Three modules, each one kind of grasp maths the policies share:

- :mod:`~ipbench.policies.grasping.segments`: the grasp of a perceived segment
  (:func:`grasp_target`: its footprint completed behind its visible front, a short round
  object centred on its rim, candidate jaw yaws and openings), and the memory of grasps that
  failed (:class:`FailureMemory`);
- :mod:`~ipbench.policies.grasping.free`: whether the depth image shows a grasp to be free
  (the fingers' landing boxes, the closing box between the pads and the palm against the
  cloud, :func:`~ipbench.policies.grasping.free.check_grasp`);
- :mod:`~ipbench.policies.grasping.boxes`: the grasp of an object whose pose and bounding box
  are known (the ground-truth sorter's and the in-hand capture rig's), and the rules for short
  objects and jaw openings that segment grasps share.

The segment grasp's names are this package's own (``from ipbench.policies.grasping import
grasp_target``), the public entry point for a policy of one's own.
"""

from ipbench.policies.grasping.segments import (
    FailureMemory,
    GraspTarget,
    completed_footprint,
    grasp_target,
    jaw_opening,
    rim_circle,
)

__all__ = [
    "FailureMemory",
    "GraspTarget",
    "completed_footprint",
    "grasp_target",
    "jaw_opening",
    "rim_circle",
]
