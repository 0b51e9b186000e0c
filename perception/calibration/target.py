"""The checkerboard calibration target (thesis ch. 4: 24 mm squares) and its corner detector.

Geometry. The board has ``cols x rows`` *inner* corners, i.e. ``(cols + 1) x (rows + 1)``
squares of side ``square_m``, inside a white margin. The target frame has its origin at the
first inner corner, x along a row (``cols`` corners), y along a column (``rows`` corners) and z
into the board (OpenCV's convention: seen from the front, x right and y down give z away from
the camera). Corner ``k = j * cols + i`` sits at ``(i, j, 0) * square_m``. Square ``(sx, sy)``
(``sx`` in ``0..cols``, ``sy`` in ``0..rows``; square ``(0, 0)`` is the outer one diagonal to
corner 0) is black when ``sx + sy`` is even.

Why 9 x 6 inner corners by default: a board whose inner-corner counts have an odd sum looks
different after a half turn (every square changes colour), so the corner order is
unambiguous; 9 x 6 (10 x 7 squares, 240 x 168 mm at 24 mm, with the margin 288 x 216 mm) is
the count of OpenCV's own calibration sample pattern and is small enough for a gripper to hold
in front of the head cameras and of the wrist Xtion. Even sums (8 x 6, 7 x 7) are refused.

Detection (:func:`find_corners`): ``cv2.findChessboardCornersSB`` (normalised, exhaustive),
falling back to ``cv2.findChessboardCorners`` (adaptive threshold, normalised); either way the
corners are refined by ``cv2.cornerSubPix`` (half window a third of the smallest corner
spacing, 2-11 px). The refinement is there because on small squares it is the more accurate:
on anti-aliased synthetic 640 x 480 views with 15-25 px squares, SB's own sub-pixel positions
(``CALIB_CB_ACCURACY``) were off by up to 0.5 px, after ``cornerSubPix`` by at most 0.15 px
(tests/test_calibration_target.py's views). Then the order is made the board's own: the
detectors may start at another corner of the grid, so corners are re-ordered to a
right-handed grid (the board seen from its front) whose square colours match the pattern
above.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ipbench.perception.calibration.errors import CalibrationError

__all__ = [
    "DEFAULT_SQUARE_M",
    "PLANAR_PX",
    "Checkerboard",
    "board_in_view",
    "board_outline",
    "find_corners",
    "planar_residual_px",
]

DEFAULT_SQUARE_M = 0.024  # m; the thesis' checkerboard squares (ch. 4, 24 mm)
PLANAR_PX = 1.0
"""Bound on :func:`planar_residual_px` for a view to be measured: five times the largest
residual of correctly found corners (0.2 px), a twentieth of a square at the head's 1.5 m."""
_SB_FLAGS = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE
_CLASSIC_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)


