"""The action and observation spaces of ``ipbench/Sorting-*`` and the check of an action.

:func:`action_space` and :func:`observation_space` build the spaces of
:class:`~ipbench.envs.sorting.SortingEnv` from its settings (which cameras, which commands,
whether the jaws pre-shape); :func:`check_action` holds an action to its space and turns it
into the values the environment executes, or raises an
:class:`~ipbench.envs.errors.InvalidActionError` naming the field and what is valid.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from gymnasium import spaces

from ipbench.assets.compose import HEAD_SIDES
from ipbench.assets.objects import CATEGORIES
from ipbench.envs.cell.extrinsics import DIST_SIZE
from ipbench.envs.errors import InvalidActionError

__all__ = ["action_space", "check_action", "observation_space"]


def observation_space(
    cameras: tuple[str, ...],
    n_joints: int,
    wrist_size: tuple[int, int],
    head_size: tuple[int, int],
    max_depth_m: float,
    dist_cameras: Sequence[str] = (),
) -> spaces.Dict:
    """The observation space: ``qpos`` (``n_joints``), the keys of each of ``cameras``
    (``"wrist"``: ``wrist_size`` images, depth up to ``max_depth_m``; ``"head"``: the stereo
    pair of ``head_size``), and ``{c}_dist`` for each camera in ``dist_cameras`` (the
    distortion the robot believes; extrinsics other than ``"true"``)."""
    hh, hw = head_size
    mat = spaces.Box(-np.inf, np.inf, (3, 3), np.float64)
    pose = spaces.Box(-np.inf, np.inf, (4, 4), np.float64)
    obs_spaces = {"qpos": spaces.Box(-np.inf, np.inf, (n_joints,), np.float64)}
    if "wrist" in cameras:
        obs_spaces |= {
            "wrist_rgb": spaces.Box(0, 255, (*wrist_size, 3), np.uint8),
            "wrist_depth": spaces.Box(0.0, np.float32(max_depth_m), wrist_size, np.float32),
            "wrist_K": mat,
            "wrist_pose": pose,
        }
    if "head" in cameras:
        for side in HEAD_SIDES:
            obs_spaces |= {
                f"head_{side}": spaces.Box(0, 255, (hh, hw, 3), np.uint8),
                f"head_{side}_K": mat,
                f"head_{side}_pose": pose,
            }
    if dist_cameras:  # the distortion the robot believes
        dist = spaces.Box(-np.inf, np.inf, (DIST_SIZE,), np.float64)
        obs_spaces |= {f"{c}_dist": dist for c in dist_cameras}
    return spaces.Dict(obs_spaces)  # (keys sorted)


def action_space(n_commands: int, max_jaw_opening: float | None) -> spaces.Dict:
    """The action space: ``command`` (``n_commands``), ``position`` (world, m), ``yaw``,
    ``bin`` and, unless ``max_jaw_opening`` is None (no pre-shaping), ``opening`` (m)."""
    space = spaces.Dict(
        {
            "command": spaces.Discrete(n_commands),
            "position": spaces.Box(
                np.array([-2.0, -2.0, 0.0], np.float32),
                np.array([2.0, 2.0, 2.5], np.float32),
                (3,),
                np.float32,
            ),
            "yaw": spaces.Box(-np.pi, np.pi, (1,), np.float32),
            "bin": spaces.Discrete(len(CATEGORIES)),
        }
    )
    if max_jaw_opening is not None:
        space.spaces["opening"] = spaces.Box(0.0, max_jaw_opening, (1,), np.float32)
    return space


def check_action(
    action, space: spaces.Dict, commands: tuple[str, ...]
) -> tuple[int, np.ndarray, float, int, float | None]:
    """``(command, position (3,), yaw, bin, opening or None)`` of ``action``, checked against
    ``space`` (``commands``: the names of its ``command`` values, for the message)."""
    if not isinstance(action, dict) or set(action) != set(space.spaces):
        got = sorted(action) if isinstance(action, dict) else type(action).__name__
        raise InvalidActionError(f"an action is a dict with keys {sorted(space.spaces)}; got {got}")
    for key, sub in space.spaces.items():
        value = action[key]
        if isinstance(sub, spaces.Discrete):
            ok = (
                np.ndim(value) == 0 and float(value) == int(value) and sub.contains(np.int64(value))
            )
            if not ok:
                names = CATEGORIES if key == "bin" else commands
                valid = ", ".join(f"{i}={n}" for i, n in enumerate(names))
                raise InvalidActionError(f"action[{key!r}] = {value!r}; valid: {valid}")
        else:
            arr = np.asarray(value, dtype=np.float32).reshape(-1)
            if arr.shape != sub.shape or not sub.contains(arr):
                raise InvalidActionError(
                    f"action[{key!r}] = {value!r} is outside {sub} (shape "
                    f"{sub.shape}, low {sub.low.tolist()}, high {sub.high.tolist()})"
                )
    return (
        int(action["command"]),
        np.asarray(action["position"], float).reshape(3),
        float(np.asarray(action["yaw"]).reshape(-1)[0]),
        int(action["bin"]),
        float(np.asarray(action["opening"]).reshape(-1)[0]) if "opening" in action else None,
    )
