"""Training and test views rendered by the simulator, as the thesis captured its database.

Each catalogue instance stands alone at the centre of the table's spawn area and the wrist
Xtion (with its depth noise) looks at it from ``elevations`` at ``distance``, while the object
turns in ``yaw_step`` steps (18 views at 20 deg), upright and, for objects that can lie, on its
side. Every view goes through the same perception as an episode: point cloud, table plane,
prism and clustering; the largest segment's FPFH descriptors are stored (not yet encoded, so
the codebook can be refitted), with a sample of :data:`~ipbench.perception.viewset.POINTS_PER_VIEW`
of its points (world frame, m, z up: the frame the FPFH are computed in; drawn by
:func:`~ipbench.perception.viewset.sample_points` with a generator seeded per view, apart from
the depth-noise stream, so the FPFH are those of version 2) for point-cloud networks. *Known*
instances make the training set, *unknown* ones the test set; segments cut out of cluttered
scenes, labelled by their overlap with the ground-truth masks, make the realistic test set.
Each instance is also picked up and turned in front of the wrist camera
(:mod:`ipbench.eval.capture.hand_views`): the in-hand views.

The objects and the sensor are those of ``DatasetConfig.env_id``: for ``ipbench/Sorting-v2`` the
v2 catalogue (its *train* split is known; *similar* and *novel* are held out) and the
structured-light sensor, with one sensor unit (systematic error) per instance's capture.

This is an eval module: it renders with the simulator (it produces data, like a capture
rig); perception itself never reads simulator state. Results are cached on disk under a hash of the
configuration; a missing, stale or corrupt cache file is rebuilt with a message.
"""

from __future__ import annotations

import hashlib
import json
import zipfile
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
from ipbench.envs import env_config
from ipbench.envs.ik import look_at_rotation
from ipbench.envs.layout import Layout, PlacedObject
from ipbench.envs.robot import RobotController, ik_model
from ipbench.envs.sensors import (
    SensorRenderer,
    camera_pose,
    intrinsics,
    specular_geoms,
)
from ipbench.envs.sensors.depth_noise import DepthNoiseConfig, DepthNoiseModel
from ipbench.envs.skills import Skills
from ipbench.envs.sorting import WRIST_CAMERA, WRIST_SIZE
from ipbench.envs.world import Places, build_world
from ipbench.eval.capture.hand_factors import check_factor
from ipbench.eval.capture.hand_views import render_in_hand_factors, render_in_hand_views
from ipbench.eval.schedule import pool_worker
from ipbench.eval.workers import run_tasks
from ipbench.perception.cloud import PerceptionError, depth_to_points
from ipbench.perception.features import FeatureConfig, fpfh
from ipbench.perception.segmentation import SegmentationConfig, segment_scene
from ipbench.perception.viewset import POINTS_PER_VIEW, ViewSet, sample_points
from ipbench.policies import EVAL_CAMERAS

__all__ = [
    "DatasetConfig",
    "InHandAblationConfig",
    "ViewSet",
    "render_instance_views",
    "render_in_hand_points",
    "render_in_hand_rows",
    "render_cluttered_segments",
    "load_or_build",
    "missing_parts",
    "render_part",
    "save_part",
    "DATASET_VERSION",
]

DATASET_VERSION = 3
"""Bumped whenever the rendering protocol changes, so old caches are rebuilt (2: in-hand
captures hold short objects with the pads under their top, :mod:`ipbench.eval.capture.hand_views`;
3: every view also stores a sample of its points, ``ViewSet.points``; the FPFH are
unchanged)."""

_POINT_STREAMS = {"isolated": 1, "in_hand": 2, "cluttered": 3}
"""Distinguishes the point-sampling seeds of the view sources (:func:`_point_rng`)."""


