"""The stereo head's part of an observation, as both task families report it.

:func:`observe_head` renders the head's two cameras (``head_left``/``head_right`` images, their
intrinsics ``head_*_K`` and world-from-camera poses ``head_*_pose``), optionally with each
camera's object mask, and bends images and masks through the true lenses when the world is
the true cell (the envs' ``extrinsics`` other than ``"true"``,
:mod:`ipbench.envs.cell.extrinsics`). :class:`~ipbench.envs.sorting.SortingEnv` and
:class:`~ipbench.envs.exploration.ExplorationEnv` both build their head keys with it.
"""

from __future__ import annotations

from collections.abc import Mapping

import mujoco
import numpy as np

from ipbench.assets.compose import HEAD_SIDES
from ipbench.envs.cell.extrinsics import distort_labels
from ipbench.envs.sensors import SensorRenderer, camera_pose, intrinsics
from ipbench.envs.sensors.lens_distortion import LensDistortion, distort_image

__all__ = ["observe_head"]


def observe_head(
    renderer: SensorRenderer,
    model: mujoco.MjModel,
    data: mujoco.MjData,
    size: tuple[int, int],
    *,
    pose_data: mujoco.MjData | None = None,
    lenses: Mapping[str, LensDistortion] | None = None,
    mask_lut: np.ndarray | None = None,
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The head keys of an observation and, with ``mask_lut``, each side's object mask.

    Per side of :data:`~ipbench.assets.compose.HEAD_SIDES`, in this order: ``head_{side}``
    (``size`` = (height, width) RGB rendered from ``data``), ``head_{side}_K`` (3x3) and
    ``head_{side}_pose`` (4x4, the camera's pose in ``pose_data``, e.g. forward kinematics of
    encoder readings; default ``data``). ``mask_lut`` maps a geom id (the last entry: none) to
    what the mask reports; masks are keyed by side. ``lenses`` (camera name -> the true lens):
    images are distorted by it (bilinear), masks too (nearest label); ``None``: pinhole.
    """
    h, w = size
    obs: dict[str, np.ndarray] = {}
    masks: dict[str, np.ndarray] = {}
    for s in HEAD_SIDES:
        cam = f"head_{s}_camera"
        obs[f"head_{s}"] = renderer.render_rgb(data, cam, w, h)
        obs[f"head_{s}_K"] = intrinsics(model, cam, w, h).K
        obs[f"head_{s}_pose"] = camera_pose(model, data if pose_data is None else pose_data, cam)
        if mask_lut is not None:
            masks[s] = mask_lut[renderer.render_segmentation(data, cam, w, h)]
        if lenses is not None:  # the true lens
            lens, K = lenses[cam], obs[f"head_{s}_K"]  # noqa: N806
            obs[f"head_{s}"] = distort_image(obs[f"head_{s}"], K, lens)
            if mask_lut is not None:
                masks[s] = distort_labels(masks[s], K, lens)
    return obs, masks
