"""Camera and hand-eye calibration of the CloPeMa cell (thesis ch. 4), with OpenCV 4.x.

Pure functions of images, target models, robot poses and camera poses; the routine that moves
the simulated robot and captures the data is the evaluation's (``ipbench calibrate``).

- :mod:`.target`: the 24 mm checkerboard (9x6 inner corners) and its corner detection;
- :mod:`.intrinsics`: ``cv2.calibrateCamera`` (K, Brown-Conrady distortion, reprojection);
- :mod:`.hand_eye`: ``AX = XB`` with the five methods of ``cv2.calibrateHandEye`` and
  ``cv2.calibrateRobotWorldHandEye``, eye-in-hand and eye-to-hand, degenerate motions refused;
- :mod:`.stereo_extrinsics`: the head's right-from-left transform by the thesis' eq. 4.7,
  refined by bundle adjustment;
- :mod:`.dynamic`: the left camera's pose after a PTU move from tracked features (§4.4.4);
- :mod:`.consistency`: which candidate stereo pair the images' epipolar geometry supports;
- :mod:`.poses`: 4x4 transform helpers; :mod:`.errors`: the family's root exception.
"""