def _point_rng(config: DatasetConfig, source: str, *ids: int) -> np.random.Generator:
    """The generator that samples the points of one view: seeded by the dataset seed, the
    view source and ``ids`` (instance and view numbers, or scene seed and segment number)."""
    return np.random.default_rng([config.seed, _POINT_STREAMS[source], *ids])


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
    in_hand_views : in-hand views per grasp (:mod:`ipbench.eval.capture.hand_views`); 0 skips
        them.
    in_hand_turn_deg : rotation of the object in hand between those views (deg; thesis: 30).
    in_hand_placements : grasps per resting pose, the object turned on the table by 360 deg /
        this between them (the wrist alone turns through about 180 deg).
    env_id : the environment whose objects (catalogue) and sensor are captured; its
        cluttered scene gives the cluttered segments (``ipbench/Sorting-v1``: the v1 catalogue
        and cluttered segments of ``SortingCluttered-v0``, as before v2).
    depth_noise : the sensor; ``None``: the env's own (:attr:`sensor`).
    segmentation, features : the perception settings.
    """

    yaw_step_deg: float = 20.0
    elevations_deg: tuple[float, ...] = (40.0, 65.0)
    side_elevation_deg: float | None = 55.0
    distance: float = 0.75
    seed: int = 0
    cluttered_seeds: tuple[int, ...] = tuple(range(10_000, 10_012))
    min_overlap: float = 0.6
    per_category: int | None = None
    in_hand_views: int = 6
    in_hand_turn_deg: float = 30.0
    in_hand_placements: int = 2
    env_id: str = "ipbench/Sorting-v1"
    depth_noise: DepthNoiseConfig | None = None
    segmentation: SegmentationConfig = field(default_factory=SegmentationConfig)
    features: FeatureConfig = field(default_factory=FeatureConfig)

    def __post_init__(self) -> None:
        if self.in_hand_views < 0 or self.in_hand_placements < 1:
            raise ValueError(
                f"in_hand_views={self.in_hand_views}, in_hand_placements="
                f"{self.in_hand_placements}; valid: in_hand_views >= 0 (0: none), "
                "in_hand_placements >= 1"
            )
        if self.yaw_step_deg <= 0 or self.distance <= 0:
            raise ValueError("yaw_step_deg and distance must be positive")
        env_config(self.env_id)  # an unknown id is an error listing the valid ones

    @property
    def sensor(self) -> DepthNoiseConfig:
        """The depth sensor the views are captured with."""
        return self.depth_noise or env_config(self.env_id).depth_noise

    @property
    def catalog(self) -> str:
        """The object catalogue of :attr:`env_id`."""
        return env_config(self.env_id).catalog

    def chosen_instances(self) -> tuple[ObjectInstance, ...]:
        """The instances captured: the whole catalogue, or with ``per_category`` the first
        ``per_category`` of each category and split."""
        every = instances(catalog=self.catalog)
        if self.per_category is None:
            return every
        if self.catalog == "v1":  # first known and first unknown ones (as before v2)
            return tuple(
                i
                for i in every
                if (i.index % KNOWN_INSTANCES if not i.known else i.index) < self.per_category
            )
        seen: dict[tuple[str, str], int] = {}
        chosen = []
        for inst in every:
            n = seen.get((inst.category, inst.split), 0)
            if n < self.per_category:
                chosen.append(inst)
            seen[inst.category, inst.split] = n + 1
        return tuple(chosen)

    def key(self) -> str:
        """Hash of everything that changes the data (the cache key): the protocol, and the
        objects (every instance's dimensions, mass, family and split)."""
        objects = hashlib.sha256(repr(instances(catalog=self.catalog)).encode()).hexdigest()
        fields = {"v": DATASET_VERSION, "objects": objects, **asdict(self)}
        if fields.get("in_hand_removed", 0) is None:  # InHandAblationConfig as captured:
            del fields["in_hand_removed"]  # the key of the DatasetConfig it extends
        text = json.dumps(fields, sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class InHandAblationConfig(DatasetConfig):
    """A capture of the in-hand ablation (:mod:`ipbench.eval.perception.in_hand_ablation`): a
    :class:`DatasetConfig` whose in-hand views have one factor removed.

    A subclass, not a new field, so that every configuration and fingerprint holding a
    :class:`DatasetConfig` (models, sorting runs) stays as it was.

    Attributes
    ----------
    in_hand_removed : the factor of :data:`~ipbench.eval.capture.hand_factors.IN_HAND_FACTORS`
        removed from the in-hand capture; ``None``: every factor as captured (then the cache
        key is that of the :class:`DatasetConfig` with the same other fields).
    """

    in_hand_removed: str | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        check_factor(self.in_hand_removed)


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
    world = build_world(Layout("isolated", 0, (placed,)), objects=env_config(config.env_id).objects)
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
    noise = DepthNoiseModel(config.sensor)
    rng = np.random.default_rng([config.seed, inst.index, CATEGORIES.index(inst.category)])
    # one sensor unit per capture run (its own stream: rng's draws, which v1 uses, do not move)
    unit = noise.draw_unit(np.random.default_rng([config.seed, inst.index, 7500]))
    h, w = WRIST_SIZE
    k = intrinsics(model, WRIST_CAMERA, w, h)
    shiny = np.append(specular_geoms(model), False)  # index -1 = background
    toward_robot = places.scene_view[:2] - places.scene_target[:2]
    toward_robot /= np.linalg.norm(toward_robot)
    qadr = model.jnt_qposadr[model.body_jntadr[world.object_bodies[0]]]
    descriptors, labels, points = [], [], []
    camera_q: dict[float, dict[str, float]] = {}
    try:
        for view, (pose, yaw, elevation) in enumerate(_views(config, inst)):
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
            depth = noise.apply(depth, k.fx, k.fy, rng, specular=shiny[seg], unit=unit)
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
            rng_points = _point_rng(config, "isolated", inst.index, _category(inst), view)
            points.append(sample_points(biggest.points, POINTS_PER_VIEW, rng_points))
    finally:
        renderer.close()
    n = len(descriptors)
    names, known = [inst.name] * n, [inst.known] * n
    return ViewSet.from_views(descriptors, labels, names, known, "isolated", points)


def _category(inst: ObjectInstance) -> int:
    return CATEGORIES.index(inst.category)


def render_in_hand_points(inst: ObjectInstance, config: DatasetConfig) -> ViewSet:
    """:func:`~ipbench.eval.capture.hand_views.render_in_hand_views` with each view's point sample
    (view ``v`` drawn by :func:`_point_rng` of ``("in_hand", instance, category, v)``)."""
    category = _category(inst)
    return render_in_hand_views(
        inst, config, lambda v: _point_rng(config, "in_hand", inst.index, category, v)
    )


def render_in_hand_rows(
    inst: ObjectInstance, config: DatasetConfig, factors: tuple[str | None, ...]
) -> dict[str | None, ViewSet]:
    """:func:`~ipbench.eval.capture.hand_views.render_in_hand_factors` (every factor's in-hand views
    of ``inst`` from one pass), with the point samples :func:`render_in_hand_points` draws:
    factor ``f``'s views are those :func:`render_in_hand_points` renders with
    ``in_hand_removed=f``."""
    category = _category(inst)
    return render_in_hand_factors(
        inst, config, factors, lambda v: _point_rng(config, "in_hand", inst.index, category, v)
    )


def render_cluttered_segments(config: DatasetConfig, progress: bool = True) -> ViewSet:
    """Segments of cluttered scenes (the first observation of each seed), labelled by the
    ground-truth object covering most of their pixels."""
    import gymnasium as gym

    import ipbench.envs  # noqa: F401

    # only the wrist is read (the head's images would be rendered for nothing; the same data)
    if config.env_id == "ipbench/Sorting-v1":  # as before v2
        env = gym.make(
            "ipbench/SortingCluttered-v0", depth_noise=config.sensor, cameras=EVAL_CAMERAS
        )
    else:
        env = gym.make(
            config.env_id, scene="cluttered", depth_noise=config.sensor, cameras=EVAL_CAMERAS
        )
    descriptors, labels, names, known, points = [], [], [], [], []
    try:
        for seed in tqdm(config.cluttered_seeds, desc="cluttered scenes", disable=not progress):
            obs, info = env.reset(seed=seed)
            cloud = depth_to_points(obs["wrist_depth"], obs["wrist_K"], obs["wrist_pose"])
            mask = info["wrist_mask"].reshape(-1)
            eye = obs["wrist_pose"][:3, 3]
            for number, segment in enumerate(segment_scene(cloud, config.segmentation).segments):
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
                rng_points = _point_rng(config, "cluttered", seed, number)
                points.append(sample_points(segment.points, POINTS_PER_VIEW, rng_points))
    finally:
        env.close()
    return ViewSet.from_views(descriptors, labels, names, known, "cluttered", points)


_RENDERERS = {"isolated": render_instance_views, "in_hand": render_in_hand_points}
"""Per-instance view sources and what renders them."""


def _part_path(parts_dir: Path, kind: str, inst: ObjectInstance) -> Path:
    return parts_dir / (f"{inst.name}.npz" if kind == "isolated" else f"{inst.name}.{kind}.npz")


def _load_part(path: Path) -> ViewSet | None:
    """A finished part, or None when it is missing or unreadable (then it is deleted)."""
    if not path.exists():
        return None
    try:
        return ViewSet.load(path)
    except (OSError, ValueError, KeyError, zipfile.BadZipFile):
        path.unlink()
        return None


def _jobs(
    config: DatasetConfig, training_only: bool, kinds: tuple[str, ...] | None
) -> list[tuple[str, ObjectInstance]]:
    """The per-instance parts of a build, in the data's order (instance by instance)."""
    wanted = tuple(_RENDERERS) if kinds is None else kinds
    unknown = [k for k in wanted if k not in _RENDERERS]
    if unknown:
        raise ValueError(f"unknown view kinds {unknown}; valid: {', '.join(_RENDERERS)}")
    chosen = [i for i in config.chosen_instances() if i.known or not training_only]
    kinds = tuple(
        k for k in _RENDERERS if k in wanted and (k != "in_hand" or config.in_hand_views > 0)
    )
    return [(kind, inst) for inst in chosen for kind in kinds]


def missing_parts(
    cache_dir: Path, config: DatasetConfig, training_only: bool = True
) -> list[tuple[str, ObjectInstance]]:
    """The parts :func:`load_or_build` would render now: none when the whole cache file
    exists; else those without a part file (an unreadable one is re-rendered when
    :func:`load_or_build` reads it), every isolated part before every in-hand one (what
    table-top models read comes first)."""
    cache_dir = Path(cache_dir)
    if (cache_dir / f"views-{config.key()}.npz").exists():
        return []
    parts_dir = cache_dir / f"parts-{config.key()}"
    todo = [
        (kind, inst)
        for kind, inst in _jobs(config, training_only, None)
        if not _part_path(parts_dir, kind, inst).exists()
    ]
    return sorted(todo, key=lambda job: list(_RENDERERS).index(job[0]))  # stable


def render_part(kind: str, inst: ObjectInstance, config: DatasetConfig) -> ViewSet:
    """The views of one part (``kind`` one of ``isolated``, ``in_hand``) of ``inst``; what a
    worker runs."""
    return _RENDERERS[kind](inst, config)


def save_part(
    cache_dir: Path, config: DatasetConfig, kind: str, inst: ObjectInstance, views: ViewSet
) -> None:
    """Write one rendered part where :func:`load_or_build` finds it (atomically: a finished
    part survives interruptions and worker crashes)."""
    parts_dir = Path(cache_dir) / f"parts-{config.key()}"
    parts_dir.mkdir(parents=True, exist_ok=True)
    final = _part_path(parts_dir, kind, inst)
    tmp = final.with_name(final.name.replace(".npz", ".tmp.npz"))
    views.save(tmp)
    tmp.replace(final)


def load_or_build(
    cache_dir: Path,
    config: DatasetConfig = DatasetConfig(),
    progress: bool = True,
    workers: int = 2,
    training_only: bool = False,
    kinds: tuple[str, ...] | None = None,
) -> ViewSet:
    """Every instance's isolated and in-hand views and the cluttered-scene segments, cached
    or rendered.

    The cache file is ``cache_dir/views-<config hash>.npz``; one that cannot be read (corrupt
    or truncated) is reported and rebuilt. Instances render in ``workers`` processes and each
    instance's part is written as soon as it is done, so an interrupted build resumes where it
    stopped.

    ``training_only``: just the known instances' views (no test instances, no cluttered
    segments), which is all that training a model reads — what a sorting evaluation needs,
    about a third less rendering. They are the known views of the whole set, in its order (so the
    models are identical), taken from the whole cache file if it exists; otherwise only their
    parts are rendered, which a later whole build reuses (only a whole build writes the file).
    ``kinds``: only these per-instance view kinds, e.g. ``("isolated",)`` for a table-top
    model (the same views, in the same order, as the subset of the whole set); without
    ``training_only``, those kinds' parts of every chosen instance (known and unknown) and no
    cluttered segments, taken from the whole file if it exists, else from the parts (e.g.
    ``("in_hand",)`` for the in-hand ablation, whose captures differ in the in-hand views
    alone).
    """
    cache_dir = Path(cache_dir)
    cache_dir.mkdir(parents=True, exist_ok=True)
    path = cache_dir / f"views-{config.key()}.npz"
    if path.exists():
        try:
            views = ViewSet.load(path)
            sources = tuple(_RENDERERS) if kinds is None else kinds
            if training_only:
                return views.subset(views.known & np.isin(views.source, sources))
            if kinds is not None:
                return views.subset(np.isin(views.source, sources))
            return views
        except (OSError, ValueError, KeyError, zipfile.BadZipFile) as err:
            print(f"ipbench: dataset cache {path} is unreadable ({err}); rebuilding it")
            path.unlink()
    parts_dir = cache_dir / f"parts-{config.key()}"
    parts_dir.mkdir(exist_ok=True)
    jobs = _jobs(config, training_only, kinds)
    parts: dict[tuple[str, str], ViewSet] = {}
    for kind, inst in jobs:
        part = _load_part(_part_path(parts_dir, kind, inst))
        if part is not None:
            parts[kind, inst.name] = part
    todo = [(kind, inst) for kind, inst in jobs if (kind, inst.name) not in parts]
    bar = tqdm(
        total=len(jobs),
        initial=len(parts),
        desc="rendering views",
        unit="part",
        disable=not progress,
    )
    renders = run_tasks(
        render_part,
        [(kind, inst, config) for kind, inst in todo],
        workers,
        pool_worker if workers > 1 else None,
        what="dataset part",
    )
    for k, views in renders:
        kind, inst = todo[k]
        save_part(cache_dir, config, kind, inst, views)
        parts[kind, inst.name] = views
        bar.update()
    bar.close()
    sets = [parts[kind, inst.name] for kind, inst in jobs]
    if training_only or kinds is not None:
        return ViewSet.concat(sets)
    part = parts_dir / "cluttered.npz"
    clutter = _load_part(part)
    if clutter is None:
        clutter = render_cluttered_segments(config, progress)
        clutter.save(part)
    sets.append(clutter)
    views = ViewSet.concat(sets)
    tmp = path.with_suffix(".tmp.npz")
    views.save(tmp)
    tmp.replace(path)
    return views
