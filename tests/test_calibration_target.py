"""The checkerboard target: geometry, texture, and corners found in synthetic perspective views."""

import cv2
import numpy as np
import pytest

from ipbench.perception.calibration.errors import CalibrationError
from ipbench.perception.calibration.target import (
    Checkerboard,
    board_in_view,
    board_outline,
    find_corners,
)

BOARD = Checkerboard()
W, H = 640, 480
K = np.array([[540.884, 0.0, 322.650], [0.0, 539.125, 239.429], [0.0, 0.0, 1.0]])  # Xtion RGB
PPS = 40  # texture px per square
SS = 4  # supersampling of the synthetic views


def view(board, rvec, tvec, k=K, size=(W, H), pps=PPS):
    """Anti-aliased pinhole image of the board's texture and the true corner positions (px)."""
    texture = board.render_texture(pps)
    rot, _ = cv2.Rodrigues(np.asarray(rvec, np.float64))
    u0, v0 = board.texture_corners_px(pps)[0]  # texture px -> target frame (m)
    scale = board.square_m / pps
    to_target = np.array([[scale, 0.0, -u0 * scale], [0.0, scale, -v0 * scale], [0.0, 0.0, 1.0]])
    homography = k @ np.column_stack([rot[:, 0], rot[:, 1], tvec]) @ to_target
    # output pixel u covers supersampled pixels SS u .. SS u + SS - 1, centred at SS u + (SS-1)/2
    up = np.array([[SS, 0.0, (SS - 1) / 2], [0.0, SS, (SS - 1) / 2], [0.0, 0.0, 1.0]])
    big = cv2.warpPerspective(
        texture,
        up @ homography,
        (size[0] * SS, size[1] * SS),
        flags=cv2.INTER_LINEAR,
        borderValue=128,
    )
    image = cv2.resize(big, size, interpolation=cv2.INTER_AREA)
    truth, _ = cv2.projectPoints(board.object_points(), np.asarray(rvec, float), tvec, k, None)
    return image, truth.reshape(-1, 2)


def test_object_points_are_the_board_grid():
    pts = BOARD.object_points()
    assert pts.shape == (54, 3) and pts.dtype == np.float64
    assert BOARD.square_m == 0.024  # the thesis' 24 mm squares
    np.testing.assert_array_equal(pts[0], [0, 0, 0])
    np.testing.assert_allclose(pts[1], [0.024, 0, 0])  # along a row first
    np.testing.assert_allclose(pts[9], [0, 0.024, 0])
    np.testing.assert_allclose(pts[-1], [8 * 0.024, 5 * 0.024, 0])
    assert not pts[:, 2].any()
    np.testing.assert_allclose(BOARD.size_m, (12 * 0.024, 9 * 0.024))


def test_texture_pattern_and_corners():
    tex = BOARD.render_texture(10)
    assert tex.dtype == np.uint8 and tex.shape == BOARD.texture_shape(10) == (90, 120)
    assert set(np.unique(tex)) == {0, 255}
    assert (tex[:10] == 255).all() and (tex[:, -10:] == 255).all()  # white margin
    assert tex[15, 15] == 0  # square (0, 0) black
    assert tex[15, 25] == 255 and tex[25, 15] == 255 and tex[25, 25] == 0
    uv = BOARD.texture_corners_px(10)
    np.testing.assert_allclose(uv[0], [19.5, 19.5])  # between pixels 19 and 20
    np.testing.assert_allclose(uv[-1], [99.5, 69.5])
    # the texture spans the board at true scale: px per metre equal on both axes
    assert tex.shape[1] / BOARD.size_m[0] == pytest.approx(tex.shape[0] / BOARD.size_m[1])


POSES = [
    ((0.0, 0.0, 0.0), (-0.10, -0.06, 0.55)),
    ((0.35, -0.25, 0.1), (-0.09, -0.07, 0.6)),
    ((-0.3, 0.4, -0.5), (-0.08, -0.05, 0.7)),
    ((0.1, 0.2, np.pi), (0.10, 0.06, 0.6)),  # half a turn in the image plane
]


@pytest.mark.parametrize("rvec,tvec", POSES)
def test_corners_found_within_0_2_px(rvec, tvec):
    image, truth = view(BOARD, rvec, tvec)
    corners = find_corners(image, BOARD)
    assert corners is not None and corners.shape == (54, 2) and corners.dtype == np.float64
    err = np.linalg.norm(corners - truth, axis=1)
    assert err.max() < 0.2, err.max()


def test_rgb_input_and_classic_fallback_agree(monkeypatch):
    image, truth = view(BOARD, (0.2, -0.3, 0.2), (-0.1, -0.06, 0.6))
    rgb = np.repeat(image[:, :, None], 3, axis=2)
    assert np.linalg.norm(find_corners(rgb, BOARD) - truth, axis=1).max() < 0.2
    # without the SB detector: findChessboardCorners + cornerSubPix, in the same order
    monkeypatch.setattr(cv2, "findChessboardCornersSB", lambda *a, **k: (False, None))
    corners = find_corners(image, BOARD)
    assert corners is not None
    assert np.linalg.norm(corners - truth, axis=1).max() < 0.2


