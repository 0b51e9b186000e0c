"""Lens distortion of the renders: presets against their sources, the remap against the model."""

import math

import cv2
import numpy as np
import pytest

from ipbench.envs.sensors.depth_noise import SensorError
from ipbench.envs.sensors.lens_distortion import (
    D5100_35MM,
    XTION_RGB,
    LensDistortion,
    distort_image,
    distortion_maps,
)
from ipbench.perception.calibration.target import Checkerboard, find_corners

# head: D5100 + 35 mm rendered at 1024 x 680 (f = 7308 px at 4928 px over 23.6 mm)
HEAD_SIZE = (1024, 680)
HEAD_F = 7308.0 * 1024 / 4928
HEAD_K = np.array([[HEAD_F, 0, 511.5], [0, HEAD_F, 339.5], [0, 0, 1.0]])
# wrist: the Glasgow Xtion RGB calibration at 640 x 480 (calibration_UG/xtion1_rgb_camera.yaml)
XTION_SIZE = (640, 480)
XTION_K = np.array([[540.884, 0, 322.650], [0, 539.125, 239.429], [0, 0, 1.0]])
BOARD = Checkerboard()


def pixel_model(points, k, distortion):
    """Where the lens puts ideal pixels: K distort(K^-1 p), by the model's formula."""
    xy = (np.asarray(points, float) - k[:2, 2]) / np.diag(k)[:2]
    return distortion.distort_normalized(xy) * np.diag(k)[:2] + k[:2, 2]


def checkerboard_image(k, size, rvec, tvec, pps=40, ss=4):
    """Anti-aliased ideal (pinhole) image of the board."""
    texture = BOARD.render_texture(pps)
    u0, v0 = BOARD.texture_corners_px(pps)[0]
    scale = BOARD.square_m / pps
    to_target = np.array([[scale, 0, -u0 * scale], [0, scale, -v0 * scale], [0, 0, 1.0]])
    rot, _ = cv2.Rodrigues(np.asarray(rvec, float))
    homography = k @ np.column_stack([rot[:, 0], rot[:, 1], tvec]) @ to_target
    up = np.array([[ss, 0, (ss - 1) / 2], [0, ss, (ss - 1) / 2], [0, 0, 1.0]])
    big = cv2.warpPerspective(
        texture, up @ homography, (size[0] * ss, size[1] * ss), borderValue=255
    )
    return cv2.resize(big, size, interpolation=cv2.INTER_AREA)


def test_presets_are_their_sources():
    # ug_bluerobot calibration_UG/xtion1_rgb_camera.yaml, plumb_bob (k1, k2, p1, p2, k3)
    np.testing.assert_array_equal(
        XTION_RGB.coefficients, [0.020598, -0.098738, -0.001657, 0.000591, 0.0]
    )
    # lensfun slr-nikon.xml, AF-S DX Nikkor 35mm f/1.8G at crop 1.528: PTLens a, b, c
    a, b, c = 0.003, -0.017, 0.005
    fit = LensDistortion.from_ptlens(a, b, c, focal_mm=35.0, crop_factor=1.528)
    np.testing.assert_allclose(fit.coefficients, D5100_35MM.coefficients, rtol=2e-3)
    # the Brown curve follows the PTLens curve over the DX frame to 2.4e-4 of f
    h = math.hypot(36, 24) / 1.528 / math.hypot(1.5, 1) / 2  # mm, lensfun's radius unit
    d, s = 1 - a - b - c, 35.0 / h
    r = np.linspace(1e-3, math.hypot(1.5 * h, h) / (35.0 * d), 200)
    ptlens = r * (1 + (c * s * r + b * s**2 * r**2 + a * s**3 * r**3) / d)
    brown = D5100_35MM.distort_normalized(np.stack([r, 0 * r], axis=1))[:, 0]
    assert np.abs(brown - ptlens).max() < 2.4e-4
    # barrel, -0.9 % at the middle of the long edge, -2.7 % at the corner
    for radius, percent in ((h / (35.0 * d), -0.87), (r[-1], -2.74)):
        xd = D5100_35MM.distort_normalized(np.array([[radius, 0.0]]))[0, 0]
        assert 100 * (xd / radius - 1) == pytest.approx(percent, abs=0.01)


