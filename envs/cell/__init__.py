"""The simulated cell as the robot knows it: how the true cell differs from its nominal model
(:mod:`~ipbench.envs.cell.model_errors`), what the robot believes of its cameras
(:mod:`~ipbench.envs.cell.extrinsics`, the envs' ``extrinsics`` option) and the calibration
file those beliefs can come from (:mod:`~ipbench.envs.cell.calibration_file`).
"""

__all__: list[str] = []
