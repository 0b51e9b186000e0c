"""Gentle settling: objects laid on others come to rest as if put there by hand.

A pile's layout (:mod:`ipbench.envs.layout`) lays objects on top of others without
simulation; dropped there undamped they would fall, bounce and roll off the table (MuJoCo's
contacts have no rolling resistance: a bowl or bottle set rolling by a fall rolls on).
:func:`settle_gently` damps their motion until they rest, then lets the physics alone keep
them there (a scene's :attr:`~ipbench.envs.sorting_scenes.SceneConfig.gentle_settle`).
"""

from __future__ import annotations

from collections.abc import Callable

import mujoco
import numpy as np

__all__ = ["settle_gently"]

_GENTLE_TAU = 0.1
"""Time constant (s) with which a gentle settling damps the objects' velocities."""
_REST_SPEED, _REST_SPIN = 0.005, 0.05
"""Speeds (m/s, rad/s) below which every object counts as at rest (gentle settling)."""
_REST_CHECK = 0.05
"""Physics time (s) between the checks of a gentle settling."""
_RELEASE_CALM = 5
"""Checks in a row that must find the objects at rest, undamped, to end a gentle settling."""
_WAKE_SPEED = 0.02
"""Speed (m/s) of an object that damps the objects again during a gentle settling."""


def settle_gently(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    bodies: np.ndarray,
    hold: Callable[[float], None],
    longest: float,
) -> None:
    """Let the free bodies ``bodies`` (body ids) come to rest with their motion damped, running the
    physics by ``hold(seconds)`` (the robot holding its pose), for at most ``longest`` s.

    Each object's velocities decay with time constant :data:`_GENTLE_TAU` (s) on top of
    the physics until no object moves faster than :data:`_REST_SPEED` (m/s) and
    :data:`_REST_SPIN` (rad/s); then the physics runs alone, until the objects stay at
    rest for :data:`_RELEASE_CALM` checks in a row (the end), or one moves faster than
    :data:`_WAKE_SPEED` (m/s: it topples, or slides off another), which damps them all
    again; at most ``longest`` s of physics in all. The objects laid on a pile thus come
    down onto the others as if put there by hand, and rest where the physics alone keeps
    them (``tests/test_pile_scene.py``). The model's dof damping is restored on return.
    """
    m, d = model, data
    dofs = np.concatenate([m.jnt_dofadr[m.body_jntadr[b]] + np.arange(6) for b in bodies])
    mass = np.repeat(m.body_mass[bodies][:, None], 3, axis=1)  # (n, 3), kg
    # per dof: the mass for the translations, the principal moments (kg m^2) for rotations
    damping = np.hstack([mass, m.body_inertia[bodies]]).ravel() / _GENTLE_TAU
    undamped = m.dof_damping[dofs].copy()
    damped, still, end = True, 0, d.time + longest
    try:
        while d.time < end and still < _RELEASE_CALM:
            m.dof_damping[dofs] = undamped + damping if damped else undamped
            hold(_REST_CHECK)
            v = np.abs(d.qvel[dofs]).reshape(-1, 6)
            rest = v[:, :3].max() < _REST_SPEED and v[:, 3:].max() < _REST_SPIN
            still = still + 1 if rest and not damped else 0
            damped = (damped and not rest) or v[:, :3].max() > _WAKE_SPEED
    finally:
        m.dof_damping[dofs] = undamped
