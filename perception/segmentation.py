"""Table-top object segmentation of a depth cloud (thesis ch. 5 §5.3.1, ch. 6 §6.4.1).

Non-foveated (:func:`segment_scene`), as PCL's table-top pipeline: pass-through box (the work
table) -> voxel grid -> RANSAC table plane (open3d, seeded and run on one thread: its parallel
RANSAC is not repeatable even with a seed; refined by least squares on its inliers, retried
while the plane is tilted) -> convex hull of the inliers in the plane's 2-D
coordinates, extruded into a prism ``(min_height, prism_height]`` above the table -> Euclidean
clustering of the voxels inside the prism (PCL's ``EuclideanClusterExtraction``: connected
components of the radius graph, deterministic, equivalent to DBSCAN with ``min_points=1``;
found by a compiled grid and union-find, :mod:`._cluster_kernels`, which leaves the rare
view with a pair within rounding of the tolerance to a scipy KD-tree) -> size rules ->
:class:`Segment` objects carrying *all* their points and pixels (labels go back from voxels
to points). Foveated: :func:`segment_region` (a box such as the inspection area) and
:func:`segment_in_hand` (the gripper's own points removed by its known geometry).
:mod:`~ipbench.perception.segment_eval` scores segments against ground truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np
import open3d as o3d
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, cKDTree

from ._cloud_kernels import HULL_LIMIT as _HULL_LIMIT
from ._cloud_kernels import hand_keep, hull_members
from ._cluster_kernels import radius_components
from .cloud import Cloud, PerceptionError, crop_box, voxel_grid

__all__ = [
    "DEFAULT_SEGMENTATION",
    "GripperGeometry",
    "SceneSegmentation",
    "Segment",
    "SegmentationConfig",
    "crop_box",
    "grasp_yaw",
    "make_segment",
    "plane_basis",
    "segment_in_hand",
    "segment_region",
    "segment_scene",
]


@dataclass(frozen=True)
class SegmentationConfig:
    """Parameters of the segmentation (units in the comments).

    Size rule: a cluster is kept iff it has ``>= min_points`` points (pixels) and the largest
    side of its box lies in ``[min_extent, max_extent]`` (smaller: noise or a sliver; larger:
    the table edge, the robot or background, never one household object).
    """

    workspace_min: tuple[float, float, float] = (0.55, -0.60, 0.60)  # m; pass-through box (world)
    workspace_max: tuple[float, float, float] = (1.35, 0.40, 1.10)  # m; = the work table
    voxel_size: float = 0.005  # m; voxel grid for RANSAC and clustering (speed)
    plane_distance: float = 0.01  # m; RANSAC inlier distance
    plane_iterations: int = 300  # RANSAC iterations
    plane_max_tilt_deg: float = 15.0  # deg; a plane tilted more is not the table (retry)
    plane_attempts: int = 3  # RANSAC runs, each without the previous (tilted) plane's inliers
    seed: int = 0  # open3d RANSAC seed
    min_height: float = 0.007  # m; above the plane (table noise: 98 % within +-5 mm at 1 m)
    prism_height: float = 0.30  # m; prism top above the table
    cluster_eps: float = 0.015  # m; Euclidean clustering distance between voxel centres
    min_points: int = 100  # points (= pixels) per segment
    min_extent: float = 0.02  # m; the largest box side must be at least this
    max_extent: float = 0.40  # m; and at most this
    hand_radius: float = 0.30  # m; in-hand: keep points within this of the TCP
    gripper_margin: float = 0.01  # m; in-hand: grown gripper boxes
    hand_cluster_eps: float = 0.025  # m; in-hand clustering distance (bridges specular holes)
    grasp_reach: float = 0.03  # m; in-hand: the object comes this close to the pads (or nearer)

    def __post_init__(self) -> None:
        positive = "voxel_size plane_distance plane_iterations plane_attempts prism_height "
        positive += "cluster_eps min_points max_extent hand_radius hand_cluster_eps"
        nonnegative = "min_height min_extent gripper_margin grasp_reach"
        rules = ((positive, "> 0", lambda v: v > 0), (nonnegative, ">= 0", lambda v: v >= 0))
        for names, rule, ok in rules:
            for name in names.split():
                if not ok(value := getattr(self, name)):
                    raise PerceptionError(f"SegmentationConfig.{name}={value!r}; valid: {rule}")
        if not (
            np.all(np.less(self.workspace_min, self.workspace_max))
            and self.min_extent <= self.max_extent
            and self.min_height < self.prism_height
        ):
            raise PerceptionError(
                f"SegmentationConfig: workspace {self.workspace_min}..{self.workspace_max}, "
                f"extents [{self.min_extent}, {self.max_extent}], heights ({self.min_height}, "
                f"{self.prism_height}]; valid: each lower bound below its upper bound"
            )


DEFAULT_SEGMENTATION = SegmentationConfig()


@dataclass(frozen=True, eq=False)
class Segment:
    """One object hypothesis. World frame, metres.

    ``box_rotation`` columns are the box axes: x along the longer horizontal side, y along the
    shorter, z = the table normal (up); ``box_extent`` holds full side lengths. The box
    reaches down to the table (the camera never sees an object's bottom); for in-hand
    segments "up" is world +z and the box spans the points. ``height`` is the top above the
    table (in hand: the vertical extent); ``top`` its world z. Top = 99th percentile.
    """

    points: np.ndarray  # (N, 3)
    pixels: np.ndarray  # (N,) flat pixel indices
    centroid: np.ndarray  # (3,)
    box_center: np.ndarray  # (3,)
    box_rotation: np.ndarray  # (3, 3)
    box_extent: np.ndarray  # (3,)
    height: float
    top: float


@dataclass(frozen=True, eq=False)
class SceneSegmentation:
    """Segments (largest first) and the table plane ``normal . x + offset = 0`` (normal up).

    ``oversized``: clusters that passed the point count but not ``max_extent`` (largest
    first): the table's edge, the robot, or a pile of touching objects, for a caller that can
    split them (:mod:`~ipbench.perception.split`); not part of ``segments``.
    """

    segments: tuple[Segment, ...]
    normal: np.ndarray  # (3,) unit
    offset: float  # m
    oversized: tuple[Segment, ...] = ()

    @property
    def plane(self) -> tuple[np.ndarray, float]:
        """``(normal, offset)``, e.g. for :func:`segment_region`."""
        return self.normal, self.offset


@dataclass(frozen=True)
class GripperGeometry:
    """The parallel-jaw gripper (``assets/motoman/gripper.xml``) in its palm frame, metres.

    +z is the approach direction, the jaws close along x; ``q`` = half the jaw opening. Each
    finger with its pad spans x in ``[q + finger_x[0], q + finger_x[1]]`` (mirrored for the
    other finger); the palm (flange cylinder, visual and collision boxes) is one box.
    """

    tcp_offset: float = 0.225  # m; the `tcp` site along +z of the palm
    palm_center: tuple[float, float, float] = (0.0, 0.0, 0.045)
    palm_half: tuple[float, float, float] = (0.135, 0.04, 0.045)  # y: the 0.04 m flange
    finger_x: tuple[float, float] = (0.0, 0.018)  # pad inner face at q, finger outside q+0.018
    finger_half_y: float = 0.022
    finger_z: tuple[float, float] = (0.08, 0.26)  # finger body 0.17 +- 0.09

    def boxes(self, jaw_opening: float) -> list[tuple[np.ndarray, np.ndarray]]:
        """(centre (3,), half sizes (3,)) of the palm and both fingers in the TCP frame."""
        q = 0.5 * jaw_opening
        zc, zh = 0.5 * (self.finger_z[0] + self.finger_z[1]), 0.5 * np.ptp(self.finger_z)
        xc, xh = q + 0.5 * sum(self.finger_x), 0.5 * (self.finger_x[1] - self.finger_x[0])
        shift = np.array([0.0, 0.0, self.tcp_offset])
        half = np.array([xh, self.finger_half_y, zh])
        boxes = [(np.array(self.palm_center) - shift, np.array(self.palm_half))]
        return boxes + [(np.array([s * xc, 0.0, zc]) - shift, half) for s in (1.0, -1.0)]


def _fit_plane(points: np.ndarray, config: SegmentationConfig) -> tuple[np.ndarray, float]:
    """Table plane (unit normal with +z component, offset) by seeded RANSAC + least squares."""
    remaining = points
    for _ in range(config.plane_attempts):
        if len(remaining) < 3:
            break
        pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(remaining))
        threads = o3d.utility.get_max_threads()
        o3d.utility.set_max_threads(1)  # the seed makes only a one-thread RANSAC repeatable
        try:
            o3d.utility.random.seed(config.seed)
            model, _ = pcd.segment_plane(config.plane_distance, 3, config.plane_iterations)
        finally:
            o3d.utility.set_max_threads(threads)
        normal, offset = np.asarray(model[:3]), float(model[3])
        scale = np.linalg.norm(normal) * (1.0 if normal[2] >= 0 else -1.0)
        normal, offset = normal / scale, offset / scale
        if normal[2] >= math.cos(math.radians(config.plane_max_tilt_deg)):
            inlier = np.abs(points @ normal + offset) <= config.plane_distance
            centre = points[inlier].mean(axis=0)
            normal = np.linalg.svd(points[inlier] - centre, full_matrices=False)[2][2]
            normal = normal if normal[2] >= 0 else -normal
            return normal, -float(normal @ centre)
        remaining = remaining[np.abs(remaining @ normal + offset) > config.plane_distance]
    raise PerceptionError(
        f"no table plane within {config.plane_max_tilt_deg} deg of horizontal among "
        f"{len(points)} voxels; valid: a cloud showing the table top"
    )


def _cross(a, b) -> np.ndarray:
    """``np.cross`` of two 3-vectors (3,) with numpy's operations (``a1 b2 - a2 b1``, ...: each
    product rounded, then the difference), without its general-shape machinery."""
    a0, a1, a2 = (float(v) for v in a)
    b0, b1, b2 = (float(v) for v in b)
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def plane_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (3,) spanning the plane of unit ``normal`` (3,), with ``normal`` a
    right-handed frame."""
    e1 = _cross(normal, [0.0, 1.0, 0.0] if abs(normal[0]) > 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    return e1, _cross(normal, e1)


def make_segment(points, pixels, up, offset: float | None) -> Segment:
    """Segment of ``points`` (N, 3) from ``pixels`` (N,), its box about ``up`` (3,); heights
    from the plane ``up . x + offset = 0`` (``offset`` given) or from the lowest point."""
    e1, e2 = plane_basis(up)
    flat = np.column_stack([points @ e1, points @ e2])
    (cx, cy), _, _ = rect = cv2.minAreaRect(flat.astype(np.float32))
    corners = cv2.boxPoints(rect).astype(np.float64)
    sides = [corners[1] - corners[0], corners[2] - corners[1]]
    lengths = [float(np.linalg.norm(s)) for s in sides]
    long = int(lengths[1] > lengths[0])
    axis2d = sides[long] / max(lengths[long], 1e-12)
    x = axis2d[0] * e1 + axis2d[1] * e2
    rotation = np.column_stack([x, _cross(up, x), up])
    heights = points @ up + (offset if offset is not None else 0.0)
    top = float(np.percentile(heights, 99))
    bottom = 0.0 if offset is not None else float(np.percentile(heights, 1))
    centre_up = 0.5 * (top + bottom) - (offset if offset is not None else 0.0)
    return Segment(
        points=points,
        pixels=pixels,
        centroid=points.mean(axis=0),
        box_center=cx * e1 + cy * e2 + centre_up * up,
        box_rotation=rotation,
        box_extent=np.array([lengths[long], lengths[1 - long], top - bottom]),
        height=top - bottom,
        top=float(np.percentile(points[:, 2], 99)),
    )


def _components_by_tree(centres: np.ndarray, eps: float) -> np.ndarray:
    """Connected components (V,) int32 of the graph joining the voxel ``centres`` (V, 3) at
    most ``eps`` apart (m), numbered by smallest member: a kd-tree's pairs and scipy's
    components, the reference that :func:`~._cluster_kernels.radius_components` gives
    whenever it answers."""
    pairs = cKDTree(centres).query_pairs(eps, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), (len(centres),) * 2)
    return connected_components(graph, directed=False)[1]


