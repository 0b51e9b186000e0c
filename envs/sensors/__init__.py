"""The work cell's simulated sensors: cameras, depth noise and lenses.

:mod:`~ipbench.envs.sensors.cameras` renders RGB, metric depth and segmentation from any
MjModel's cameras and gives their intrinsics and poses; :mod:`~ipbench.envs.sensors.depth_noise`
turns ideal depth into what an RGB-D sensor reports, with the projector and matcher effects of
:mod:`~ipbench.envs.sensors.structured_light` (their fused array kernels:
``ipbench.envs.sensors._kernels``); :mod:`~ipbench.envs.sensors.lens_distortion` bends pinhole
renders through a real lens. The package re-exports the camera names, e.g.
``from ipbench.envs.sensors import SensorRenderer, camera_pose, intrinsics``.
"""

from ipbench.envs.sensors.cameras import (
    CameraIntrinsics,
    RgbdCamera,
    SensorError,
    SensorRenderer,
    camera_id,
    camera_pose,
    fit_offscreen,
    intrinsics,
    specular_geoms,
)

__all__ = [
    "CameraIntrinsics",
    "RgbdCamera",
    "SensorError",
    "SensorRenderer",
    "camera_id",
    "camera_pose",
    "fit_offscreen",
    "intrinsics",
    "specular_geoms",
]
