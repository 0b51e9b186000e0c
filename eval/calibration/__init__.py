"""The robot calibrating its cameras (thesis ch. 4): ``ipbench calibrate``, ``ipbench eval
calibration`` (``evaluate``), the hand-eye study, the reconstruction of the board by the head
and by the wrist camera, and their commands.
"""
