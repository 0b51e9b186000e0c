"""Joint-space motion of the simulated robot: IK targets executed by its position servos.

:class:`RobotController` plans with :class:`~ipbench.envs.ik.ArmIK` on a kinematic copy of the
work cell (robot and static furniture, no objects) and executes the plan under physics: a
quintic joint trajectory, limited by a fraction of each joint's maximum speed (the ``user``
value of the joint in the MJCF), is streamed to the actuators at every physics step.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache

import mujoco
import numpy as np

from ipbench.assets.compose import (
    BIN_INTERIOR,
    CAMERA_ARM,
    GRIPPER_ARM,
    arm_joint_names,
    build_workcell_spec,
)
from ipbench.envs.ik import ArmIK, IKConfig, IKResult

__all__ = ["MotionConfig", "RobotController", "PlanningError", "ik_model"]


class PlanningError(RuntimeError):
    """No joint configuration reaches the requested pose."""


@dataclass(frozen=True)
class MotionConfig:
    """How fast and how precisely the robot moves.

    Attributes
    ----------
    speed_fraction : fraction of each joint's maximum speed used by trajectories.
    min_duration : shortest trajectory (s).
    settle_tolerance : joint error (rad) under which a motion counts as arrived.
    settle_timeout : longest wait for arrival after the trajectory ends (s).
    ik : IK loop settings.
    """

    speed_fraction: float = 0.5
    min_duration: float = 0.15
    settle_tolerance: float = 2e-3
    settle_timeout: float = 0.3
    ik: IKConfig = IKConfig()


@lru_cache(maxsize=2)
def ik_model(bin_depth: float = BIN_INTERIOR[2]) -> mujoco.MjModel:
    """The kinematic work cell used for planning (compiled once per process and bin depth)."""
    return build_workcell_spec(bin_depth).compile()


def _collision_geoms(model: mujoco.MjModel, prefix: str) -> list[int]:
    """Collision geoms (contype or conaffinity set) of bodies whose name starts with ``prefix``."""
    out = []
    for g in range(model.ngeom):
        if model.geom_contype[g] == 0 and model.geom_conaffinity[g] == 0:
            continue
        if model.body(model.geom_bodyid[g]).name.startswith(prefix):
            out.append(g)
    return out


class RobotController:
    """Moves the simulated arms; ``step`` advances the physics one step (and records video).

    Parameters
    ----------
    model, data : the simulation.
    step : callback that advances the simulation one physics step.
    config : motion settings.
    planning_model : the kinematic work cell to plan in (default :func:`ik_model`); it must
        have the simulation's furniture.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        step: Callable[[], None],
        config: MotionConfig = MotionConfig(),
        planning_model: mujoco.MjModel | None = None,
    ) -> None:
        self.model, self.data, self._step, self.config = model, data, step, config
        kin = ik_model() if planning_model is None else planning_model
        self._kin = kin
        furniture = [
            g
            for g in range(kin.ngeom)
            if kin.geom_bodyid[g] != 0
            and kin.body(kin.geom_bodyid[g]).name.startswith(("work_table", "bin_"))
            and kin.geom_contype[g]
        ]
        self.gripper_joints = arm_joint_names(GRIPPER_ARM)
        self.camera_joints = arm_joint_names(CAMERA_ARM)
        gripper_links = [
            g
            for g in _collision_geoms(kin, f"{GRIPPER_ARM}_")
            if "finger" not in kin.body(kin.geom_bodyid[g]).name
        ]
        camera_links = _collision_geoms(kin, f"{CAMERA_ARM}_")
        self.gripper_ik = ArmIK(
            kin,
            f"{GRIPPER_ARM}_gripper_tcp",
            self.gripper_joints,
            obstacles=furniture + camera_links,
            moving_geoms=gripper_links,
            config=config.ik,
        )
        self.camera_ik = ArmIK(
            kin,
            f"{CAMERA_ARM}_wrist_optical",
            self.camera_joints,
            obstacles=furniture + _collision_geoms(kin, f"{GRIPPER_ARM}_"),
            moving_geoms=camera_links,
            free_roll=True,
            config=config.ik,
        )
        # Joint name -> (qpos address in the simulation, in the IK model, actuator id, speed).
        self._joint = {}
        for a in range(model.nu):
            j = model.actuator_trnid[a, 0]
            name = model.joint(j).name
            self._joint[name] = (
                int(model.jnt_qposadr[j]),
                int(kin.jnt_qposadr[kin.joint(name).id]),
                a,
                float(model.jnt_user[j, 0]) if model.nuser_jnt else 1.0,
            )

    # -- state ---------------------------------------------------------------------------
    def joint_positions(self, names) -> np.ndarray:
        return np.array([self.data.qpos[self._joint[n][0]] for n in names])

    def kinematic_state(self) -> np.ndarray:
        """(nq_ik,) the robot's current joints in the IK model's layout.

        Values are clipped into the joint ranges: under load a servo can sit a hair outside
        its range (e.g. the coupled fingers closed on nothing), which would make the IK's
        limit constraints infeasible.
        """
        q = self._kin.qpos0.copy()
        for sim_adr, kin_adr, _, _ in self._joint.values():
            q[kin_adr] = self.data.qpos[sim_adr]
        kin = self._kin
        limited = kin.jnt_limited.astype(bool)
        adr = kin.jnt_qposadr[limited]
        q[adr] = np.clip(q[adr], kin.jnt_range[limited, 0], kin.jnt_range[limited, 1])
        return q

    # -- planning ------------------------------------------------------------------------
    def seeded_state(self, seed: IKResult | None) -> np.ndarray:
        """The current state with ``seed``'s joints replaced by its solution.

        Differential IK is local: started from wherever the arm happens to be (say, over a
        bin) it can stall against a collision limit. Seeding from a fixed configuration near
        the target region makes the solve independent of the path the arm took.
        """
        q = self.kinematic_state()
        if seed is not None:
            kin = self._kin
            for name, value in zip(seed.joints, seed.qpos, strict=True):
                q[kin.jnt_qposadr[kin.joint(name).id]] = value
        return q

    def home_state(self, joints) -> np.ndarray:
        """The current state with ``joints`` at CloPeMa's home (0)."""
        q = self.kinematic_state()
        for name in joints:
            q[self._kin.jnt_qposadr[self._kin.joint(name).id]] = 0.0
        return q

    def solve(
        self,
        ik: ArmIK,
        position,
        rotation,
        q0: np.ndarray | None = None,
        seeds: tuple[IKResult, ...] = (),
    ) -> IKResult:
        """IK for ``ik``'s site; raises :class:`PlanningError` if no start converges.

        With ``q0`` only that start is tried. Otherwise the starts are, in order: each of
        ``seeds`` (see :meth:`seeded_state`), the current state, and CloPeMa's home for the
        moving arm. Differential IK is local, so a few starts make it robust.
        """
        if q0 is not None:
            starts = [q0]
        else:
            starts = [self.seeded_state(s) for s in seeds]
            starts += [self.kinematic_state(), self.home_state(ik.joints)]
        result = None
        for start in starts:
            result = ik.solve(start, position, rotation)
            if result.converged:
                return result
        raise PlanningError(
            f"{ik.site} cannot reach {np.round(position, 3).tolist()} "
            f"(residual {result.position_error * 1000:.1f} mm, "
            f"{np.degrees(result.orientation_error):.1f} deg)"
        )

    # -- execution -----------------------------------------------------------------------
    def move_joints(
        self,
        targets: dict[str, float],
        speed_fraction: float | None = None,
        stop: Callable[[], bool] | None = None,
    ) -> float:
        """Drive the named joints to ``targets`` (rad) along a quintic; returns the sim time (s).

        A guarded move: when ``stop()`` turns true after a physics step, the joints' targets
        are set to where the joints are and the motion ends there (a force-limited approach).
        """
        frac = self.config.speed_fraction if speed_fraction is None else speed_fraction
        names = list(targets)
        acts = [self._joint[n][2] for n in names]
        start = np.array([self.data.ctrl[a] for a in acts])
        goal = np.array([targets[n] for n in names])
        vmax = np.array([self._joint[n][3] for n in names]) * frac
        # A quintic's peak speed is 15/8 of the mean speed.
        duration = max(self.config.min_duration, float(np.max(1.875 * np.abs(goal - start) / vmax)))

        def target(s: float) -> np.ndarray:
            return start + (goal - start) * (s**3 * (10 - 15 * s + 6 * s * s))

        return self._drive(names, duration, target, goal, stop)

    def _drive(
        self,
        names: list[str],
        duration: float,
        target: Callable[[float], np.ndarray],
        goal: np.ndarray,
        stop: Callable[[], bool] | None,
    ) -> float:
        """Set the named joints' servo targets to ``target(s)``, s from 0 to 1 over
        ``duration`` (s) of physics steps, then wait for them to settle at ``goal``; ``stop``:
        see :meth:`move_joints`. Returns the sim time (s)."""
        acts = [self._joint[n][2] for n in names]
        dt = self.model.opt.timestep
        n_steps = int(np.ceil(duration / dt))
        t0 = self.data.time
        for k in range(1, n_steps + 1):
            self.data.ctrl[acts] = target(k / n_steps)
            self._step()
            if stop is not None and stop():
                self.data.ctrl[acts] = [self.data.qpos[self._joint[n][0]] for n in names]
                return self.data.time - t0
        qadr = [self._joint[n][0] for n in names]
        for _ in range(int(self.config.settle_timeout / dt)):
            if np.max(np.abs(self.data.qpos[qadr] - goal)) < self.config.settle_tolerance:
                break
            self._step()
        return self.data.time - t0

    def move_to(
        self,
        result: IKResult,
        speed_fraction: float | None = None,
        stop: Callable[[], bool] | None = None,
    ) -> float:
        """Execute an IK solution (its moving joints only); ``stop``: see :meth:`move_joints`."""
        targets = dict(zip(result.joints, result.qpos, strict=True))
        return self.move_joints(targets, speed_fraction, stop)

    def move_path(
        self,
        path: Sequence[IKResult],
        speed_fraction: float | None = None,
        stop: Callable[[], bool] | None = None,
        min_duration: float | None = None,
    ) -> float:
        """Drive the joints through the waypoints ``path`` (IK solutions for the same joints)
        in one motion lasting at least ``min_duration`` (s); returns the sim time (s).

        The joint targets run along the polyline from the current targets through the
        waypoints, timed by one quintic in the path parameter, and the duration is the one
        :meth:`move_joints` gives the polyline's summed per-joint lengths (so no joint exceeds
        ``speed_fraction`` of its maximum speed). Closely spaced waypoints of a Cartesian
        line make the TCP follow that line, as a controller's linear move does. ``stop``:
        see :meth:`move_joints`.
        """
        if not path:
            return 0.0
        frac = self.config.speed_fraction if speed_fraction is None else speed_fraction
        names = list(path[0].joints)
        acts = [self._joint[n][2] for n in names]
        points = np.array([[self.data.ctrl[a] for a in acts]] + [r.qpos for r in path])
        vmax = np.array([self._joint[n][3] for n in names]) * frac
        seconds = np.max(np.abs(np.diff(points, axis=0)) / vmax, axis=1)  # (n,) per segment
        knots = np.concatenate([[0.0], np.cumsum(seconds)])
        duration = max(self.config.min_duration, min_duration or 0.0, 1.875 * float(knots[-1]))

        def target(s: float) -> np.ndarray:
            u = knots[-1] * s**3 * (10 - 15 * s + 6 * s * s)
            i = min(int(np.searchsorted(knots, u, side="right")) - 1, len(seconds) - 1)
            w = 0.0 if seconds[i] == 0 else (u - knots[i]) / seconds[i]
            return points[i] + (points[i + 1] - points[i]) * min(w, 1.0)

        return self._drive(names, duration, target, points[-1], stop)

    def hold(self, duration: float) -> None:
        """Let the physics run for ``duration`` s with the current targets."""
        for _ in range(int(round(duration / self.model.opt.timestep))):
            self._step()

    def teleport(self, targets: dict[str, float]) -> None:
        """Set joints and their servo targets directly (only at reset, before anything moves)."""
        for name, value in targets.items():
            sim_adr, _, act, _ = self._joint[name]
            self.data.qpos[sim_adr] = value
            self.data.ctrl[act] = value
        mujoco.mj_forward(self.model, self.data)
