"""Stereo: triangulation accuracy with the head's baseline, epipolar checks, hypothesis pairing.

Pure geometry: known 3-D points projected by known cameras with 0.5 px noise.
"""

from __future__ import annotations

import numpy as np
import pytest

from ipbench.perception.features2d import ActiveVisionError, Features
from ipbench.perception.recognition import Hypothesis
from ipbench.perception.stereo import (
    StereoRig,
    hypothesis_position,
    match_hypotheses,
    projection_matrix,
)

BASELINE = 0.29  # the head's calibrated ~0.288 m (CloPeMa calibration_UG)
# 18 mm (the kit lens' wide end, the worst depth resolution) on the D5100's 23.6 mm sensor,
# 1024 px wide: 18 / 23.6 * 1024 = 781 px
F_PX = 781.0
K = np.array([[F_PX, 0, 511.5], [0, F_PX, 339.5], [0, 0, 1.0]])


def look_at(eye, target) -> np.ndarray:
    """World-from-camera pose (OpenCV axes) at ``eye`` looking at ``target``, world z up."""
    z = np.asarray(target, float) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, (0.0, 0.0, 1.0))
    x /= np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([x, np.cross(z, x), z], 1)
    pose[:3, 3] = eye
    return pose


def head(distance: float) -> tuple[StereoRig, np.ndarray]:
    """A head 1.0 m above the table verged on a point ``distance`` away; and that point."""
    target = np.array(
        [0.2, distance * np.cos(np.deg2rad(25)), 1.0 - distance * np.sin(np.deg2rad(25))]
    )
    left_eye = np.array([-BASELINE / 2, 0.0, 1.0])
    right_eye = np.array([BASELINE / 2, 0.0, 1.0])
    target = left_eye + (target - left_eye) / np.linalg.norm(target - left_eye) * distance
    return StereoRig(K, look_at(left_eye, target), K, look_at(right_eye, target)), target


def project(K: np.ndarray, pose: np.ndarray, points: np.ndarray) -> np.ndarray:
    uvw = np.hstack([points, np.ones((len(points), 1))]) @ projection_matrix(K, pose).T
    return uvw[:, :2] / uvw[:, 2:]


def triangulation_errors(distance: float, n: int = 400, seed: int = 0) -> np.ndarray:
    rig, target = head(distance)
    rng = np.random.default_rng(seed)
    points = target + rng.uniform(-0.1, 0.1, (n, 3))
    xl = project(rig.K_left, rig.pose_left, points) + rng.normal(0, 0.5, (n, 2))
    xr = project(rig.K_right, rig.pose_right, points) + rng.normal(0, 0.5, (n, 2))
    return np.linalg.norm(rig.triangulate(xl, xr) - points, axis=1)


def test_triangulation_is_within_a_centimetre_at_one_metre_and_degrades_with_depth():
    near = triangulation_errors(1.0)
    # 18 mm lens, 0.5 px noise: 2 mm median; the rare worst points (> 99th percentile) of
    # ill-conditioned geometry may pass 1 cm
    assert np.percentile(near, 99) < 0.01
    far = triangulation_errors(2.3)
    # the error is mostly depth error, sigma_z = z^2 sigma_d / (f b) with the disparity noise
    # sigma_d = sqrt(2) 0.5 px; the median of |N(0, sigma)| is 0.674 sigma
    for errors, z in ((near, 1.0), (far, 2.3)):
        expected = 0.674 * z**2 * np.sqrt(2) * 0.5 / (F_PX * BASELINE)
        assert 0.7 * expected < np.median(errors) < 1.4 * expected
    # at the table (2.3 m) the 18 mm lens gives about 11 mm median, 3 cm at the 95th percentile
    assert np.median(far) < 0.015 and np.percentile(far, 95) < 0.04


def test_projection_and_epipolar_geometry_are_consistent():
    rig, target = head(1.5)
    assert rig.baseline == pytest.approx(BASELINE)
    np.testing.assert_allclose(project(K, rig.pose_left, target[None]), [[511.5, 339.5]], atol=1e-9)
    rng = np.random.default_rng(1)
    points = target + rng.uniform(-0.3, 0.3, (50, 3))
    xl, xr = project(K, rig.pose_left, points), project(K, rig.pose_right, points)
    assert rig.epipolar_distance(xl, xr).max() < 1e-6
    np.testing.assert_allclose(rig.triangulate(xl, xr), points, atol=1e-9)
    assert np.all(rig.depths(points) > 0)
    # a right point moved off its epipolar line (here ~vertical to it) is far from it
    assert rig.epipolar_distance(xl[:1], xr[:1] + (0.0, 25.0))[0] > 20.0
    with pytest.raises(ActiveVisionError, match="4, 4"):
        StereoRig(K, np.eye(3), K, np.eye(4))


