"""The recognition database of ``ipbench/Exploration-v0``, captured by the robot's own head.

Thesis ch. 3 recognises objects by matching local features against a database of views of
each known object. Here the benchmark builds that database itself, as the robot would: each
:data:`~ipbench.envs.exploration_scene.DATABASE_CLASSES` object stands **alone** at the centre
of the front work table (every resting pose it has among ``poses``, turned about the vertical
every ``yaw_step_deg``), the head fixates it (:func:`~ipbench.envs.exploration_scene.aim_head`)
and both cameras take a picture: a stereo pair per view, at the distance and with the optics
of the exploration episodes. The renderer's segmentation gives each object's mask, and the
image is cropped to the mask's box plus a margin (features are detected inside the mask only;
the crop keeps the detector's image pyramid small).

Views are cached per :class:`DatabaseCaptureConfig` key (``exploration-views-KEY.npz``), the
database per feature type (``exploration-db-FEATURE-KEY.npz``): a later run loads them. This is
an evaluation job (it renders with the simulator); :mod:`ipbench.perception.object_database`
only describes what it is given.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path

import mujoco
import numpy as np

from ipbench.assets.compose import HEAD_SIDES
from ipbench.assets.objects import resting_poses
from ipbench.assets.objects.object_model import ObjectModel
from ipbench.envs.exploration_scene import (
    DATABASE_CLASSES,
    FRONT_AREA,
    GAZE_JOINTS,
    ExplorationScene,
    SceneObject,
    aim_head,
    build_model,
    database_instance,
)
from ipbench.envs.sensors import SensorRenderer, fit_offscreen
from ipbench.perception.object_database import DatabaseFileError, ObjectDatabase, ObjectView

__all__ = [
    "CAPTURE_VERSION",
    "DatabaseCaptureConfig",
    "capture_views",
    "load_or_build_database",
]

CAPTURE_VERSION = 2  # 2: the head captures in the lab room (walls)
"""Version of the capture protocol (part of the cache key)."""


@dataclass(frozen=True)
class DatabaseCaptureConfig:
    """How the database views are taken.

    Attributes
    ----------
    yaw_step_deg : the object turns about the vertical by this step (deg): 360 / step views
        per resting pose.
    poses : at most this many of the object's resting poses (upright first, then lying).
    head_size : (height, width) px of the head images, as in the episodes.
    margin_px : the crop around the mask's box, px.
    classes : the database classes.
    upright_prints : the objects' prints read upright (the episodes' ``ObjectModel``).
    """

    yaw_step_deg: float = 45.0
    poses: int = 2
    head_size: tuple[int, int] = (680, 1024)
    margin_px: int = 16
    classes: tuple[str, ...] = DATABASE_CLASSES
    upright_prints: bool = False

    def key(self) -> str:
        """Hash of the protocol and of the objects it shows (their catalogue entries)."""
        objects = [repr(database_instance(c)) for c in self.classes]
        settings = asdict(self)
        if not self.upright_prints:  # the released prints: the key they always had
            del settings["upright_prints"]
        text = json.dumps([CAPTURE_VERSION, settings, objects], sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _alone(label: str, quat: np.ndarray, height: float) -> ExplorationScene:
    (x0, x1), (y0, y1) = FRONT_AREA
    centre = (0.5 * (x0 + x1), 0.5 * (y0 + y1), height)
    obj = SceneObject("object_00", database_instance(label), label, "database", "", centre, quat)
    return ExplorationScene("database", 0, (obj,), (0.0, 0.0, 0.0, 0.0), centre)


def capture_views(label: str, config: DatabaseCaptureConfig) -> list[ObjectView]:
    """Stereo views of ``label`` alone on the table (module docstring), left then right camera
    per view, cropped around the object's mask."""
    inst = database_instance(label)
    h, w = config.head_size
    views: list[ObjectView] = []
    for pose in resting_poses(inst)[: config.poses]:
        objects = ObjectModel(upright_prints=config.upright_prints)
        model = build_model(_alone(label, np.asarray(pose.quat), 0.0), objects=objects)
        data = mujoco.MjData(model)
        mujoco.mj_resetDataKeyframe(model, data, model.key("home").id)
        body = model.body("object_00").id
        mujoco.mj_kinematics(model, data)
        table = float(data.site("work_table_top").xpos[2])
        xy = model.body_pos[body, :2].copy()
        qadr = [model.jnt_qposadr[model.joint(j).id] for j in GAZE_JOINTS]
        fit_offscreen(model, w, h)
        renderer = SensorRenderer(model)
        try:
            for yaw in np.radians(np.arange(0.0, 360.0, config.yaw_step_deg)):
                turn = np.array([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)])
                quat = np.empty(4)
                mujoco.mju_mulQuat(quat, turn, np.asarray(pose.quat, float))
                model.body_pos[body] = (*xy, table + pose.height)
                model.body_quat[body] = quat
                rot = np.empty(9)
                mujoco.mju_quat2Mat(rot, quat)
                centre = model.body_pos[body] + rot.reshape(3, 3) @ np.asarray(inst.center)
                data.qpos[qadr] = aim_head(centre)
                mujoco.mj_forward(model, data)
                for side in HEAD_SIDES:
                    cam = f"head_{side}_camera"
                    seg = renderer.render_segmentation(data, cam, w, h)
                    mask = np.isin(seg, np.flatnonzero(model.geom_bodyid == body))
                    if not mask.any():
                        continue
                    rgb = renderer.render_rgb(data, cam, w, h)
                    rows, cols = np.flatnonzero(mask.any(1)), np.flatnonzero(mask.any(0))
                    m = config.margin_px
                    r0, r1 = max(rows[0] - m, 0), min(rows[-1] + m + 1, h)
                    c0, c1 = max(cols[0] - m, 0), min(cols[-1] + m + 1, w)
                    views.append(ObjectView(rgb[r0:r1, c0:c1].copy(), mask[r0:r1, c0:c1], label))
        finally:
            renderer.close()
    return views


