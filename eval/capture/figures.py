"""``ipbench figures``: the README's pictures of an env id's objects and sensor, made anew.

- :func:`family_gallery`: one instance of every family of every category (first instance of
  each family), standing in rows on the work table — one row per category, in bin order
  (juice bottles farthest from the camera) — rendered by the env itself (a hand-made
  layout, ``reset(options={"layout": ...})``).
- :func:`depth_figure`: a cluttered scene from the wrist Xtion: RGB, the ideal depth the
  renderer returns and what the sensor model makes of it (missing depth in black).

Both are deterministic for a given seed on one machine (software rendering).
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import ipbench.envs  # noqa: E402, F401  (registers the ids)
from ipbench.assets.objects import CATEGORIES, instances, resting_poses  # noqa: E402
from ipbench.envs import env_config  # noqa: E402
from ipbench.envs.layout import Layout, PlacedObject  # noqa: E402
from ipbench.envs.sensors import intrinsics  # noqa: E402
from ipbench.envs.sorting import WRIST_CAMERA, WRIST_SIZE, workcell_places  # noqa: E402

__all__ = ["family_gallery", "depth_figure", "gallery_layout"]

_SPACING = 0.2  # m between neighbours of a gallery row
_ROW = 0.17  # m between rows


def gallery_layout(catalog: str) -> Layout:
    """The first instance of every family of ``catalog``, upright, in one row per category."""
    firsts: dict[tuple[str, str], object] = {}
    for inst in instances(catalog=catalog):
        firsts.setdefault((inst.category, inst.family), inst)
    places = workcell_places()
    cx, cy, _ = places.table_top.center
    placed = []
    for row, category in enumerate(CATEGORIES):
        row_insts = [i for (c, _), i in firsts.items() if c == category]
        for col, inst in enumerate(row_insts):
            pose = resting_poses(inst)[0]
            x = cx + (row - (len(CATEGORIES) - 1) / 2) * _ROW
            y = cy + (col - (len(row_insts) - 1) / 2) * _SPACING
            z = places.table_height + pose.height
            obj = PlacedObject(len(placed), inst, pose, (x, y, z), 0.0, tuple(pose.quat))
            placed.append(obj)
    return Layout("gallery", 0, tuple(placed))


def _free_camera(lookat, distance: float, azimuth: float, elevation: float) -> mujoco.MjvCamera:
    cam = mujoco.MjvCamera()
    cam.type = mujoco.mjtCamera.mjCAMERA_FREE
    cam.lookat[:] = lookat
    cam.distance, cam.azimuth, cam.elevation = distance, azimuth, elevation
    return cam


def family_gallery(path: Path, env_id: str = "ipbench/Sorting-v2", size=(720, 1280)) -> Path:
    """Render :func:`gallery_layout` of ``env_id``'s catalogue to ``path`` (PNG)."""
    layout = gallery_layout(env_config(env_id).catalog)
    env = gym.make(env_id, scene="uncluttered")
    try:
        env.reset(seed=0, options={"layout": layout})
        base = env.unwrapped
        base.robot.hold(1.0)  # let them settle
        center = np.mean([base.data.xpos[b] for b in base.world.object_bodies], axis=0)
        renderer = mujoco.Renderer(base.model, *size)
        try:
            renderer.update_scene(base.data, _free_camera(center, 1.45, 180.0, -40.0))
            image = renderer.render()
        finally:
            renderer.close()
    finally:
        env.close()
    path.parent.mkdir(parents=True, exist_ok=True)
    plt.imsave(path, image)
    return path


def depth_figure(path: Path, env_id: str = "ipbench/Sorting-v2", seed: int = 0) -> Path:
    """RGB, ideal depth and sensor depth of the wrist camera in ``env_id``'s cluttered scene,
    side by side, to ``path`` (PNG)."""
    env = gym.make(env_id, scene="cluttered")
    try:
        obs, _ = env.reset(seed=seed)
        base = env.unwrapped
        h, w = WRIST_SIZE
        _, ideal = base.renderer.render_rgbd(base.data, WRIST_CAMERA, w, h)
        k = intrinsics(base.model, WRIST_CAMERA, w, h)
    finally:
        env.close()
    noisy = obs["wrist_depth"]
    valid = ideal[ideal > 0]
    lo, hi = float(np.percentile(valid, 1)), float(np.percentile(valid, 60))  # the table
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2), dpi=100)
    panels = [
        (obs["wrist_rgb"], "wrist RGB"),
        (np.ma.masked_equal(ideal, 0), "ideal depth (renderer)"),
        (np.ma.masked_equal(noisy, 0), f"sensor depth ({(noisy == 0).mean():.0%} missing)"),
    ]
    cmap = matplotlib.colormaps["viridis"].with_extremes(bad="black")
    for ax, (image, title) in zip(axes, panels, strict=True):
        if image.ndim == 3:
            ax.imshow(image)
        else:
            ax.imshow(image, cmap=cmap, vmin=lo, vmax=hi)
        ax.set_title(title, fontsize=10)
        ax.axis("off")
    fig.suptitle(f"{env_id}, cluttered, seed {seed}; fx = {k.fx:.0f} px", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