def test_a_rig_with_lenses_undistorts_before_its_geometry():
    """Pixels seen through each camera's lens (``cv2.projectPoints`` with its distortion)
    triangulate back exactly and lie on their epipolar lines when the rig knows the lenses;
    a pinhole rig given the same pixels is millimetres off."""
    import cv2

    rig, target = head(1.5)
    lenses = (np.array([-0.08, 0.12, 0.001, -0.002, 0.0]), np.array([-0.05, 0.09, 0, 0, 0.0]))
    rng = np.random.default_rng(2)
    points = target + rng.uniform(-0.3, 0.3, (50, 3))
    seen = []
    for pose, dist in zip((rig.pose_left, rig.pose_right), lenses, strict=True):
        rvec = cv2.Rodrigues(pose[:3, :3].T)[0]
        tvec = -pose[:3, :3].T @ pose[:3, 3]
        seen.append(cv2.projectPoints(points, rvec, tvec, K, dist)[0].reshape(-1, 2))
    lensed = StereoRig(K, rig.pose_left, K, rig.pose_right, *lenses)
    np.testing.assert_allclose(lensed.triangulate(*seen), points, atol=1e-6)
    assert lensed.epipolar_distance(*seen).max() < 1e-4
    assert np.abs(rig.triangulate(*seen) - points).max() > 0.003
    zeros = StereoRig(K, rig.pose_left, K, rig.pose_right, np.zeros(5), np.zeros(5))
    assert zeros.dist_left is None  # zeros are a pinhole: the geometry is untouched
    np.testing.assert_array_equal(zeros.triangulate(*seen), rig.triangulate(*seen))
    with pytest.raises(ActiveVisionError, match="dist_left"):
        StereoRig(K, rig.pose_left, K, rig.pose_right, np.zeros(4))


def _hypothesis(name: str, centre: np.ndarray, indices=None) -> Hypothesis:
    indices = np.zeros(0, np.int64) if indices is None else indices
    outline = centre + np.array([[-40.0, -30], [40, -30], [40, 30], [-40, 30]])
    return Hypothesis(name, centre, outline, max(len(indices), 10), 0.5, indices, 0, np.eye(3))


def test_same_class_instances_side_by_side_pair_up_with_the_vergence_disparity():
    rig, target = head(2.3)
    objects = {
        "tea_a": ("tea", target),
        "tea_b": ("tea", target + (0.2, 0.0, 0.0)),  # side by side along the baseline
        "soap": ("soap", target + (-0.1, 0.3, 0.0)),
        "lost": ("soap", target + (0.0, -0.3, 0.0)),  # seen by the left camera only
    }
    left = [_hypothesis(c, project(K, rig.pose_left, p[None])[0]) for c, p in objects.values()]
    right_order = ["soap", "tea_b", "tea_a"]
    right = [
        _hypothesis(objects[k][0], project(K, rig.pose_right, objects[k][1][None])[0] + 0.7)
        for k in right_order
    ]
    disparity = right[2].centre[0] - left[0].centre[0]  # vergence on tea_a
    pairs = match_hypotheses(left, right, rig, expected_disparity=disparity)
    assert pairs == [(0, 2), (1, 1), (2, 0)]
    for i, j in pairs:
        position = hypothesis_position(left[i], right[j], rig)
        assert np.linalg.norm(position - list(objects.values())[i][1]) < 0.03
    # without the vergence disparity the two teas are ambiguous along the epipolar line, but
    # classes never mix and nothing is paired twice
    loose = match_hypotheses(left, right, rig)
    assert len({j for _, j in loose}) == len(loose) == 3
    assert all(left[i].class_name == right[j].class_name for i, j in loose)
    assert match_hypotheses(left, [], rig) == []


def test_position_from_inlier_matches_is_the_median_of_triangulated_points():
    rig, target = head(1.0)
    rng = np.random.default_rng(2)
    n = 60
    points = target + rng.uniform(-0.05, 0.05, (n, 3))
    descriptors = rng.random((n, 128)).astype(np.float32)

    def features(pose, order):
        xy = (project(K, pose, points) + rng.normal(0, 0.5, (n, 2)))[order].astype(np.float32)
        ones = np.ones(n, np.float32)
        return Features("sift", xy, ones, ones, ones, descriptors[order])

    order = rng.permutation(n)
    fl, fr = features(rig.pose_left, np.arange(n)), features(rig.pose_right, order)
    left = _hypothesis("tea", fl.xy.mean(0).astype(float), np.arange(n))
    # a right centre 30 px off: the inlier matches, not the centres, give the position
    right = _hypothesis("tea", fr.xy.mean(0).astype(float) + (30.0, 0.0), np.arange(n))
    position = hypothesis_position(left, right, rig, fl, fr)
    assert np.linalg.norm(position - np.median(points, axis=0)) < 0.01
    from_centres = hypothesis_position(left, right, rig)
    assert np.linalg.norm(from_centres - target) > 0.02