def _over_hull(points: np.ndarray, index: np.ndarray, e1, e2, equations) -> np.ndarray:
    """Mask (M,) of ``points[index]`` whose plane coordinates ``(p . e1, p . e2)`` are in the
    hull of facets ``equations`` (F, 3) within :data:`~._cloud_kernels.HULL_LIMIT` (m): the
    compiled test, or numpy's expression for a point within rounding of the limit."""
    decided, inside = hull_members(points, index, e1, e2, equations)
    if decided:
        return inside
    flat = np.column_stack([points[index] @ e1, points[index] @ e2])
    return np.all(flat @ equations[:, :2].T + equations[:, 2] <= _HULL_LIMIT, axis=1)


def _cluster(
    cloud: Cloud, config: SegmentationConfig, up, offset, oversized: list | None = None
) -> list[Segment]:
    """Euclidean clusters of ``cloud`` passing the size rules, largest first (those larger
    than ``max_extent`` are appended to ``oversized`` when given)."""
    if len(cloud) == 0:
        return []
    centres, voxel_of = voxel_grid(cloud.points, config.voxel_size)
    labels = radius_components(centres, config.cluster_eps)
    if labels is None:  # a pair at eps within rounding (or a huge grid): the kd-tree decides
        labels = _components_by_tree(centres, config.cluster_eps)
    labels = labels[voxel_of]
    order = np.argsort(labels, kind="stable")
    starts = np.flatnonzero(np.diff(labels[order], prepend=-1))
    segments = []
    for members in np.split(order, starts[1:]):
        if len(members) < config.min_points:
            continue
        seg = make_segment(cloud.points[members], cloud.pixels[members], up, offset)
        if config.min_extent <= max(seg.box_extent) <= config.max_extent:
            segments.append(seg)
        elif oversized is not None and max(seg.box_extent) > config.max_extent:
            oversized.append(seg)
    if oversized is not None:
        oversized.sort(key=lambda s: -len(s.points))
    return sorted(segments, key=lambda s: -len(s.points))