def _views_file(cache: Path, config: DatabaseCaptureConfig) -> Path:
    return cache / f"exploration-views-{config.key()}.npz"


def _load_views(path: Path) -> list[ObjectView] | None:
    try:
        with np.load(path, allow_pickle=False) as f:
            n = int(f["n"])
            return [
                ObjectView(f[f"image_{i}"], f[f"mask_{i}"], str(f[f"label_{i}"])) for i in range(n)
            ]
    except (OSError, KeyError, ValueError) as err:
        print(f"ipbench: {path} is unreadable ({err}); capturing the database views again")
        return None


def _all_views(cache: Path, config: DatabaseCaptureConfig, progress: bool) -> list[ObjectView]:
    path = _views_file(cache, config)
    views = _load_views(path) if path.exists() else None
    if views is not None:
        return views
    from tqdm import tqdm

    views = []
    for label in tqdm(config.classes, desc="database views", unit="class", disable=not progress):
        views += capture_views(label, config)
    arrays: dict[str, np.ndarray] = {"n": np.int64(len(views))}
    for i, v in enumerate(views):
        arrays |= {f"image_{i}": v.image, f"mask_{i}": v.mask, f"label_{i}": np.str_(v.class_name)}
    cache.mkdir(parents=True, exist_ok=True)
    tmp = _own_tmp(path)
    np.savez_compressed(tmp, **arrays)
    tmp.replace(path)
    return views


def _own_tmp(path: Path) -> Path:
    """This process' temporary file for ``path``: runs that build the same entry at once (two
    evaluations sharing a cache) each write their own and the last rename wins (same content)."""
    return path.with_name(f"{path.stem}.{os.getpid()}.tmp.npz")


def load_or_build_database(
    feature_type: str,
    cache: Path,
    config: DatabaseCaptureConfig = DatabaseCaptureConfig(),
    progress: bool = True,
) -> ObjectDatabase:
    """The database of ``feature_type`` for ``config``: loaded from ``cache``, else built from
    the (cached or newly captured) views and saved. A damaged file is rebuilt, saying so."""
    cache = Path(cache)
    path = cache / f"exploration-db-{feature_type}-{config.key()}.npz"
    if path.exists():
        try:
            return ObjectDatabase.load(path, feature_type)
        except DatabaseFileError as err:
            print(f"ipbench: {err}; building the {feature_type} database again")
    database = ObjectDatabase.build(_all_views(cache, config, progress), feature_type)
    cache.mkdir(parents=True, exist_ok=True)
    tmp = _own_tmp(path)
    database.save(tmp)
    tmp.replace(path)
    return database
