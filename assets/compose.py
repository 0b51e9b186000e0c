"""Compose the CloPeMa work cell from its MJCF parts with :class:`mujoco.MjSpec`.

``motoman/motoman.xml`` (the robot base, included by the scene ``scenes/workcell.xml``)
carries mount sites; two ``ma1400.xml`` arms attach to them (prefixes
``left_`` and ``right_``), the gripper to the left arm's flange, the Xtion to the right arm's
camera mount, and two ``ptu_d46.xml`` units to the head mounts (``head_left_``,
``head_right_``); the bins are generated per category. Names follow from the prefixes:
``left_joint_s``, ``left_gripper_tcp``, ``right_wrist_camera``, ``head_left_camera``, ...
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from ipbench.assets import ASSETS_DIR

__all__ = [
    "ARM_JOINTS",
    "GRIPPER_ARM",
    "CAMERA_ARM",
    "HEAD_SIDES",
    "BIN_PITCH",
    "BIN_INTERIOR",
    "attach_robot_parts",
    "build_robot_spec",
    "build_workcell_spec",
    "arm_joint_names",
    "head_gaze",
]

ARM_JOINTS: tuple[str, ...] = ("joint_s", "joint_l", "joint_u", "joint_r", "joint_b", "joint_t")
"""MA1400 axes from base to tool (prefix with ``left_`` or ``right_``)."""
GRIPPER_ARM = "left"
"""The arm that carries the parallel gripper (CloPeMa r2)."""
CAMERA_ARM = "right"
"""The arm that carries the Xtion wrist camera (CloPeMa r1, whose Xtion was calibrated)."""
HEAD_SIDES: tuple[str, ...] = ("left", "right")


def arm_joint_names(arm: str) -> tuple[str, ...]:
    """Joint names of one arm, base to tool, e.g. ``left_joint_s`` ... ``left_joint_t``."""
    return tuple(f"{arm}_{j}" for j in ARM_JOINTS)


def _load(*parts: str) -> mujoco.MjSpec:
    return mujoco.MjSpec.from_file(str(ASSETS_DIR.joinpath(*parts)))


def attach_robot_parts(spec: mujoco.MjSpec) -> None:
    """Attach the arms, their tools and the head to the mount sites of ``motoman.xml``.

    ``spec`` is ``motoman.xml`` itself or a scene that includes it.
    """
    for arm, tool, mount, prefix in (
        (GRIPPER_ARM, ("motoman", "gripper.xml"), "flange", "gripper_"),
        (CAMERA_ARM, ("motoman", "xtion.xml"), "camera_mount", "wrist_"),
    ):
        arm_spec = _load("motoman", "ma1400.xml")
        arm_spec.attach(_load(*tool), site=arm_spec.site(mount), prefix=prefix)
        spec.attach(arm_spec, site=spec.site(f"{arm}_arm_mount"), prefix=f"{arm}_")
    for side in HEAD_SIDES:
        spec.attach(
            _load("head", "ptu_d46.xml"),
            site=spec.site(f"head_{side}_mount"),
            prefix=f"head_{side}_",
        )


def build_robot_spec() -> mujoco.MjSpec:
    """The dual-arm robot alone: turntable, two arms, gripper, wrist Xtion and the PTU head."""
    robot = _load("motoman", "motoman.xml")
    attach_robot_parts(robot)
    return robot


BIN_PITCH = 0.32
"""Distance between neighbouring bin centres along x (m)."""
BIN_INTERIOR = (0.29, 0.36, 0.32)
"""Inside length (x), width (y) and height (z) of a bin (m). 32 cm deep holds five 29 cm
juice bottles below the rim (``Sorting-v0``'s 24 cm bins overflowed: a bottle dropped on the
pile knocked others out, often into the next bin)."""
_BIN_WALL = 0.005  # half thickness (m)


def _add_bins(
    scene: mujoco.MjSpec, categories: Sequence[str], depth: float, floor_backing: float = 0.0
) -> None:
    """One open box per category along the ``bin_row_start`` site, ``depth`` m deep inside,
    coloured by material ``bin_<category>``; a site ``bin_<category>`` fills each bin's
    inside (used to tell what is in which bin); ``floor_backing`` > 0 makes each floor that
    much thicker, downwards (:func:`build_workcell_spec`)."""
    start = np.array(scene.site("bin_row_start").pos)
    ix, iy, iz = 0.5 * BIN_INTERIOR[0], 0.5 * BIN_INTERIOR[1], 0.5 * depth
    w = _BIN_WALL
    # (half size, centre) of the floor and the four walls, in the bin frame.
    b = 0.5 * floor_backing  # the floor grows downwards; its top stays at 2 w
    panels = [
        ((ix + 2 * w, iy + 2 * w, w + b), (0, 0, w - b)),
        ((w, iy + 2 * w, iz), (ix + w, 0, 2 * w + iz)),
        ((w, iy + 2 * w, iz), (-ix - w, 0, 2 * w + iz)),
        ((ix, w, iz), (0, iy + w, 2 * w + iz)),
        ((ix, w, iz), (0, -iy - w, 2 * w + iz)),
    ]
    for k, category in enumerate(categories):
        body = scene.worldbody.add_body(
            name=f"bin_{category}", pos=start + np.array([k * BIN_PITCH, 0.0, 0.0])
        )
        for size, centre in panels:
            body.add_geom(
                type=mujoco.mjtGeom.mjGEOM_BOX,
                size=size,
                pos=centre,
                material=f"bin_{category}",
                friction=[0.5, 0.01, 0.001],
            )
        body.add_site(
            name=f"bin_{category}",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[ix, iy, iz],
            pos=[0, 0, 2 * w + iz],
            group=5,
        )


def build_workcell_spec(
    bin_depth: float = BIN_INTERIOR[2], bin_floor_backing: float = 0.0
) -> mujoco.MjSpec:
    """The work cell scene (``workcell.xml``, which includes the robot) with the robot's parts
    and the bins (``bin_depth`` m deep inside) attached; no objects yet.

    ``bin_floor_backing`` (m): each bin's 1 cm floor is that much thicker, downwards, its top
    where it was (0, as every released id). An object released above a bin hits the floor at
    up to ~3 m/s, ~6 mm per 2 ms physics step: a thin part (a bowl's foot, a mug's handle)
    can pass a 1 cm floor's mid-plane, after which the contact pushes it down and it stays
    stuck in the floor.
    """
    from ipbench.assets.objects import CATEGORIES

    scene = _load("scenes", "workcell.xml")
    attach_robot_parts(scene)
    _add_bins(scene, CATEGORIES, bin_depth, bin_floor_backing)
    return scene


def head_gaze(
    camera_pos: np.ndarray, base_xmat: np.ndarray, target: np.ndarray
) -> tuple[float, float]:
    """Pan and tilt (rad) that point a PTU's camera at ``target``.

    Parameters
    ----------
    camera_pos : (3,) world position of the PTU base (m).
    base_xmat : (3, 3) world orientation of the PTU base (columns = base axes).
    target : (3,) world point to look at (m).

    The camera looks along the tilt link's +x; pan turns about the base z, positive tilt
    pitches the camera down (about the pan link's +y). This ignores the offsets between the
    axes and the lens (a few degrees at table distance); refine with forward kinematics.
    """
    v = base_xmat.T @ (np.asarray(target, float) - np.asarray(camera_pos, float))
    pan = float(np.arctan2(v[1], v[0]))
    tilt = float(np.arctan2(-v[2], np.hypot(v[0], v[1])))
    return pan, tilt
