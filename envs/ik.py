"""Inverse kinematics for one arm with mink: frame targets under joint limits and collisions.

The solver runs on its own kinematic copy of the work cell (robot, tables and bins, no
objects), so it never touches the simulation state. A target is a world pose of a site (the
gripper's TCP or the wrist camera's optical frame); the arm's six joints, and optionally the
turntable, move, every other joint is frozen exactly (mink's ``DofFreezingTask`` as an
equality constraint). Configuration limits and collision avoidance between the moving arm and
the tables, bins and the other arm are mink limits.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mink
import mujoco
import numpy as np

__all__ = ["IKConfig", "IKResult", "ArmIK", "tool_down_rotation", "look_at_rotation"]


@dataclass(frozen=True)
class IKConfig:
    """Settings of the differential IK loop.

    Attributes
    ----------
    dt : integration step of the differential IK (s); with gain 1 one step removes the
        linearised error, so this only scales the velocity limits.
    max_iterations : iterations before giving up.
    position_tolerance : converged when the frame is this close to the target (m).
    orientation_tolerance : ... and its rotation error is below this (rad).
    posture_cost : weight pulling the joints towards the start configuration (regularises
        redundancy and keeps solutions near the previous one).
    collision_margin : minimum distance kept between the arm and the obstacles (m).
    solver : QP solver used by mink.
    """

    dt: float = 0.2
    max_iterations: int = 150
    position_tolerance: float = 1e-3
    orientation_tolerance: float = 5e-3
    posture_cost: float = 1e-3
    collision_margin: float = 0.01
    solver: str = "daqp"


@dataclass(frozen=True)
class IKResult:
    """Outcome of one IK solve.

    Attributes
    ----------
    q : (nq,) joint positions of the IK model, by the IK model's qpos layout (rad, m).
    joints : names of the joints that moved, in the order of ``qpos``.
    qpos : (len(joints),) their solved positions (rad).
    position_error : distance of the frame from the target (m).
    orientation_error : angle between the frame's and the target's rotation (rad).
    converged : both errors within the tolerances.
    iterations : iterations used.
    """

    q: np.ndarray
    joints: tuple[str, ...]
    qpos: np.ndarray
    position_error: float
    orientation_error: float
    converged: bool
    iterations: int


def tool_down_rotation(yaw: float) -> np.ndarray:
    """(3, 3) world rotation of a tool pointing down (+z to world -z) with jaws along ``yaw``.

    The tool's x axis (the jaw closing direction) is (cos yaw, sin yaw, 0).
    """
    x = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    z = np.array([0.0, 0.0, -1.0])
    return np.column_stack([x, np.cross(z, x), z])


def look_at_rotation(eye: np.ndarray, target: np.ndarray, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """(3, 3) world rotation of a MuJoCo camera/site at ``eye`` looking at ``target``.

    MuJoCo cameras look along their -z with +y up; the image's up is as close to ``up`` as
    the viewing direction allows.
    """
    forward = np.asarray(target, float) - np.asarray(eye, float)
    forward /= np.linalg.norm(forward)
    z = -forward
    x = np.cross(np.asarray(up, float), z)
    if np.linalg.norm(x) < 1e-6:  # looking straight down/up: image up along world +x
        x = np.cross(np.array([1.0, 0.0, 0.0]), z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


class ArmIK:
    """IK for one site driven by one arm (and optionally the turntable).

    Parameters
    ----------
    model : the IK model (robot and static work cell, no free objects).
    site : name of the site to place.
    joints : names of the joints allowed to move.
    obstacles : geom names the moving bodies must keep clear of.
    moving_geoms : collision geom names of the moving chain (checked against ``obstacles``).
    free_roll : leave the rotation about the site's z axis free (a camera on a 5-DOF chain,
        such as the Xtion on the B link, can point anywhere but not also choose its roll);
        the orientation error is then the angle between the site's and the target's z axes.
    config : loop settings.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        site: str,
        joints: Sequence[str],
        obstacles: Sequence[str] = (),
        moving_geoms: Sequence[str] = (),
        free_roll: bool = False,
        config: IKConfig = IKConfig(),
    ) -> None:
        self.model = model
        self.site = site
        self.joints = tuple(joints)
        self.config = config
        self._configuration = mink.Configuration(model)
        self._qadr = np.array([model.jnt_qposadr[model.joint(j).id] for j in self.joints])
        moving_dofs = {int(model.jnt_dofadr[model.joint(j).id]) for j in self.joints}
        frozen = [i for i in range(model.nv) if i not in moving_dofs]
        self._constraints = [mink.DofFreezingTask(model, dof_indices=frozen)] if frozen else []
        self.free_roll = free_roll
        self._frame_task = mink.FrameTask(
            site,
            "site",
            position_cost=1.0,
            orientation_cost=[1.0, 1.0, 0.0] if free_roll else 1.0,
            lm_damping=1e-3,
        )
        self._posture = mink.PostureTask(model, cost=config.posture_cost)
        self._limits: list[mink.Limit] = [mink.ConfigurationLimit(model)]
        if obstacles and moving_geoms:
            self._limits.append(
                mink.CollisionAvoidanceLimit(
                    model,
                    geom_pairs=[(list(moving_geoms), list(obstacles))],
                    minimum_distance_from_collisions=config.collision_margin,
                    collision_detection_distance=config.collision_margin + 0.1,
                )
            )

    def site_pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World position (3,) and rotation (3, 3) of the site at configuration ``q``."""
        self._configuration.update(q)
        data = self._configuration.data
        return data.site(self.site).xpos.copy(), data.site(self.site).xmat.reshape(3, 3).copy()

    def _errors(self, position: np.ndarray, rotation: np.ndarray) -> tuple[float, float]:
        """Distance (m) and angle (rad) between the site's current pose and the target."""
        data = self._configuration.data
        pos = data.site(self.site).xpos
        rot = data.site(self.site).xmat.reshape(3, 3)
        pos_err = float(np.linalg.norm(pos - position))
        if self.free_roll:
            cos = float(np.clip(rot[:, 2] @ np.asarray(rotation)[:, 2], -1.0, 1.0))
        else:
            cos = float(np.clip((np.trace(np.asarray(rotation).T @ rot) - 1.0) / 2.0, -1.0, 1.0))
        return pos_err, float(np.arccos(cos))

    def solve(self, q0: np.ndarray, position: np.ndarray, rotation: np.ndarray) -> IKResult:
        """Move the site to ``position`` (3,) m and ``rotation`` (3, 3), starting from ``q0``."""
        cfg = self.config
        position, rotation = np.asarray(position, float), np.asarray(rotation, float)
        self._configuration.update(np.asarray(q0, float))
        target = mink.SE3.from_rotation_and_translation(
            mink.SO3.from_matrix(np.asarray(rotation, float)), np.asarray(position, float)
        )
        self._frame_task.set_target(target)
        self._posture.set_target(np.asarray(q0, float))
        tasks = [self._frame_task, self._posture]
        pos_err = rot_err = np.inf
        iterations = 0
        for iterations in range(1, cfg.max_iterations + 1):  # noqa: B007 (reported below)
            try:
                vel = mink.solve_ik(
                    self._configuration,
                    tasks,
                    cfg.dt,
                    cfg.solver,
                    damping=1e-4,
                    limits=self._limits,
                    constraints=self._constraints,
                )
            except mink.NoSolutionFound:  # infeasible limits: report as not converged
                break
            self._configuration.integrate_inplace(vel, cfg.dt)
            pos_err, rot_err = self._errors(position, rotation)
            if pos_err < cfg.position_tolerance and rot_err < cfg.orientation_tolerance:
                break
        q = self._configuration.q.copy()
        return IKResult(
            q=q,
            joints=self.joints,
            qpos=q[self._qadr].copy(),
            position_error=pos_err,
            orientation_error=rot_err,
            converged=bool(
                pos_err < cfg.position_tolerance and rot_err < cfg.orientation_tolerance
            ),
            iterations=iterations,
        )
