"""Perception: depth to point cloud, segmentation, FPFH bag-of-words, GP classification.

Filled in by the perception issue; perception only ever reads observations, never
simulator state.
"""

__all__: list[str] = []