@dataclass(frozen=True)
class Checkerboard:
    """A planar checkerboard target.

    cols, rows : inner corners along a row (target x) and along a column (target y); both
        >= 3 and ``cols + rows`` odd (see the module docstring).
    square_m : side of a square, m (default 0.024, the thesis' board).
    margin_squares : white margin around the squares, in squares (quiet zone for detection).
    """

    cols: int = 9
    rows: int = 6
    square_m: float = DEFAULT_SQUARE_M
    margin_squares: float = 1.0

    def __post_init__(self) -> None:
        for name in ("cols", "rows"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 3:
                raise CalibrationError(f"{name} must be an int >= 3 (inner corners), got {value!r}")
        if (self.cols + self.rows) % 2 == 0:
            raise CalibrationError(
                f"a {self.cols} x {self.rows} board looks the same after a half turn, so its "
                "corner order is ambiguous; use inner-corner counts with an odd sum, e.g. 9 x 6"
            )
        if not (math.isfinite(self.square_m) and self.square_m > 0):
            raise CalibrationError(f"square_m must be a positive length in m, got {self.square_m}")
        if not (math.isfinite(self.margin_squares) and self.margin_squares >= 0):
            raise CalibrationError(f"margin_squares must be >= 0, got {self.margin_squares}")

    @property
    def pattern_size(self) -> tuple[int, int]:
        """``(cols, rows)``, as OpenCV's ``patternSize``."""
        return (int(self.cols), int(self.rows))

    @property
    def n_corners(self) -> int:
        """Number of inner corners, ``cols * rows``."""
        return int(self.cols * self.rows)

    @property
    def size_m(self) -> tuple[float, float]:
        """(width, height) of the whole board with its margin, m."""
        return (
            (self.cols + 1 + 2 * self.margin_squares) * self.square_m,
            (self.rows + 1 + 2 * self.margin_squares) * self.square_m,
        )

    def object_points(self) -> np.ndarray:
        """(N, 3) float64 corner positions in the target frame, m (z = 0), row by row."""
        j, i = np.mgrid[0 : self.rows, 0 : self.cols]
        pts = np.zeros((self.n_corners, 3))
        pts[:, 0] = i.ravel() * self.square_m
        pts[:, 1] = j.ravel() * self.square_m
        return pts

    def texture_shape(self, px_per_square: int) -> tuple[int, int]:
        """(height, width) of :meth:`render_texture`'s image, px."""
        margin = self._margin_px(px_per_square)
        return (
            (self.rows + 1) * px_per_square + 2 * margin,
            (self.cols + 1) * px_per_square + 2 * margin,
        )

    def render_texture(self, px_per_square: int) -> np.ndarray:
        """(H, W) uint8 image of the board (black 0, white 255) with its white margin.

        Pixel centres are at integer coordinates: corner ``(i, j)`` is at
        :meth:`texture_corners_px`. The texture spans :attr:`size_m` exactly when
        ``margin_squares * px_per_square`` is whole (the margin is rounded to whole px), so a
        plate of that size textured with this image carries the board at true scale (repeat
        the image on three channels for an RGB texture).
        """
        _check_px_per_square(px_per_square)
        margin = self._margin_px(px_per_square)
        sy, sx = np.mgrid[0 : self.rows + 1, 0 : self.cols + 1]
        squares = np.where((sx + sy) % 2 == 0, 0, 255).astype(np.uint8)
        board = np.kron(squares, np.ones((px_per_square, px_per_square), np.uint8))
        return np.pad(board, margin, constant_values=255)

    def texture_corners_px(self, px_per_square: int) -> np.ndarray:
        """(N, 2) float64 (u, v) positions of the inner corners in :meth:`render_texture`."""
        _check_px_per_square(px_per_square)
        first = self._margin_px(px_per_square) + px_per_square - 0.5  # pixel edge, centres at int
        return first + self.object_points()[:, :2] / self.square_m * px_per_square

    def _margin_px(self, px_per_square: int) -> int:
        return int(round(self.margin_squares * px_per_square))


def _check_px_per_square(px_per_square: int) -> None:
    if isinstance(px_per_square, bool) or not isinstance(px_per_square, (int, np.integer)):
        raise CalibrationError(f"px_per_square must be an int, got {px_per_square!r}")
    if px_per_square < 4:
        raise CalibrationError(f"px_per_square must be >= 4, got {px_per_square}")


def _gray(image: np.ndarray) -> np.ndarray:
    image = np.asarray(image)
    if image.dtype != np.uint8:
        raise CalibrationError(
            f"image must be uint8, got {image.dtype}; scale it to 0-255 and convert first"
        )
    if image.ndim == 2:
        return np.ascontiguousarray(image)
    if image.ndim == 3 and image.shape[2] == 1:
        return np.ascontiguousarray(image[:, :, 0])
    if image.ndim == 3 and image.shape[2] == 3:
        return cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2GRAY)
    raise CalibrationError(f"image must be (H, W) grey or (H, W, 3) RGB, got shape {image.shape}")


def _subpix_window(corners: np.ndarray, board: Checkerboard) -> int:
    """Half window of ``cornerSubPix``: about a third of the smallest corner spacing, 2-11 px."""
    grid = corners.reshape(board.rows, board.cols, 2)
    spacing = min(
        float(np.linalg.norm(np.diff(grid, axis=0), axis=-1).min()),
        float(np.linalg.norm(np.diff(grid, axis=1), axis=-1).min()),
    )
    return int(np.clip(spacing / 3.0, 2, 11))


def _board_order(corners: np.ndarray, gray: np.ndarray, board: Checkerboard) -> np.ndarray:
    """Re-order detected corners to the board's own order (right-handed, colours matching)."""
    grid = corners.reshape(board.rows, board.cols, 2)
    ex, ey = grid[0, -1] - grid[0, 0], grid[-1, 0] - grid[0, 0]
    if ex[0] * ey[1] - ex[1] * ey[0] < 0:  # left-handed: a mirrored order; the front is seen
        grid = grid[::-1]
    pts = grid.reshape(-1, 2)
    homography, _ = cv2.findHomography(board.object_points()[:, :2] / board.square_m, pts)
    if homography is None:
        return pts
    sy, sx = np.mgrid[0 : board.rows + 1, 0 : board.cols + 1]
    centres = np.stack([sx.ravel() - 0.5, sy.ravel() - 0.5], axis=1)[None].astype(np.float64)
    uv = cv2.perspectiveTransform(centres, homography)[0]
    h, w = gray.shape
    inside = (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1)
    if not inside.any():
        return pts
    col = np.clip(np.rint(uv[inside, 0]).astype(int), 0, w - 1)
    row = np.clip(np.rint(uv[inside, 1]).astype(int), 0, h - 1)
    value = gray[row, col].astype(np.float64)
    black = ((sx.ravel() + sy.ravel()) % 2 == 0)[inside]
    if value[black].size and value[~black].size and value[black].mean() > value[~black].mean():
        pts = pts[::-1]  # half a turn: every square has the other colour
    return np.ascontiguousarray(pts)


