"""The robot's skills, written once and used by the environment.

``look`` points the wrist camera at a place; ``pick`` grasps whatever is at a position with
the jaws turned to a yaw; ``place_in_bin``, ``place_in_inspection_area`` and
``present_in_hand`` act on the object in hand. Grasps are physical: the gripper closes under a
force limit and only contact and friction hold the object. Every skill returns a
:class:`SkillResult`; a failed grasp or an unreachable pose is a reported outcome, never
retried silently.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ipbench.assets.compose import GRIPPER_ARM
from ipbench.envs.ik import look_at_rotation, tool_down_rotation
from ipbench.envs.robot import PlanningError, RobotController
from ipbench.envs.world import Places

__all__ = ["SkillConfig", "SkillResult", "Skills"]


@dataclass(frozen=True)
class SkillConfig:
    """Geometry and timing of the skills (m, s).

    Attributes
    ----------
    transit_height : TCP height above the table for moves with an empty gripper (clears the
        tallest object, 0.29 m, with the pads below the TCP).
    carry_clearance : while carrying, the held object's bottom stays this high above the
        table (so it passes over the other objects) where the arm can reach that high.
    min_grasp_height : lowest TCP height above the table (the pads are 6 cm tall).
    grasp_depth : how far below the reported position the TCP goes (grasping a segment's
        centroid a little lower holds tall objects better), clamped by ``min_grasp_height``.
    open_width, close_time, release_time : gripper half-opening (m) and waiting times (the
        close time counts from when the closing fingers' target reaches zero).
    finger_speed : how fast each finger's target moves when closing (m/s; 0.1 closes the
        jaws at 0.2 m/s, an electric parallel gripper's speed): fingers that slam shut on an
        object would launch light neighbours. ``None`` steps the target shut at once
        (``Sorting-v0``).
    min_held_width : a grasp holds something only if the jaws stay at least this far apart.
    bin_release_clearance : height of the held object's bottom above the bin rim at release.
    min_opening : narrowest jaw opening a pick pre-shapes to (m, full opening).
    guard_force : a pick's descent stops where the contact force on the gripper exceeds this
        (N), as a robot with a wrist force sensor would; ``None`` descends blind.
    """

    transit_height: float = 0.36
    carry_clearance: float = 0.31
    min_grasp_height: float = 0.04
    grasp_depth: float = 0.02
    open_width: float = 0.105
    close_time: float = 0.3
    finger_speed: float | None = 0.1
    release_time: float = 0.35
    min_held_width: float = 0.004
    bin_release_clearance: float = 0.10
    min_opening: float = 0.03
    guard_force: float | None = 20.0


@dataclass(frozen=True)
class SkillResult:
    """Outcome of a skill: ``success`` and, when it failed, a ``reason``; simulated seconds."""

    name: str
    success: bool
    reason: str = ""
    sim_time: float = 0.0


class Skills:
    """Skills of the CloPeMa robot in one simulated work cell."""

    def __init__(self, robot: RobotController, places: Places, config: SkillConfig = SkillConfig()):
        self.robot, self.places, self.config = robot, places, config
        model = robot.model
        self.grasp_actuator = model.actuator(f"{GRIPPER_ARM}_gripper_grasp").id
        self._finger = model.jnt_qposadr[model.joint(f"{GRIPPER_ARM}_gripper_finger_a").id]
        gripper_bodies = {
            b
            for b in range(model.nbody)
            if model.body(b).name.startswith(f"{GRIPPER_ARM}_gripper_")
        }
        self._gripper_geom = np.array(
            [model.geom_bodyid[g] in gripper_bodies for g in range(model.ngeom)]
        )
        self._tcp = model.site(f"{GRIPPER_ARM}_gripper_tcp").id
        self.pads = (
            model.geom(f"{GRIPPER_ARM}_gripper_pad_a").id,
            model.geom(f"{GRIPPER_ARM}_gripper_pad_b").id,
        )
        robot_bodies = {
            b for b in range(model.nbody) if model.body(b).name.startswith(("left_", "right_"))
        }
        self._free_geoms = np.array(
            [
                model.body_rootid[model.geom_bodyid[g]] not in robot_bodies
                and model.body_jntnum[model.body_rootid[model.geom_bodyid[g]]] > 0
                for g in range(model.ngeom)
            ]
        )
        ready = places.spawn_area.center + np.array([-0.1, 0.2, config.transit_height])
        self.ready = robot.solve(robot.gripper_ik, ready, tool_down_rotation(0.0))
        """Gripper-arm configuration over the table that seeds the gripper's IK solves."""
        self.camera_ready = robot.solve(
            robot.camera_ik,
            places.scene_view,
            look_at_rotation(places.scene_view, places.scene_target),
        )
        """Camera-arm configuration looking at the table that seeds the camera's IK solves."""
        self.holding = False
        """Whether the last pick or present left an object between the jaws."""
        self.grasp_height = 0.0
        """TCP height above the support surface at the last grasp (m)."""
        self.grasp_yaw = 0.0
        """Jaw yaw of the current grasp (rad)."""

    # -- helpers ---------------------------------------------------------------------------
    def _t(self) -> float:
        return float(self.robot.data.time)

    def _gripper(self, width: float, wait: float) -> None:
        self.robot.data.ctrl[self.grasp_actuator] = width
        self.robot.hold(wait)

    def _close(self) -> None:
        """Close the jaws at ``finger_speed`` and let the grip settle for ``close_time``."""
        ctrl = self.robot.data.ctrl
        start = float(ctrl[self.grasp_actuator])
        dt = self.robot.model.opt.timestep
        speed = self.config.finger_speed
        n = 0 if speed is None else int(np.ceil(start / (speed * dt)))
        for k in range(1, n + 1):
            ctrl[self.grasp_actuator] = start * (1 - k / n)
            self.robot.hold(dt)
        self._gripper(0.0, self.config.close_time)

    def _pads_touch_object(self) -> bool:
        data = self.robot.data
        touched = [False, False]
        for c in data.contact[: data.ncon]:
            for k, pad in enumerate(self.pads):
                other = c.geom2 if c.geom1 == pad else c.geom1 if c.geom2 == pad else -1
                if other >= 0 and self._free_geoms[other]:
                    touched[k] = True
        return all(touched)

    def gripper_contact_force(self) -> float:
        """Total normal contact force (N) between the gripper and anything else."""
        model, data = self.robot.model, self.robot.data
        n = data.ncon
        if n == 0:
            return 0.0
        g1, g2 = data.contact.geom1[:n], data.contact.geom2[:n]
        total, force = 0.0, np.zeros(6)
        for i in np.flatnonzero(self._gripper_geom[g1] != self._gripper_geom[g2]):
            mujoco.mj_contactForce(model, data, int(i), force)
            total += abs(force[0])
        return total

    def _touched(self) -> bool:
        guard = self.config.guard_force
        return guard is not None and self.gripper_contact_force() > guard

    def is_holding(self) -> bool:
        """Both pads touch a free object and the jaws did not close on nothing."""
        width = float(self.robot.data.qpos[self._finger])
        return width > self.config.min_held_width and self._pads_touch_object()

    def tool_pose(self, xy, z: float, yaw: float, q0: np.ndarray | None = None):
        """IK for the TCP at (``xy``, ``z``) pointing down with jaws along ``yaw``.

        From ``q0`` if given, else from the ready configuration over the table, the current
        state or home (the first that converges). Raises :class:`PlanningError`.
        """
        target, rot = np.array([xy[0], xy[1], z]), tool_down_rotation(yaw)
        return self.robot.solve(self.robot.gripper_ik, target, rot, q0, seeds=(self.ready,))

    def _move_tool(self, xy, z: float, yaw: float, speed: float | None = None) -> None:
        self.robot.move_to(self.tool_pose(xy, z, yaw), speed)

    def _retreat(self) -> None:
        """Straight up from where the gripper is to the transit height (planned from here)."""
        q = self.robot.kinematic_state()
        pos, _ = self.robot.gripper_ik.site_pose(q)
        try:
            target = self.tool_pose(pos[:2], max(pos[2], self._transit_z()), self.grasp_yaw, q)
        except PlanningError:
            return  # already as high as the arm goes here: stay
        self.robot.move_to(target)

    def _transit_z(self) -> float:
        lift = self.config.transit_height
        if self.holding:
            lift = max(lift, self.grasp_height + self.config.carry_clearance)
        return self.places.table_height + lift

    # -- skills ----------------------------------------------------------------------------
    def look(self, eye: np.ndarray, target: np.ndarray, name: str = "look") -> SkillResult:
        """Move the wrist camera to ``eye`` (3,) looking at ``target`` (3,) (world, m)."""
        t0 = self._t()
        try:
            result = self.robot.solve(
                self.robot.camera_ik, eye, look_at_rotation(eye, target), seeds=(self.camera_ready,)
            )
        except PlanningError as err:
            return SkillResult(name, False, f"unreachable: {err}", 0.0)
        self.robot.move_to(result)
        return SkillResult(name, True, "", self._t() - t0)

    def pick(self, position: np.ndarray, yaw: float, opening: float | None = None) -> SkillResult:
        """Grasp whatever is at ``position`` (3,) (world, m) with the jaws along ``yaw`` (rad),
        pre-shaped to ``opening`` (m, full jaw opening; None: fully open).

        The descent is guarded (:attr:`SkillConfig.guard_force`): where a jaw lands on
        something the arm stops and the jaws close there.
        """
        t0 = self._t()
        if self.holding:
            return SkillResult("pick", False, "already holding an object", 0.0)
        yaw = float((yaw + np.pi / 2) % np.pi - np.pi / 2)  # parallel jaws: yaw mod 180 deg
        table = self.places.table_height
        z = max(float(position[2]) - self.config.grasp_depth, table + self.config.min_grasp_height)
        try:
            above = self.tool_pose(position, self._transit_z(), yaw)
            grasp = self.tool_pose(position, z, yaw, q0=above.q)
        except PlanningError as err:
            return SkillResult("pick", False, f"unreachable: {err}", 0.0)
        half = self.config.open_width
        if opening is not None:
            half = float(np.clip(opening / 2, self.config.min_opening / 2, half))
        self._gripper(half, 0.0)
        self.robot.move_to(above)
        self.robot.move_to(grasp, speed_fraction=0.25, stop=self._touched)
        self.grasp_yaw = yaw
        # where the TCP stopped (a guarded descent can stop above the planned height)
        reached = self.robot.data.site_xpos[self._tcp][2] if self.config.guard_force else z
        self.grasp_height = float(reached) - table
        self._close()
        self._retreat()
        self.holding = self.is_holding()
        if not self.holding:
            self._gripper(self.config.open_width, 0.1)
            return SkillResult(
                "pick", False, "grasp failed: nothing held after lifting", self._t() - t0
            )
        return SkillResult("pick", True, "", self._t() - t0)

    def _set_down(self, name: str, xy, z: float, yaw: float, above_z: float) -> SkillResult:
        """Carry the object in hand over ``xy`` at ``above_z``, lower the TCP to ``z`` with the
        jaws along ``yaw``, let go and retreat upwards."""
        t0 = self._t()
        if not self.holding:
            return SkillResult(name, False, "nothing in hand", 0.0)
        try:
            above = self.tool_pose(xy, above_z, yaw)
            down = self.tool_pose(xy, z, yaw, q0=above.q)
        except PlanningError as err:
            return SkillResult(name, False, f"unreachable: {err}", 0.0)
        self.robot.move_to(above)
        self.robot.move_to(down, 0.25)
        self.grasp_yaw = yaw
        self._gripper(self.config.open_width, self.config.release_time)
        self.holding = False
        self._retreat()
        return SkillResult(name, True, "", self._t() - t0)

    def place_in_bin(self, category: str) -> SkillResult:
        """Carry the object in hand over the bin of ``category`` and let go just above the rim
        (the held object hangs about ``grasp_height`` below the TCP)."""
        box = self.places.bins[category]
        rim = box.center[2] + box.half[2]
        z = rim + self.grasp_height + self.config.bin_release_clearance
        return self._set_down(
            "place_in_bin", box.center[:2], z, self.grasp_yaw, self._transit_z() + 0.1
        )

    def place_in_inspection_area(self, turn: float = 0.0) -> SkillResult:
        """Set the object in hand down in the inspection area, turned by ``turn`` (rad)."""
        area = self.places.inspection_area.center
        z = area[2] + self.grasp_height + 0.01
        return self._set_down(
            "place_in_inspection_area", area[:2], z, self.grasp_yaw + turn, self._transit_z()
        )

    def present_in_hand(self, turn: float = 0.0) -> SkillResult:
        """Hold the object in front of the wrist camera, turned about the vertical by ``turn``."""
        t0 = self._t()
        if not self.holding:
            return SkillResult("present_in_hand", False, "nothing in hand", 0.0)
        p = self.places.present_point
        yaw = self.grasp_yaw + turn
        try:
            self._move_tool(p[:2], p[2], yaw)
        except PlanningError as err:
            return SkillResult(
                "present_in_hand", False, f"cannot turn further: {err}", self._t() - t0
            )
        self.grasp_yaw = yaw
        look = self.look(self.places.present_view, p - np.array([0, 0, self.grasp_height / 2]))
        if not look.success:
            return SkillResult("present_in_hand", False, look.reason, self._t() - t0)
        self.holding = self.is_holding()
        if not self.holding:
            return SkillResult(
                "present_in_hand", False, "object slipped out of the gripper", self._t() - t0
            )
        return SkillResult("present_in_hand", True, "", self._t() - t0)

    def release_on_table(self) -> None:
        """Open the gripper where it is (used when an episode ends with an object in hand)."""
        self._gripper(self.config.open_width, self.config.release_time)
        self.holding = False
        mujoco.mj_forward(self.robot.model, self.robot.data)
