"""Proprioception: where the gripper is, from the joint positions in the observation.

The policies see the robot only through ``observation["qpos"]`` (joint order
:data:`~ipbench.envs.sorting.ROBOT_JOINTS`); forward kinematics on the kinematic work-cell
model (no objects, no simulator state) gives the tool-centre-point pose that in-hand
segmentation needs, as a real robot's ``/tf`` would.
"""

from __future__ import annotations

import mujoco
import numpy as np

from ipbench.assets.compose import GRIPPER_ARM
from ipbench.envs.robot import ik_model
from ipbench.envs.sorting import ROBOT_JOINTS

__all__ = ["HandKinematics", "TCP_SITE"]

TCP_SITE = f"{GRIPPER_ARM}_gripper_tcp"
"""The gripper's tool centre point: between the pads' centres."""


class HandKinematics:
    """Forward kinematics of the gripper arm from observed joint positions."""

    def __init__(self) -> None:
        self.model = ik_model()
        self.data = mujoco.MjData(self.model)
        m = self.model
        self._qadr = np.array([m.jnt_qposadr[m.joint(j).id] for j in ROBOT_JOINTS])
        self._site = m.site(TCP_SITE).id
        self._finger = ROBOT_JOINTS.index(f"{GRIPPER_ARM}_gripper_finger_a")

    def _check(self, qpos: np.ndarray) -> np.ndarray:
        q = np.asarray(qpos, dtype=float)
        if q.shape != (len(ROBOT_JOINTS),) or not np.all(np.isfinite(q)):
            raise ValueError(
                f"qpos must be {len(ROBOT_JOINTS)} finite joint positions in the order of "
                f"ROBOT_JOINTS (observation['qpos']), got shape {q.shape}"
            )
        return q

    def tcp_pose(self, qpos: np.ndarray) -> np.ndarray:
        """(4, 4) world-from-TCP transform (m) for the joint positions ``qpos``."""
        self.data.qpos[self._qadr] = self._check(qpos)
        mujoco.mj_kinematics(self.model, self.data)
        pose = np.eye(4)
        pose[:3, :3] = self.data.site_xmat[self._site].reshape(3, 3)
        pose[:3, 3] = self.data.site_xpos[self._site]
        return pose

    def jaw_opening(self, qpos: np.ndarray) -> float:
        """Distance between the pads (m): twice the driven finger's travel."""
        return 2.0 * float(self._check(qpos)[self._finger])