def find_corners(image: np.ndarray, board: Checkerboard) -> np.ndarray | None:
    """Inner corners of ``board`` in ``image``, or None when the whole board is not found.

    image : (H, W) or (H, W, 3) uint8, grey or RGB.
    Returns (N, 2) float64 pixel positions (u, v) (pixel centres at integers), in the order of
    :meth:`Checkerboard.object_points`.
    """
    if not isinstance(board, Checkerboard):
        raise CalibrationError(f"board must be a Checkerboard, got {type(board).__name__}")
    gray = _gray(image)
    if min(gray.shape) < 16:
        raise CalibrationError(f"image of shape {gray.shape} is too small (>= 16 x 16 px)")
    found, corners = cv2.findChessboardCornersSB(gray, board.pattern_size, flags=_SB_FLAGS)
    if not found or corners is None:
        found, corners = cv2.findChessboardCorners(gray, board.pattern_size, flags=_CLASSIC_FLAGS)
        if not found or corners is None:
            return None
    corners = np.ascontiguousarray(corners, np.float32).reshape(-1, 1, 2)
    if corners.shape[0] != board.n_corners:
        return None
    half = _subpix_window(corners.reshape(-1, 2).astype(np.float64), board)
    corners = cv2.cornerSubPix(gray, corners, (half, half), (-1, -1), _SUBPIX_CRITERIA)
    return _board_order(corners.reshape(-1, 2).astype(np.float64), gray, board)


def board_outline(corners: np.ndarray, board: Checkerboard) -> np.ndarray | None:
    """(4, 2) image corners (px) of the whole printed board, white margin included: its outline
    mapped by the homography that the found inner ``corners`` ((N, 2) px, :func:`find_corners`)
    fit; None when they fit none."""
    corners = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    if corners.shape[0] != board.n_corners or not np.all(np.isfinite(corners)):
        raise CalibrationError(
            f"corners must be the {board.n_corners} finite (u, v) corners of the board, "
            f"got shape {corners.shape}"
        )
    plane = board.object_points()[:, :2] / board.square_m  # in squares
    H, _ = cv2.findHomography(plane, corners)
    if H is None:
        return None
    reach = 1.0 + board.margin_squares  # from an outer inner corner to the board's edge
    lo, hi = -reach, np.array([board.cols - 1, board.rows - 1]) + reach
    outline = np.array([[lo, lo], [hi[0], lo], [hi[0], hi[1]], [lo, hi[1]]], np.float64)
    return cv2.perspectiveTransform(outline.reshape(-1, 1, 2), H).reshape(-1, 2)


def board_in_view(corners: np.ndarray, board: Checkerboard, image_size: tuple[int, int]) -> bool:
    """Whether the whole printed board, its white margin included, lies inside the image.

    corners : (N, 2) inner corners found in the image (:func:`find_corners`), px.
    image_size : (height, width) of the image, px.

    Every corner of the board's :func:`board_outline` must fall inside the image, pixel
    centres at integers. A detector finds the inner corners of a board cut by the image border
    too, but the outermost ones then lack the squares and the quiet zone around them that
    locate them: in the simulated head cameras' distorted views such a view put one corner 2.6
    and 7.4 px off, where corners are otherwise within 0.2 px.
    """
    mapped = board_outline(corners, board)
    if mapped is None:
        return False
    height, width = image_size
    return bool(
        np.all(mapped[:, 0] >= -0.5)
        and np.all(mapped[:, 0] <= width - 0.5)
        and np.all(mapped[:, 1] >= -0.5)
        and np.all(mapped[:, 1] <= height - 0.5)
    )


def planar_residual_px(
    corners: np.ndarray, board: Checkerboard, K: np.ndarray, dist: np.ndarray | None
) -> float:
    """Largest distance, px, of the found ``corners`` ((N, 2), as observed) from the
    least-squares homography of the board's plane, after undistorting them with ``K`` (3, 3)
    and ``dist`` (OpenCV coefficients or None).

    Under a pinhole camera a planar board maps by a homography, so found corners depart from
    it by their detection noise only: in the simulated head cameras' views, at most about
    0.2 px. A corner the detector put on the wrong edge or blob departs by pixels; such a view
    measures the detector, not the cameras (:data:`PLANAR_PX` is the bound the evaluation
    uses).
    """
    corners = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    if corners.shape[0] != board.n_corners or not np.all(np.isfinite(corners)):
        raise CalibrationError(
            f"corners must be the {board.n_corners} finite (u, v) corners of the board, "
            f"got shape {corners.shape}"
        )
    K = np.asarray(K, dtype=np.float64)
    ideal = corners if dist is None else cv2.undistortPoints(
        corners.reshape(-1, 1, 2), K, np.asarray(dist, np.float64), P=K).reshape(-1, 2)  # fmt: skip
    plane = board.object_points()[:, :2].astype(np.float64)
    H, _ = cv2.findHomography(plane, ideal, 0)
    if H is None:
        return float("inf")
    mapped = cv2.perspectiveTransform(plane.reshape(-1, 1, 2), H).reshape(-1, 2)
    return float(np.linalg.norm(mapped - ideal, axis=1).max())
