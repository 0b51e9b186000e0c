"""The robot's skills, written once and used by the environment.

``look`` points the wrist camera at a place; ``pick`` grasps whatever is at a position with
the jaws turned to a yaw; ``place_in_bin``, ``place_in_inspection_area`` and
``present_in_hand`` act on the object in hand. Grasps are physical: the gripper closes under a
force limit and only contact and friction hold the object. Every skill returns a
:class:`SkillResult`; a failed grasp or an unreachable pose is a reported outcome.

``Sorting-v3``'s pick (:data:`V3_SKILLS`) comes down and goes up on straight vertical lines at
a reduced speed, from a little above the transit height, and reacts to what the arm senses
while grasping, as a robot with a wrist force/torque sensor
(:mod:`ipbench.envs.grasp_sensing`) and pad contact sensing would: a finger that lands on
something well above the grasp height is moved in and the descent tried again; jaws stopped
by something a pad does not touch close again higher; and a load that hangs off the jaws'
centre is set down and grasped again through its centre of mass. Its set-downs lower the
object on a straight line that stops where the wrist senses it supported, and back up
straight after letting go. Each is a
:class:`~ipbench.envs.skill_config.SkillConfig` field whose default is the released pick.
The skills plan from the commanded pose, the joint encoders, the wrist wrench and the pads'
contacts only, never from an object's pose in the simulation.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from ipbench.assets.compose import GRIPPER_ARM
from ipbench.envs.grasp_sensing import contact_wrench, load_offset
from ipbench.envs.ik import look_at_rotation, tool_down_rotation
from ipbench.envs.robot import PlanningError, RobotController
from ipbench.envs.skill_config import V3_SKILLS, SkillConfig
from ipbench.envs.world import Places

__all__ = ["SkillConfig", "SkillResult", "Skills", "V3_SKILLS"]


_RELEASED = SkillConfig()


@dataclass(frozen=True)
class SkillResult:
    """Outcome of a skill: ``success`` and, when it failed, a ``reason``; simulated seconds."""

    name: str
    success: bool
    reason: str = ""
    sim_time: float = 0.0


class Skills:
    """Skills of the CloPeMa robot in one simulated work cell."""

    def __init__(self, robot: RobotController, places: Places, config: SkillConfig = _RELEASED):
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

    def _pad_touches(self) -> list[bool]:
        """Whether each pad touches a free object (the pads' contact sensing)."""
        data = self.robot.data
        touched = [False, False]
        for c in data.contact[: data.ncon]:
            for k, pad in enumerate(self.pads):
                other = c.geom2 if c.geom1 == pad else c.geom1 if c.geom2 == pad else -1
                if other >= 0 and self._free_geoms[other]:
                    touched[k] = True
        return touched

    def _pads_touch_object(self) -> bool:
        return all(self._pad_touches())

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

    def _approach_pose(self, xy, yaw: float):
        """A pick's transit pose over ``xy``: ``approach_rise`` above the transit height where
        the arm reaches that high, else at it. Raises PlanningError."""
        if self.config.approach_rise is not None:
            try:
                return self.tool_pose(xy, self._transit_z() + self.config.approach_rise, yaw)
            except PlanningError:
                pass
        return self.tool_pose(xy, self._transit_z(), yaw)

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
        something the arm stops and the jaws close there. With :data:`V3_SKILLS` the descent
        and the lift are straight, and the pick retries and regrasps from what it senses (see
        the module docstring).
        """
        t0 = self._t()
        if self.holding:
            return SkillResult("pick", False, "already holding an object", 0.0)
        yaw = float((yaw + np.pi / 2) % np.pi - np.pi / 2)  # parallel jaws: yaw mod 180 deg
        table = self.places.table_height
        z = max(float(position[2]) - self.config.grasp_depth, table + self.config.min_grasp_height)
        try:
            above = self._approach_pose(position, yaw)
            grasp = self.tool_pose(position, z, yaw, q0=above.q)
        except PlanningError as err:
            return SkillResult("pick", False, f"unreachable: {err}", 0.0)
        half = self.config.open_width
        if opening is not None:
            half = float(np.clip(opening / 2, self.config.min_opening / 2, half))
        if self.config.approach_rise is None:
            self._gripper(half, 0.0)
            self.robot.move_to(above)
        else:  # pre-shape over the target, not where the arm comes from (over a bin)
            self.robot.move_to(above)
            self._gripper(half, 0.0)
        self._descend(position, z, yaw, above, grasp)
        if self.config.early_contact is not None:
            position, half = self._descend_again(position, z, yaw, half)
        self.grasp_yaw = yaw
        # where the TCP stopped (a guarded descent can stop above the planned height)
        reached = self.robot.data.site_xpos[self._tcp][2] if self.config.guard_force else z
        self.grasp_height = float(reached) - table
        self._close()
        if self.config.rim_regrasp is not None:
            self._close_higher(position, yaw, half)
        if self.config.balance_lift is not None:
            self._balance(yaw, half)
        if self.config.line_step is None:
            self._retreat()
        else:
            self._lift_straight()
        self.holding = self.is_holding()
        if not self.holding:
            self._gripper(self.config.open_width, 0.1)
            return SkillResult(
                "pick", False, "grasp failed: nothing held after lifting", self._t() - t0
            )
        return SkillResult("pick", True, "", self._t() - t0)

    # -- straight moves and sensed corrections of a pick (Sorting-v3) ---------------------------
    def _vertical_path(
        self, xy, z_from: float, z_to: float, yaw: float, q0: np.ndarray, partial: bool = False
    ) -> list:
        """IK waypoints (``line_step`` apart, ``z_to`` last) of the TCP's vertical line over
        ``xy`` from ``z_from``, each solved from the previous one. Raises PlanningError, or
        with ``partial`` returns the waypoints up to the first unreachable one."""
        n = max(1, int(np.ceil(abs(z_to - z_from) / self.config.line_step)))
        path = []
        for k in range(1, n + 1):
            try:
                step = self.tool_pose(xy, z_from + (z_to - z_from) * k / n, yaw, q0)
            except PlanningError:
                if partial:
                    break
                raise
            path.append(step)
            q0 = step.q
        return path

    def _descend(self, position, z: float, yaw: float, above, grasp) -> None:
        """The guarded descent from ``above`` to ``grasp`` (TCP height ``z``): a vertical line
        with ``line_step``, else one joint-space move."""
        if self.config.line_step is not None:
            if self._line_down(position[:2], above, z, yaw, self._touched):
                return
        self.robot.move_to(grasp, speed_fraction=0.25, stop=self._touched)

    def _line_down(self, xy, above, z: float, yaw: float, stop) -> bool:
        """Down a vertical line over ``xy`` from the pose ``above`` to TCP height ``z`` (m),
        peaking at ``line_speed``, until ``stop()`` (None: to the end); False, with nothing
        moved, when the line cannot be planned."""
        start = self.robot.gripper_ik.site_pose(above.q)[0][2]
        try:
            path = self._vertical_path(xy, start, z, yaw, above.q)
        except PlanningError:
            return False
        seconds = 1.875 * abs(start - z) / self.config.line_speed  # quintic peak
        self.robot.move_path(path, 0.25, stop=stop, min_duration=seconds)
        return True

    def _lift_straight(self, top: float | None = None) -> None:
        """Straight up from where the TCP is to ``top`` (world z, m), by default the height a
        carry starts from (the held object's bottom ``carry_clearance`` above the table, at
        least the transit height), or as high as the arm reaches over here: the next move
        then sets off above the others."""
        q = self.robot.kinematic_state()
        pos, _ = self.robot.gripper_ik.site_pose(q)
        cfg = self.config
        if top is None:
            lift = max(cfg.transit_height, self.grasp_height + cfg.carry_clearance)
            top = self.places.table_height + lift
        top = max(pos[2], top)
        path = self._vertical_path(pos[:2], pos[2], top, self.grasp_yaw, q, partial=True)
        if not path:
            self._retreat()
            return
        end = self.robot.gripper_ik.site_pose(path[-1].q)[0][2]
        self.robot.move_path(path, min_duration=1.875 * (end - pos[2]) / cfg.line_speed)

    def _wrench_offset(self) -> tuple[float, np.ndarray | None]:
        """The wrist wrench's vertical force (N, + pushes the gripper up) and the horizontal
        offset (3,) of its load from the TCP (m; None under ``min_load``)."""
        tcp = self.robot.data.site_xpos[self._tcp].copy()
        wrench = contact_wrench(self.robot.model, self.robot.data, self._gripper_geom, tcp)
        return float(wrench.force[2]), load_offset(wrench, self.config.min_load)

    def _descend_again(self, position, z: float, yaw: float, half: float):
        """After a descent that stopped more than ``early_contact`` above the planned TCP
        height ``z``: the finger under the wrench's centre of pressure moves in by
        ``finger_inset`` (the TCP shifts half of it away, the jaws narrow by half of it, the
        other finger stays) and the descent starts again from the transit height. Returns the
        grasp's position and half-opening."""
        cfg = self.config
        closing = np.array([np.cos(yaw), np.sin(yaw)])
        for _ in range(cfg.contact_retries):
            if self.robot.data.site_xpos[self._tcp][2] - z <= cfg.early_contact:
                break
            force_z, offset = self._wrench_offset()
            narrower = half - cfg.finger_inset / 2
            if offset is None or force_z <= 0 or narrower < cfg.min_opening / 2:
                break
            side = float(offset[:2] @ closing)
            if abs(abs(side) - half) > cfg.finger_inset:
                break  # not under a finger (the pad's face to the finger's outer face): the palm
            xy = np.asarray(position[:2], float) - np.sign(side) * cfg.finger_inset / 2 * closing
            try:
                above = self._approach_pose(xy, yaw)
                grasp = self.tool_pose(xy, z, yaw, q0=above.q)
            except PlanningError:
                break
            position, half = np.array([xy[0], xy[1], position[2]]), narrower
            self.robot.move_to(above)
            self._gripper(half, 0.0)
            self._descend(position, z, yaw, above, grasp)
        return position, half

    def _close_higher(self, position, yaw: float, half: float) -> None:
        """Jaws stopped by something a pad does not touch (it is wider above that pad, as a
        bowl's flared rim that meets the finger): open, rise by ``rim_regrasp`` and close
        again there."""
        if self.robot.data.qpos[self._finger] <= self.config.min_held_width:
            return
        if all(self._pad_touches()):
            return
        z = float(self.robot.data.site_xpos[self._tcp][2]) + self.config.rim_regrasp
        try:
            higher = self.tool_pose(position[:2], z, yaw, self.robot.kinematic_state())
        except PlanningError:
            return
        self._gripper(half, self.config.release_time)
        self.robot.move_to(higher, speed_fraction=0.25)
        self.grasp_height = z - self.places.table_height
        self._close()

    def _balance(self, yaw: float, half: float) -> None:
        """Lift ``balance_lift`` slowly, read the load's centre of mass from the wrist wrench
        and, if it hangs more than ``com_tolerance`` off the TCP along the jaws' width, set the
        load down, open, move the TCP over it, close and lift slowly again (once)."""
        cfg = self.config
        q = self.robot.kinematic_state()
        pos, _ = self.robot.gripper_ik.site_pose(q)
        width = tool_down_rotation(yaw)[:, 1]  # the jaws' width direction (horizontal)
        try:
            up = self.tool_pose(pos[:2], pos[2] + cfg.balance_lift, yaw, q)
        except PlanningError:
            return
        self.robot.move_to(up, speed_fraction=0.25)
        self.robot.hold(cfg.balance_time)
        force_z, offset = self._wrench_offset()
        if offset is None or force_z >= 0:
            return  # nothing hangs from the jaws
        shift = float(offset @ width)
        if abs(shift) <= cfg.com_tolerance:
            return
        xy = pos[:2] + shift * width[:2]
        try:
            down = self.tool_pose(pos[:2], pos[2], yaw, up.q)
            over = self.tool_pose(xy, pos[2], yaw, down.q)
            up = self.tool_pose(xy, pos[2] + cfg.balance_lift, yaw, over.q)
        except PlanningError:
            return
        self.robot.move_to(down, speed_fraction=0.25)
        self._gripper(half, cfg.release_time)
        self.robot.move_to(over, speed_fraction=0.25)
        self._close()
        self.robot.move_to(up, speed_fraction=0.25)

    def _carry_poses(self, xy, z: float, above_z: float, yaw: float):
        """The poses of a set-down over ``xy``: the carry pose at ``above_z`` and the release
        pose at ``z`` (TCP heights, m). With ``line_step``, where the arm cannot reach
        ``above_z`` there, the carry goes as high as it reaches, tried ``line_step`` apart down
        to the release height. Raises PlanningError."""
        heights = [above_z]
        if self.config.line_step is not None and above_z > z:
            n = int(np.ceil((above_z - z) / self.config.line_step))
            heights += [above_z - (above_z - z) * k / n for k in range(1, n + 1)]
        for k, height in enumerate(heights):
            try:
                above = self.tool_pose(xy, height, yaw)
                break
            except PlanningError:
                if k == len(heights) - 1:
                    raise
        return above, self.tool_pose(xy, z, yaw, q0=above.q)

    def _set_down(self, name: str, xy, z: float, yaw: float, above_z: float) -> SkillResult:
        """Carry the object in hand over ``xy`` at ``above_z``, lower the TCP to ``z`` with the
        jaws along ``yaw``, let go and retreat upwards. With ``line_step`` the carry is as high
        as the arm reaches there (:meth:`_carry_poses`), the lowering stops where the object
        rests on something (:meth:`_lower_until_supported`), and the retreat goes straight up
        to the carry height, so that the open jaws leave the way they came and do not sweep
        what they set down."""
        t0 = self._t()
        if not self.holding:
            return SkillResult(name, False, "nothing in hand", 0.0)
        try:
            above, down = self._carry_poses(xy, z, above_z, yaw)
        except PlanningError as err:
            return SkillResult(name, False, f"unreachable: {err}", 0.0)
        self.robot.move_to(above)
        if self.config.line_step is None:
            self.robot.move_to(down, 0.25)
        else:
            self._lower_until_supported(xy, above, down, yaw)
        self.grasp_yaw = yaw
        self._gripper(self.config.open_width, self.config.release_time)
        self.holding = False
        if self.config.line_step is None:
            self._retreat()
        else:
            carry_z = float(self.robot.gripper_ik.site_pose(above.q)[0][2])
            self._lift_straight(max(carry_z, self._transit_z()))
        return SkillResult(name, True, "", self._t() - t0)

    def _lower_until_supported(self, xy, above, down, yaw: float) -> None:
        """Lower the object in hand from the carry pose ``above`` to the release pose ``down``
        on a vertical line over ``xy``, stopping where the wrist wrench senses it supported:
        the load's vertical force has fallen to half of what hung from the jaws at the start
        (what it now rests on, e.g. an object standing out of a full bin, carries the rest)."""
        force_z, _ = self._wrench_offset()

        def supported() -> bool:
            return self._wrench_offset()[0] > 0.5 * force_z

        stop = supported if force_z < -self.config.min_load else None
        z = float(self.robot.gripper_ik.site_pose(down.q)[0][2])
        if not self._line_down(xy, above, z, yaw, stop):
            self.robot.move_to(down, 0.25)

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