@pytest.mark.parametrize("distortion", [D5100_35MM, XTION_RGB])
def test_model_is_opencvs(distortion):
    xy = np.random.default_rng(0).uniform(-0.4, 0.4, (50, 2))
    uv, _ = cv2.projectPoints(
        np.column_stack([xy, np.ones(50)]),
        np.zeros(3),
        np.zeros(3),
        np.eye(3),
        distortion.coefficients,
    )
    np.testing.assert_allclose(distortion.distort_normalized(xy), uv.reshape(-1, 2), atol=1e-12)


def test_zero_distortion_is_identity():
    rng = np.random.default_rng(1)
    rgb = rng.integers(0, 256, (HEAD_SIZE[1], HEAD_SIZE[0], 3), dtype=np.uint8)
    np.testing.assert_array_equal(distort_image(rgb, HEAD_K, LensDistortion()), rgb)
    depth = rng.uniform(0.5, 3.0, (480, 640)).astype(np.float32)
    out = distort_image(depth, XTION_K, LensDistortion(), interpolation=cv2.INTER_NEAREST)
    np.testing.assert_array_equal(out, depth)


@pytest.mark.parametrize(
    "k,size,distortion", [(HEAD_K, HEAD_SIZE, D5100_35MM), (XTION_K, XTION_SIZE, XTION_RGB)]
)
def test_image_corner_moves_as_the_model_says(k, size, distortion):
    map_x, map_y = distortion_maps(k, distortion, size)
    w, h = size
    for u, v in ((0, 0), (w - 1, 0), (0, h - 1), (w - 1, h - 1)):
        source = np.array([[map_x[v, u], map_y[v, u]]])
        np.testing.assert_allclose(pixel_model(source, k, distortion), [[u, v]], atol=2e-3)
    # a blob near the corner of the ideal image lands where the model says
    ideal = np.array([60.0, 45.0])
    target = pixel_model(ideal[None], k, distortion)[0]
    vv, uu = np.mgrid[0:h, 0:w]
    blob = np.exp(-((uu - ideal[0]) ** 2 + (vv - ideal[1]) ** 2) / (2 * 2.0**2)).astype(np.float32)
    out = distort_image(blob, k, distortion).astype(np.float64)
    win = (np.abs(uu - target[0]) < 12) & (np.abs(vv - target[1]) < 12)
    centroid = np.array([(out * uu)[win].sum(), (out * vv)[win].sum()]) / out[win].sum()
    assert np.linalg.norm(centroid - target) < 0.05
    if distortion is D5100_35MM:
        assert np.linalg.norm(target - ideal) > 5  # barrel: pulled towards the centre
        assert (target > ideal).all()


@pytest.mark.parametrize(
    "k,size,distortion,pose",
    [
        (HEAD_K, HEAD_SIZE, D5100_35MM, ((0.1, -0.15, 0.05), (-0.095, -0.062, 0.33))),
        (XTION_K, XTION_SIZE, XTION_RGB, ((-0.1, 0.1, 0.0), (-0.1, -0.063, 0.235))),
    ],
)
def test_undistort_restores_the_ideal_image(k, size, distortion, pose):
    """The round trip: distort, then cv2.undistort with the same K and coefficients."""
    ideal = checkerboard_image(k, size, *pose)
    distorted = distort_image(ideal, k, distortion)
    restored = cv2.undistort(distorted, k, distortion.coefficients)
    truth = find_corners(ideal, BOARD)
    seen = find_corners(distorted, BOARD)
    back = find_corners(restored, BOARD)
    assert truth is not None and seen is not None and back is not None
    assert np.linalg.norm(back - truth, axis=1).max() < 0.5
    # and the distorted corners are where the model puts the ideal ones
    assert np.linalg.norm(seen - pixel_model(truth, k, distortion), axis=1).max() < 0.5
    if distortion is D5100_35MM:
        assert np.linalg.norm(seen - truth, axis=1).max() > 5  # not a trivial pass


