"""What the gripper arm senses during a grasp: the wrist wrench and where its load acts.

A 6-axis force/torque sensor between the gripper arm's flange and the gripper measures the
wrench that everything touching the gripper applies to it (the gripper's own weight is
compensated, as a tared sensor's is). :func:`contact_wrench` sums the simulated contact
forces and torques on the gripper's geoms into that wrench about a reference point (the TCP);
:func:`load_offset` turns it into the horizontal point where the vertical load acts: where
the fingers landed on something during a descent (the load pushes up), or where the centre
of mass of an object hanging in the jaws is (the load pulls down). The skills
(:mod:`ipbench.envs.skills`) plan their retries and regrasps from these two and from the
joint encoders only; they never read an object's pose from the simulation.

The static-load method is the classical one of Atkeson, An and Hollerbach (1986,
"Estimation of inertial parameters of manipulator loads and links", IJRR 5(3)): held still, a
load's mass is ``-F_z / g`` and its centre of mass is ``r = (z x tau) / F_z`` off the
sensor's reference point. A commercial sensor of the gripper's size (ATI Mini45, SI-145-5
calibration: 1/16 N and 1/752 N m resolution, ATI datasheet) resolves a 0.2 kg load's centre
of mass to under 1 mm, so the simulated sensor is noise-free.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

__all__ = ["Wrench", "contact_wrench", "load_offset"]


@dataclass(frozen=True)
class Wrench:
    """A wrench on the gripper (world frame): ``force`` (3,) N and ``torque`` (3,) N m about
    ``point`` (3,) m."""

    force: np.ndarray
    torque: np.ndarray
    point: np.ndarray


def contact_wrench(
    model: mujoco.MjModel, data: mujoco.MjData, gripper_geoms: np.ndarray, point: np.ndarray
) -> Wrench:
    """The wrench that contacts with anything else apply to the gripper, about ``point`` (3,).

    ``gripper_geoms`` is an (ngeom,) bool mask of the gripper's geoms. MuJoCo's contact force
    (:func:`mujoco.mj_contactForce`, in the contact frame whose normal points from ``geom1``
    to ``geom2``) is what ``geom1`` applies to ``geom2``; its torsional and rolling parts are
    included (the rubber pads have torsional friction).
    """
    point = np.asarray(point, float)
    force, torque = np.zeros(3), np.zeros(3)
    f6 = np.zeros(6)
    n = data.ncon
    if n == 0:
        return Wrench(force, torque, point)
    g1, g2 = data.contact.geom1[:n], data.contact.geom2[:n]
    for i in np.flatnonzero(gripper_geoms[g1] != gripper_geoms[g2]):
        contact = data.contact[int(i)]
        mujoco.mj_contactForce(model, data, int(i), f6)
        frame = contact.frame.reshape(3, 3)
        sign = 1.0 if gripper_geoms[g2[i]] else -1.0  # on the gripper
        f = sign * (frame.T @ f6[:3])
        force += f
        torque += np.cross(contact.pos - point, f) + sign * (frame.T @ f6[3:])
    return Wrench(force, torque, point)


def load_offset(wrench: Wrench, min_force: float = 1.0) -> np.ndarray | None:
    """Horizontal offset (3,) from the wrench's point to where its vertical load acts, m.

    For a vertical force ``F_z`` acting at a horizontal offset ``r`` the torque is
    ``F_z (r x z)``, so ``r = (z x tau) / F_z``. ``None`` when the vertical load is below
    ``min_force`` (N): nothing is pressing on or hanging from the gripper.
    """
    fz = float(wrench.force[2])
    if abs(fz) < min_force:
        return None
    z = np.array([0.0, 0.0, 1.0])
    return np.cross(z, wrench.torque) / fz
