"""The head's trials of the reconstruction evaluation: which views to render, the dynamic
update of both cameras, and its consistency check (:mod:`.reconstruction` runs them).

- :func:`outline_world` and :func:`sees_whole`: whether both head cameras see a presented
  board whole, by geometry alone (the true cell's pinhole cameras), so that hopeless poses
  and gazes are drawn again before anything is rendered;
- :func:`dynamic_updates`: the thesis' update of the left camera (the right one by the
  encoders' chain) and the update of each camera on its own;
- :func:`checked_update`: the update the robot keeps after the check of
  :mod:`ipbench.perception.calibration.consistency`, or the encoders' pair;
- :func:`board_geometry`: the scored board's distance and incidence, which the floor depends
  on.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ipbench.envs.sensors import camera_pose
from ipbench.eval.calibration.calibrate import CAMERAS
from ipbench.perception.calibration.consistency import choose_pair, epipolar_consistency
from ipbench.perception.calibration.dynamic import right_from_chain, update_left_pose
from ipbench.perception.calibration.errors import CalibrationError
from ipbench.perception.calibration.poses import invert
from ipbench.perception.calibration.target import Checkerboard

__all__ = [
    "VIEW_MARGIN",
    "board_geometry",
    "checked_update",
    "dynamic_updates",
    "outline_world",
    "sees_whole",
]

VIEW_MARGIN = 0.03
"""Share of the image's width and height kept clear by :func:`sees_whole`: the lens'
distortion (the check is pinhole) and the detector's need of a quiet zone."""


def outline_world(shown, board: Checkerboard) -> np.ndarray:
    """(4, 3) world corners of the printed board presented as ``shown`` (its face centre,
    normal and texture up), m."""
    point, normal, up = (np.asarray(v, float) for v in shown)
    side = np.cross(up, normal)
    w, h = board.size_m
    return np.array([point + a * w / 2 * side + b * h / 2 * up
                     for a in (-1, 1) for b in (-1, 1)])  # fmt: skip


def sees_whole(model, data, adr, angles: np.ndarray, outline: np.ndarray, K: dict, size) -> bool:
    """Whether both head cameras (their true camera matrices ``K`` by name, (3, 3) px, for
    images of ``size`` (width, height)), their PTUs at ``angles``, see the whole ``outline``
    (pinhole, :data:`VIEW_MARGIN` of the image kept clear for the lens and the detector)."""
    data.qpos[adr] = angles
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)
    w, h = size
    for name in ("head_left", "head_right"):
        pose = camera_pose(model, data, CAMERAS[name])
        local = (outline - pose[:3, 3]) @ pose[:3, :3]
        if np.any(local[:, 2] <= 0):
            return False
        uv = (local @ K[name].T)[:, :2] / local[:, 2:]
        low, high = VIEW_MARGIN * np.array([w, h]), (1 - VIEW_MARGIN) * np.array([w, h])
        if np.any(uv < low) or np.any(uv > high):
            return False
    return True


def dynamic_updates(before, after, K, dist, cal, enc, failures) -> dict:
    """``dynamic`` (the left camera updated, the right one by the encoders' chain) and
    ``dynamic_both`` (each camera updated on its own), or nothing when an update fails (then
    counted in ``failures``)."""
    left, right = "head_left", "head_right"
    try:
        new_left = update_left_pose(before[left], before[right], K[left], K[right], dist[left],
                                    dist[right], cal[left], cal[right],
                                    after[left]).T_world_left  # fmt: skip
        new_right = update_left_pose(before[right], before[left], K[right], K[left], dist[right],
                                     dist[left], cal[right], cal[left],
                                     after[right]).T_world_left  # fmt: skip
    except CalibrationError:
        failures["dynamic"] += 1
        failures["dynamic_both"] += 1
        return {}
    chain = invert(enc[left]) @ enc[right]
    return {
        "dynamic": {left: new_left, right: right_from_chain(new_left, chain)},
        "dynamic_both": {left: new_left, right: new_right},
    }


def checked_update(after, K, dist, est) -> tuple[dict, dict]:
    """The update of both cameras unless the images it was computed from say the encoders' pair
    is more consistent (:func:`~ipbench.perception.calibration.consistency.epipolar_consistency`
    on the after-move images), or the update failed: (the pair kept, what the check saw)."""
    if "dynamic_both" not in est:
        return est["encoders"], {"chosen": "encoders", "reason": "update failed"}
    left, right = "head_left", "head_right"
    candidates = {m: (est[m][left], est[m][right]) for m in ("encoders", "dynamic_both")}
    try:
        scores = epipolar_consistency(after[left], after[right], K[left], K[right], dist[left],
                                      dist[right], candidates)  # fmt: skip
    except CalibrationError:
        return est["encoders"], {"chosen": "encoders", "reason": "check failed"}
    chosen = choose_pair(scores, prefer="dynamic_both")
    return est[chosen], {"chosen": chosen, "consensus": scores}


def board_geometry(shown, head_mid: np.ndarray) -> dict:
    """The scored board's distance from the middle of the head cameras, m, and the angle
    between its face normal and the direction to the head, deg."""
    point, normal, _ = shown
    view = np.asarray(head_mid, float) - point
    cos = float(np.dot(normal, view) / np.linalg.norm(view) / np.linalg.norm(normal))
    return {
        "board_distance_m": float(np.linalg.norm(view)),
        "incidence_deg": float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))),
    }
