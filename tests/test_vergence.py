"""Vergence: the peak disparity of synthetic stereo pairs and the pan turn that zeroes it."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from test_features2d import textured_patch

from ipbench.perception.features2d import ActiveVisionError, detect
from ipbench.perception.vergence import (
    fixations_agree,
    pan_angle,
    pan_correction,
    peak_disparity,
)

W, H = 1024, 680
K = np.array([[1518.0, 0.0, (W - 1) / 2], [0.0, 1518.0, (H - 1) / 2], [0.0, 0.0, 1.0]])
# 1518 px: a 35 mm lens on the D5100's 23.6 mm sensor at 1024 px width


def texture(rows: int = 9, cols: int = 10, seed: int = 100) -> np.ndarray:
    """A wall of distinct textured patches, (160 rows, 200 cols) each."""
    return np.vstack(
        [np.hstack([textured_patch(seed + r * cols + c) for c in range(cols)]) for r in range(rows)]
    )


def shifted(image: np.ndarray, dx: float) -> np.ndarray:
    return cv2.warpAffine(image, np.float64([[1, 0, dx], [0, 1, 0]]), (image.shape[1], H))


@pytest.fixture(scope="module")
def wall():
    return texture()


def test_global_and_selective_vergence_find_the_known_disparities(wall):
    left = wall[:H, :W].copy()
    right = shifted(left, -23.4)  # the background: x_right = x_left - 23.4 px
    box = textured_patch(7)  # an object nearer the head: x_right = x_left - 61.7 px
    x0, y0 = 600, 300
    left[y0 : y0 + 160, x0 : x0 + 200] = box
    patch_right = cv2.warpAffine(box, np.float64([[1, 0, 0.3], [0, 1, 0]]), (200, 160))
    right[y0 : y0 + 160, x0 - 62 : x0 - 62 + 200] = patch_right
    fl, fr = detect(left, "sift"), detect(right, "sift")
    whole = peak_disparity(fl, fr)
    assert whole is not None and abs(whole.disparity - -23.4) < 1.0
    assert abs(whole.row_offset) < 1.0 and whole.support >= 50
    roi = (x0 + 10, y0 + 10, x0 + 190, y0 + 150)
    attended = peak_disparity(fl, fr, roi=roi)
    assert attended is not None and abs(attended.disparity - -61.7) < 1.0
    # the left keypoints used lie in the ROI
    xy = fl.xy[attended.matches[attended.peak, 0]]
    assert np.all((xy[:, 0] >= roi[0]) & (xy[:, 0] <= roi[2]))
    # nothing to verge on in an empty region
    assert peak_disparity(fl, fr, roi=(0, 0, 1, 1)) is None


def _rotation_y(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _render(wall: np.ndarray, pose: np.ndarray, depth: float, px_per_m: float) -> np.ndarray:
    """The camera's image of ``wall`` on the plane z = depth of the world (left camera) frame."""
    th, tw = wall.shape
    A = np.array([[1 / px_per_m, 0, -tw / 2 / px_per_m], [0, 1 / px_per_m, -th / 2 / px_per_m],
                  [0, 0, depth]])  # fmt: skip
    A[:, 2] -= pose[:3, 3]
    homography = K @ pose[:3, :3].T @ A
    return cv2.warpPerspective(wall, homography, (W, H), flags=cv2.INTER_LINEAR)


def _project(pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    camera = (points - pose[:3, 3]) @ pose[:3, :3]
    uvw = camera @ K.T
    return uvw[:, :2] / uvw[:, 2:]


def test_vergence_iterations_converge_below_two_pixels(wall):
    depth, baseline = 1.5, 0.29  # the head's ~0.29 m baseline (CloPeMa calibration_UG)
    left_pose = np.eye(4)
    right_pose = np.eye(4)
    right_pose[:3, 3] = (baseline, 0.0, 0.0)
    left = _render(wall, left_pose, depth, 1100.0)
    fl = detect(left, "sift")
    history = []
    for _ in range(4):
        right = _render(wall, right_pose, depth, 1100.0)
        vergence = peak_disparity(fl, detect(right, "sift"))
        assert vergence is not None
        history.append(vergence.disparity)
        if abs(vergence.disparity) < 2.0:
            break
        turn = pan_correction(vergence, K)
        right_pose[:3, :3] = right_pose[:3, :3] @ _rotation_y(turn)
    assert abs(history[0]) > 250  # parallel cameras: f b / z = 293 px
    assert abs(history[-1]) < 2.0 and len(history) <= 3
    # the truth: the peak's left keypoints, on the plane, project to the right image there
    xy = fl.xy[vergence.matches[vergence.peak, 0]].astype(float)
    rays = np.linalg.solve(K, np.vstack([xy.T, np.ones(len(xy))])).T
    true_right = _project(right_pose, rays * depth / rays[:, 2:])
    assert abs(np.median(true_right[:, 0] - xy[:, 0])) < 2.0


def test_pan_angles_and_fixation_agreement():
    cx, fx = K[0, 2], K[0, 0]
    assert pan_angle(cx, K) == 0.0
    assert pan_angle(cx + fx, K) == pytest.approx(np.pi / 4)
    with pytest.raises(ActiveVisionError, match="3x3"):
        pan_angle(0.0, np.eye(2))
    assert fixations_agree(np.array([500.0, 300.0]), np.array([480.0, 302.0]), disparity=-20.0)
    assert not fixations_agree(np.array([500.0, 300.0]), np.array([450.0, 300.0]))
    with pytest.raises(ActiveVisionError, match="bin_px"):
        peak_disparity(detect(textured_patch(1), "orb"), detect(textured_patch(1), "orb"), bin_px=0)
