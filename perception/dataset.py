"""Training and test views rendered by the simulator, as the thesis captured its database.

Each catalogue instance stands alone at the centre of the table's spawn area and the wrist
Xtion (with its depth noise) looks at it from ``elevations`` at ``distance``, while the object
turns in ``yaw_step`` steps (18 views at 20 deg), upright and, for objects that can lie, on its
side. Every view goes through the same perception as an episode: point cloud, table plane,
prism and clustering; the largest segment's FPFH descriptors are stored (not yet encoded, so
the codebook can be refitted). *Known* instances make the training set, *unknown* ones the
test set; segments cut out of cluttered scenes, labelled by their overlap with the
ground-truth masks, make the realistic test set.

This module renders with the simulator (it produces data, like a capture rig); perception
itself never reads simulator state. Results are cached on disk under a hash of the
configuration; a missing, stale or corrupt cache file is rebuilt with a message.
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing
import zipfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import mujoco
import numpy as np
from tqdm import tqdm

from ipbench.assets.objects import (
    CATEGORIES,
    KNOWN_INSTANCES,
    ObjectInstance,
    instances,
    resting_poses,
)
from ipbench.envs.depth_noise import DepthNoiseConfig, DepthNoiseModel
from ipbench.envs.ik import look_at_rotation
from ipbench.envs.layout import Layout, PlacedObject
from ipbench.envs.robot import RobotController, ik_model
from ipbench.envs.sensors import SensorRenderer, camera_pose, intrinsics, specular_geoms
from ipbench.envs.skills import Skills
from ipbench.envs.sorting import WRIST_CAMERA, WRIST_SIZE
from ipbench.envs.world import Places, build_world
from ipbench.perception.cloud import PerceptionError, depth_to_points
from ipbench.perception.features import FeatureConfig, fpfh
from ipbench.perception.segmentation import SegmentationConfig, segment_scene

__all__ = [
    "DatasetConfig",
    "ViewSet",
    "render_instance_views",
    "render_cluttered_segments",
    "load_or_build",
    "DATASET_VERSION",
]

DATASET_VERSION = 1
"""Bumped whenever the rendering protocol changes, so old caches are rebuilt."""


@dataclass(frozen=True)
class DatasetConfig:
    """How views are captured.

    Attributes
    ----------
    yaw_step_deg : object rotation between views (deg); 20 gives the thesis' 18 views.
    elevations_deg : camera elevations above the table for upright objects (deg).
    side_elevation_deg : camera elevation for objects lying on their side (deg); ``None``
        skips lying poses.
    distance : camera distance from the object's base centre (m).
    seed : seeds the depth noise and RANSAC.
    cluttered_seeds : episode seeds of the cluttered scenes whose segments form the realistic
        test set (disjoint from the seeds the sorting evaluation uses, which start at 0).
    per_category : if set, only the first ``per_category`` known and the first
        ``per_category`` unknown instances of each category (for quick runs and tests).
    min_overlap : a cluttered segment is labelled with the object that covers at least this
        fraction of its pixels; segments without such an object (merged ones) are dropped.
    depth_noise, segmentation, features : the sensor and perception settings.
    """

    yaw_step_deg: float = 20.0
    elevations_deg: tuple[float, ...] = (40.0, 65.0)
    side_elevation_deg: float | None = 55.0
    distance: float = 0.75
    seed: int = 0
    cluttered_seeds: tuple[int, ...] = tuple(range(10_000, 10_012))
    min_overlap: float = 0.6
    per_category: int | None = None
    depth_noise: DepthNoiseConfig = field(default_factory=DepthNoiseConfig)
    segmentation: SegmentationConfig = field(default_factory=SegmentationConfig)
    features: FeatureConfig = field(default_factory=FeatureConfig)

    def key(self) -> str:
        """Hash of everything that changes the data (the cache key)."""
        text = json.dumps({"v": DATASET_VERSION, **asdict(self)}, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class ViewSet:
    """Views with their FPFH descriptors.

    Attributes
    ----------
    descriptors : (total, 33) float32 FPFH descriptors of all views, concatenated.
    offsets : (n + 1,) int64: view i owns ``descriptors[offsets[i]:offsets[i+1]]``.
    labels : (n,) category index (bin order).
    instance : (n,) instance name.
    known : (n,) bool, known (training) instance.
    source : (n,) "isolated" or "cluttered".
    """

    descriptors: np.ndarray
    offsets: np.ndarray
    labels: np.ndarray
    instance: np.ndarray
    known: np.ndarray
    source: np.ndarray

    def __len__(self) -> int:
        return len(self.labels)

    def view(self, i: int) -> np.ndarray:
        return self.descriptors[self.offsets[i] : self.offsets[i + 1]]

    def subset(self, mask: np.ndarray) -> ViewSet:
        idx = np.flatnonzero(mask)
        parts = [self.view(i) for i in idx]
        lengths = np.array([len(p) for p in parts], np.int64)
        return ViewSet(
            descriptors=np.concatenate(parts) if parts else np.zeros((0, 33), np.float32),
            offsets=np.concatenate([[0], np.cumsum(lengths)]),
            labels=self.labels[idx],
            instance=self.instance[idx],
            known=self.known[idx],
            source=self.source[idx],
        )

    @staticmethod
    def concat(sets: list[ViewSet]) -> ViewSet:
        sets = [s for s in sets if len(s)]
        if not sets:
            return _EMPTY
        lengths = np.concatenate([np.diff(s.offsets) for s in sets])
        return ViewSet(
            descriptors=np.concatenate([s.descriptors for s in sets]),
            offsets=np.concatenate([[0], np.cumsum(lengths)]),
            labels=np.concatenate([s.labels for s in sets]),
            instance=np.concatenate([s.instance for s in sets]),
            known=np.concatenate([s.known for s in sets]),
            source=np.concatenate([s.source for s in sets]),
        )

    def save(self, path: Path) -> None:
        np.savez_compressed(path, **asdict(self))

    @classmethod
    def load(cls, path: Path) -> ViewSet:
        with np.load(path, allow_pickle=False) as data:
            return cls(**{k: data[k] for k in cls.__dataclass_fields__})


_EMPTY = ViewSet(
    np.zeros((0, 33), np.float32),
    np.zeros(1, np.int64),
    np.zeros(0, np.int64),
    np.zeros(0, "U32"),
    np.zeros(0, bool),
    np.zeros(0, "U16"),
)


def _views(config: DatasetConfig, inst: ObjectInstance):
    """(resting pose, yaw, elevation) of every view of ``inst``."""
    yaws = np.radians(np.arange(0.0, 360.0, config.yaw_step_deg))
    for pose in resting_poses(inst):
        if pose.name == "upright":
            elevations = config.elevations_deg
        elif pose.name == "side" and config.side_elevation_deg is not None:
            elevations = (config.side_elevation_deg,)
        else:
            continue
        for elevation in elevations:
            for yaw in yaws:
                yield pose, float(yaw), float(np.radians(elevation))


def render_instance_views(inst: ObjectInstance, config: DatasetConfig) -> ViewSet:
    """Render and segment every view of one instance (see the module docstring)."""
    center = Places.from_model(ik_model()).spawn_area.center.copy()
    poses = resting_poses(inst)
    placed = PlacedObject(
        0, inst, poses[0], tuple(center + [0, 0, poses[0].height]), 0.0, poses[0].quat
    )
    world = build_world(Layout("isolated", 0, (placed,)))
    places = world.places
    model = world.model
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
    robot = RobotController(model, data, step=lambda: None)
    skills = Skills(robot, world.places)
    park = world.places.inspection_area.center + np.array([-0.05, 0.25, 0.6])
    robot.teleport(
        dict(zip(skills.ready.joints, skills.tool_pose(park[:2], park[2], 0.0).qpos, strict=True))
    )
    renderer = SensorRenderer(model)
    noise = DepthNoiseModel(config.depth_noise)
    rng = np.random.default_rng([config.seed, inst.index, CATEGORIES.index(inst.category)])
    h, w = WRIST_SIZE
    k = intrinsics(model, WRIST_CAMERA, w, h)
    shiny = np.append(specular_geoms(model), False)  # index -1 = background
    toward_robot = places.scene_view[:2] - places.scene_target[:2]
    toward_robot /= np.linalg.norm(toward_robot)
    qadr = model.jnt_qposadr[model.body_jntadr[world.object_bodies[0]]]
    descriptors, labels = [], []
    camera_q: dict[float, dict[str, float]] = {}
    try:
        for pose, yaw, elevation in _views(config, inst):
            quat = np.empty(4)
            mujoco.mju_mulQuat(quat, [np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)], pose.quat)
            data.qpos[qadr : qadr + 3] = center + [0, 0, pose.height]
            data.qpos[qadr + 3 : qadr + 7] = quat
            if elevation not in camera_q:
                target = center + [0, 0, 0.08]
                eye = (
                    target
                    + config.distance * np.r_[np.cos(elevation) * toward_robot, np.sin(elevation)]
                )
                sol = robot.solve(
                    robot.camera_ik,
                    eye,
                    look_at_rotation(eye, target),
                    seeds=(skills.camera_ready,),
                )
                camera_q[elevation] = dict(zip(sol.joints, sol.qpos, strict=True))
            robot.teleport(camera_q[elevation])  # also runs mj_forward
            rgb, depth = renderer.render_rgbd(data, WRIST_CAMERA, w, h)
            seg = renderer.render_segmentation(data, WRIST_CAMERA, w, h)
            depth = noise.apply(depth, k.fx, k.fy, rng, specular=shiny[seg])
            pose_cw = camera_pose(model, data, WRIST_CAMERA)
            cloud = depth_to_points(depth, k.K, pose_cw)
            try:
                segments = segment_scene(cloud, config.segmentation).segments
            except PerceptionError:  # no table plane found in this view
                continue
            if not segments:
                continue
            biggest = max(segments, key=lambda s: len(s.points))
            desc = fpfh(biggest.points, config.features, viewpoint=pose_cw[:3, 3])
            descriptors.append(desc.astype(np.float32))
            labels.append(CATEGORIES.index(inst.category))
    finally:
        renderer.close()
    lengths = np.array([len(d) for d in descriptors], np.int64)
    n = len(descriptors)
    return ViewSet(
        descriptors=np.concatenate(descriptors) if n else np.zeros((0, 33), np.float32),
        offsets=np.concatenate([[0], np.cumsum(lengths)]),
        labels=np.array(labels, np.int64),
        instance=np.array([inst.name] * n, "U32"),
        known=np.full(n, inst.known),
        source=np.full(n, "isolated", "U16"),
    )


def render_cluttered_segments(config: DatasetConfig, progress: bool = True) -> ViewSet:
    """Segments of cluttered scenes (the first observation of each seed), labelled by the
    ground-truth object covering most of their pixels."""
    import gymnasium as gym

    import ipbench.envs  # noqa: F401

    env = gym.make("ipbench/SortingCluttered-v0", depth_noise=config.depth_noise)
    descriptors, labels, names, known = [], [], [], []
    try:
        for seed in tqdm(config.cluttered_seeds, desc="cluttered scenes", disable=not progress):
            obs, info = env.reset(seed=seed)
            cloud = depth_to_points(obs["wrist_depth"], obs["wrist_K"], obs["wrist_pose"])
            mask = info["wrist_mask"].reshape(-1)
            eye = obs["wrist_pose"][:3, 3]
            for segment in segment_scene(cloud, config.segmentation).segments:
                ids, counts = np.unique(mask[segment.pixels], return_counts=True)
                best = int(np.argmax(counts))
                if ids[best] < 0 or counts[best] < config.min_overlap * len(segment.pixels):
                    continue
                obj = info["objects"][int(ids[best])]
                desc = fpfh(segment.points, config.features, viewpoint=eye)
                descriptors.append(desc.astype(np.float32))
                labels.append(CATEGORIES.index(obj["category"]))
                names.append(obj["instance"])
                known.append(obj["known"])
    finally:
        env.close()
    lengths = np.array([len(d) for d in descriptors], np.int64)
    return ViewSet(
        descriptors=np.concatenate(descriptors) if descriptors else np.zeros((0, 33), np.float32),
        offsets=np.concatenate([[0], np.cumsum(lengths)]),
        labels=np.array(labels, np.int64),
        instance=np.array(names, "U32"),
        known=np.array(known, bool),
        source=np.full(len(labels), "cluttered", "U16"),
    )


class _Serial:
    """A stand-in for a process pool that runs in this process."""

    def __enter__(self) -> _Serial:
        return self

    def __exit__(self, *exc) -> None:
        pass

    @staticmethod
    def map(fn, *iterables):
        return map(fn, *iterables)


def _pool(workers: int):
    if workers <= 1:
        return _Serial()
    # spawn: each worker opens its own headless GL context (no GL state crosses a fork)
    return ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))


def load_or_build(
    cache_dir: Path,
    config: DatasetConfig = DatasetConfig(),
    progress: bool = True,
    workers: int = 2,
) -> ViewSet:
    """Every instance's isolated views and the cluttered-scene segments, cached or rendered.

    The cache file is ``cache_dir/views-<config hash>.npz``; one that cannot be read (corrupt
    or truncated) is reported and rebuilt. Instances render in ``workers`` processes and each
    instance's part is written as soon as it is done, so an interrupted build resumes where it
    stopped.
    """
    cache_dir = Path(cache_dir)
    cache_dir.mkdir(parents=True, exist_ok=True)
    path = cache_dir / f"views-{config.key()}.npz"
    if path.exists():
        try:
            return ViewSet.load(path)
        except (OSError, ValueError, KeyError, zipfile.BadZipFile) as err:
            print(f"ipbench: dataset cache {path} is unreadable ({err}); rebuilding it")
            path.unlink()
    parts_dir = cache_dir / f"parts-{config.key()}"
    parts_dir.mkdir(exist_ok=True)
    chosen = [
        inst
        for inst in instances()
        if config.per_category is None
        or (inst.index % KNOWN_INSTANCES if not inst.known else inst.index) < config.per_category
    ]
    parts: dict[str, ViewSet] = {}
    for inst in chosen:
        part = parts_dir / f"{inst.name}.npz"
        if part.exists():
            try:
                parts[inst.name] = ViewSet.load(part)
            except (OSError, ValueError, KeyError, zipfile.BadZipFile):
                part.unlink()
    todo = [inst for inst in chosen if inst.name not in parts]
    bar = tqdm(
        total=len(chosen),
        initial=len(parts),
        desc="rendering views",
        unit="instance",
        disable=not progress,
    )
    with _pool(workers) as pool:
        for inst, views in zip(
            todo, pool.map(render_instance_views, todo, [config] * len(todo)), strict=True
        ):
            tmp = parts_dir / f"{inst.name}.tmp.npz"
            views.save(tmp)
            tmp.replace(parts_dir / f"{inst.name}.npz")  # finished parts survive interruptions
            parts[inst.name] = views
            bar.update()
    bar.close()
    sets = [parts[inst.name] for inst in chosen]
    part = parts_dir / "cluttered.npz"
    try:
        clutter = ViewSet.load(part)
    except (OSError, ValueError, KeyError, zipfile.BadZipFile):
        clutter = render_cluttered_segments(config, progress)
        clutter.save(part)
    sets.append(clutter)
    views = ViewSet.concat(sets)
    tmp = path.with_suffix(".tmp.npz")
    views.save(tmp)
    tmp.replace(path)
    return views