def _segment(cloud: Cloud, config: SegmentationConfig, plane) -> SceneSegmentation:
    if plane is None:
        plane = _fit_plane(voxel_grid(cloud.points, config.voxel_size)[0], config)
    normal, offset = np.asarray(plane[0], dtype=np.float64), float(plane[1])
    height = cloud.points @ normal + offset
    near = np.abs(height) <= config.plane_distance
    e1, e2 = plane_basis(normal)
    keep = np.flatnonzero((height > config.min_height) & (height <= config.prism_height))
    if near.sum() >= 3 and len(keep):
        hull_pts = cloud.points[near][:: max(1, int(near.sum()) // 20000)]
        try:
            hull = ConvexHull(np.column_stack([hull_pts @ e1, hull_pts @ e2]))
        except Exception as err:  # degenerate (collinear) support
            raise PerceptionError(f"table hull is degenerate ({err}); valid: a 2-D table") from err
        points = np.ascontiguousarray(cloud.points, dtype=np.float64)
        keep = keep[_over_hull(points, keep, e1, e2, np.ascontiguousarray(hull.equations))]
    else:
        keep = keep[:0]
    oversized: list[Segment] = []
    segments = _cluster(cloud.subset(keep), config, normal, offset, oversized)
    return SceneSegmentation(tuple(segments), normal, offset, tuple(oversized))


def segment_scene(
    cloud: Cloud, config: SegmentationConfig = DEFAULT_SEGMENTATION
) -> SceneSegmentation:
    """Non-foveated table-top segmentation of a whole view (see the module docstring).

    Raises :class:`PerceptionError` when no horizontal table plane is found.
    """
    box = np.array([config.workspace_min, config.workspace_max])
    region = crop_box(cloud, box.mean(axis=0), 0.5 * (box[1] - box[0]))
    return _segment(region, config, None)


def segment_region(
    cloud: Cloud, center, half, config: SegmentationConfig = DEFAULT_SEGMENTATION, plane=None
) -> Segment | None:
    """Foveated segmentation in a world box (e.g. the inspection area): the largest segment.

    ``center``, ``half``: (3,) m, the box (it must include some table around the object);
    ``plane``: an already known ``(normal, offset)`` (e.g. from :func:`segment_scene`) to skip
    RANSAC. None when nothing passes the size rules.
    """
    segments = _segment(crop_box(cloud, center, half), config, plane).segments
    return segments[0] if segments else None


def segment_in_hand(
    cloud: Cloud,
    tcp_pose: np.ndarray,
    jaw_opening: float,
    gripper: GripperGeometry | None = None,
    config: SegmentationConfig = DEFAULT_SEGMENTATION,
) -> Segment | None:
    """The object held by the gripper: the largest cluster between the jaws, gripper removed.

    ``tcp_pose``: (4, 4) world-from-TCP (from the robot's joints); ``jaw_opening``: distance
    between the pads, m. Points farther than ``hand_radius`` from the TCP, behind the palm's
    front face, or inside the palm and finger boxes grown by ``gripper_margin`` are dropped;
    of the clusters passing the size rules, the largest one with a point within
    ``jaw_opening / 2 + grasp_reach`` of the TCP is the object (background objects below the
    hand are often larger). None when there is none.
    """
    gripper = gripper or GripperGeometry()
    pose = np.asarray(tcp_pose, dtype=np.float64)
    if pose.shape != (4, 4) or not np.isfinite(pose).all() or not 0 <= jaw_opening < 1:
        raise PerceptionError("valid: tcp_pose a finite 4x4 transform, 0 <= jaw_opening < 1 m")
    local = (cloud.points - pose[:3, 3]) @ pose[:3, :3]
    palm_front = gripper.palm_center[2] + gripper.palm_half[2] - gripper.tcp_offset
    boxes = gripper.boxes(jaw_opening)
    keep = hand_keep(
        np.ascontiguousarray(local),
        float(config.hand_radius),
        float(palm_front),
        np.array([centre for centre, _ in boxes], dtype=np.float64).reshape(-1, 3),
        np.array([half + config.gripper_margin for _, half in boxes], np.float64).reshape(-1, 3),
    )
    reach = 0.5 * jaw_opening + config.grasp_reach
    hand = replace(config, cluster_eps=config.hand_cluster_eps)
    for segment in _cluster(cloud.subset(keep), hand, np.array([0.0, 0.0, 1.0]), None):
        if np.min(np.linalg.norm(segment.points - pose[:3, 3], axis=1)) <= reach:
            return segment  # the largest cluster reaching in between the jaws
    return None


def grasp_yaw(segment: Segment) -> float:
    """Jaw yaw (rad, in [-pi/2, pi/2)) closing across the box's narrower horizontal side.

    The environment's convention: jaws close along ``(cos yaw, sin yaw, 0)``.
    """
    y = segment.box_rotation[:, 1]
    return float((math.atan2(y[1], y[0]) + math.pi / 2) % math.pi - math.pi / 2)