def test_order_is_the_boards_whatever_the_detector_returns(monkeypatch):
    image, truth = view(BOARD, (0.1, 0.1, 0.3), (-0.1, -0.05, 0.6))
    grid = truth.reshape(6, 9, 2)
    orders = [grid[::-1, ::-1], grid[::-1], grid[:, ::-1], grid]  # half turn, both mirrors
    for order in orders:
        fake = order.reshape(-1, 1, 2).astype(np.float32)
        monkeypatch.setattr(cv2, "findChessboardCornersSB", lambda *a, f=fake, **k: (True, f))
        corners = find_corners(image, BOARD)
        assert np.linalg.norm(corners - truth, axis=1).max() < 0.2


def test_not_found_gives_none():
    assert find_corners(np.full((H, W), 200, np.uint8), BOARD) is None
    image, _ = view(BOARD, (0.0, 0.0, 0.0), (-0.10, -0.06, 0.55))
    assert find_corners(image, Checkerboard(cols=7, rows=4)) is None  # wrong board


def test_bad_input_raises():
    with pytest.raises(CalibrationError, match="odd sum"):
        Checkerboard(cols=8, rows=6)
    with pytest.raises(CalibrationError, match="cols"):
        Checkerboard(cols=2, rows=5)
    with pytest.raises(CalibrationError, match="square_m"):
        Checkerboard(square_m=-0.024)
    with pytest.raises(CalibrationError, match="px_per_square"):
        BOARD.render_texture(2)
    with pytest.raises(CalibrationError, match="uint8"):
        find_corners(np.zeros((H, W), np.float32), BOARD)
    with pytest.raises(CalibrationError, match="RGB"):
        find_corners(np.zeros((H, W, 4), np.uint8), BOARD)
    with pytest.raises(CalibrationError, match="Checkerboard"):
        find_corners(np.zeros((H, W), np.uint8), (9, 6))


@pytest.mark.parametrize("u_first", [6.0, 30.0])
def test_a_board_cut_by_the_image_border_is_not_in_view(u_first):
    # the same frontal board, first inside the image, then moved left until the border cuts
    # its outer squares or its white margin while every inner corner stays in the image
    image, truth = view(BOARD, *POSES[0])
    assert board_in_view(find_corners(image, BOARD), BOARD, (H, W))
    z = POSES[0][1][2]
    x = (u_first - K[0, 2]) * z / K[0, 0]  # the first corner u_first px from the left border
    image, truth = view(BOARD, POSES[0][0], (x, POSES[0][1][1], z))
    assert truth[:, 0].min() == pytest.approx(u_first, abs=0.01)
    assert not board_in_view(truth, BOARD, (H, W))
    corners = find_corners(image, BOARD)
    if corners is not None:  # found anyway (the planted bad view): flagged
        assert not board_in_view(corners, BOARD, (H, W))


def test_board_in_view_needs_the_boards_corners():
    with pytest.raises(CalibrationError, match="54 finite"):
        board_in_view(np.zeros((10, 2)), BOARD, (H, W))


def test_board_outline_spans_the_printed_board():
    _, truth = view(BOARD, *POSES[0])  # frontal: px per metre is f / z on both axes
    outline = board_outline(truth, BOARD)
    px_per_m = K[0, 0] / POSES[0][1][2]
    width, height = np.ptp(outline[:, 0]), np.ptp(outline[:, 1])
    assert width == pytest.approx(BOARD.size_m[0] * px_per_m, rel=2e-3)
    assert height == pytest.approx(BOARD.size_m[1] * px_per_m * K[1, 1] / K[0, 0], rel=2e-3)


def test_a_corner_found_off_the_boards_plane_is_told_from_detection_noise():
    from ipbench.perception.calibration.target import PLANAR_PX, planar_residual_px

    board = Checkerboard()
    K = np.array([[1519.0, 0.0, 511.5], [0.0, 1519.0, 339.5], [0.0, 0.0, 1.0]])
    dist = np.array([-0.1, 0.08, 0.0, 0.0, 0.0])
    rvec, tvec = np.array([0.3, -0.2, 0.1]), np.array([-0.1, -0.05, 1.5])
    corners, _ = cv2.projectPoints(board.object_points(), rvec, tvec, K, dist)
    corners = corners.reshape(-1, 2)
    assert planar_residual_px(corners, board, K, dist) < 1e-3  # exact: a homography, undistorted
    noisy = corners + np.random.default_rng(0).normal(0.0, 0.05, corners.shape)
    assert planar_residual_px(noisy, board, K, dist) < PLANAR_PX
    moved = corners.copy()
    moved[14] += [2.5, -1.0]  # one corner on the wrong edge
    assert planar_residual_px(moved, board, K, dist) > PLANAR_PX
    # the lens bends the plane's image: without undistortion the exact corners look off it
    assert planar_residual_px(corners, board, K, None) > planar_residual_px(corners, board, K, dist)