def test_depth_keeps_its_values_with_nearest():
    depth = np.full((480, 640), 2.0, np.float32)
    depth[150:330, 200:440] = 1.0  # a box in front of a wall
    depth[:, :40] = 0.0  # missing returns
    nearest = distort_image(depth, XTION_K, XTION_RGB, interpolation=cv2.INTER_NEAREST)
    assert set(np.unique(nearest)) <= {0.0, 1.0, 2.0}
    linear = distort_image(depth, XTION_K, XTION_RGB)
    blended = (linear > 0) & (linear != 1.0) & (linear != 2.0)
    assert blended.any()  # what nearest-neighbour avoids


def test_wider_render_fills_the_corners():
    margin = 24
    wide_k = HEAD_K + np.array([[0, 0, margin], [0, 0, margin], [0, 0, 0]])
    w, h = HEAD_SIZE
    ones = np.ones((h, w), np.float32)
    plain = distort_image(ones, HEAD_K, D5100_35MM)
    assert plain[0, 0] == 0 and plain[h // 2, w // 2] == 1  # barrel: no source at the corners
    wide = np.ones((h + 2 * margin, w + 2 * margin), np.float32)
    filled = distort_image(wide, HEAD_K, D5100_35MM, ideal_K=wide_k, size=HEAD_SIZE)
    assert filled.shape == (h, w) and (filled == 1).all()
    # same scene, same output where both renders have it
    vv, uu = np.mgrid[0 : h + 2 * margin, 0 : w + 2 * margin]
    scene = (np.sin(uu / 7.0) * np.cos(vv / 5.0)).astype(np.float32)  # smooth: remap's 1/32 px
    a = distort_image(scene, HEAD_K, D5100_35MM, ideal_K=wide_k, size=HEAD_SIZE)
    b = distort_image(scene[margin:-margin, margin:-margin], HEAD_K, D5100_35MM)
    np.testing.assert_allclose(a[100:-100, 100:-100], b[100:-100, 100:-100], atol=0.01)


def test_maps_are_cached_and_read_only():
    first = distortion_maps(XTION_K, XTION_RGB, XTION_SIZE)
    again = distortion_maps(XTION_K.copy(), LensDistortion(*XTION_RGB.coefficients), (640, 480))
    assert first[0] is again[0] and first[1] is again[1]
    assert first[0].dtype == np.float32 and first[0].shape == (480, 640)
    with pytest.raises(ValueError):
        first[0][0, 0] = 1.0
    other = distortion_maps(XTION_K, LensDistortion(k1=-0.1), XTION_SIZE)
    assert other[0] is not first[0] and not np.array_equal(other[0], first[0])


def test_bad_input_raises():
    image = np.zeros((480, 640), np.uint8)
    with pytest.raises(SensorError, match="camera matrix"):
        distort_image(image, np.eye(2), XTION_RGB)
    skewed = XTION_K.copy()
    skewed[0, 1] = 1.0
    with pytest.raises(SensorError, match="no skew"):
        distort_image(image, skewed, XTION_RGB)
    with pytest.raises(SensorError, match="INTER_NEAREST"):
        distort_image(image, XTION_K, XTION_RGB, interpolation=cv2.INTER_AREA)
    with pytest.raises(SensorError, match="dtype"):
        distort_image(image.astype(bool), XTION_K, XTION_RGB)
    with pytest.raises(SensorError, match="finite"):
        LensDistortion(k1=float("nan"))
    with pytest.raises(SensorError, match="width, height"):
        distortion_maps(XTION_K, XTION_RGB, (640.5, 480))
    with pytest.raises(SensorError, match="folds back"):  # r_d(r) turns back inside the image
        distortion_maps(XTION_K, LensDistortion(k1=-3.0), XTION_SIZE)
    with pytest.raises(SensorError, match="radius 0.74"):  # the D5100 lens on a wide camera
        distortion_maps(XTION_K, D5100_35MM, XTION_SIZE)
