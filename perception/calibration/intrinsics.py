"""Camera intrinsics from checkerboard views (thesis ch. 4 §4.4): ``cv2.calibrateCamera``.

Zhang's method as OpenCV implements it (``cv2.calibrateCameraExtended``): a closed-form start
from the board homographies, then Levenberg-Marquardt on all reprojection errors, fitting
``fx, fy, cx, cy`` and the Brown-Conrady ``(k1, k2, p1, p2, k3)`` (the model
:mod:`ipbench.envs.sensors.lens_distortion` applies to the renders) plus one board pose per view.
The thesis calibrated each camera from 10 poses of its 24 mm checkerboard; OpenCV needs at least 3
views of a planar target that are not all parallel to each other.

The reprojection error reported is OpenCV's: the RMS over all corners of the pixel distance
between detected and reprojected corners (``rms_px``), and the same per view.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from ipbench.perception.calibration.errors import CalibrationError
from ipbench.perception.calibration.target import Checkerboard

__all__ = ["ALLOWED_FLAGS", "MIN_VIEWS", "Intrinsics", "calibrate_intrinsics"]

MIN_VIEWS = 3
# calibrateCamera flags that keep the five-coefficient model; rational, thin-prism and tilted
# models (more coefficients) are refused.
ALLOWED_FLAGS = {
    "CALIB_USE_INTRINSIC_GUESS": cv2.CALIB_USE_INTRINSIC_GUESS,
    "CALIB_FIX_PRINCIPAL_POINT": cv2.CALIB_FIX_PRINCIPAL_POINT,
    "CALIB_FIX_ASPECT_RATIO": cv2.CALIB_FIX_ASPECT_RATIO,
    "CALIB_FIX_FOCAL_LENGTH": cv2.CALIB_FIX_FOCAL_LENGTH,
    "CALIB_ZERO_TANGENT_DIST": cv2.CALIB_ZERO_TANGENT_DIST,
    "CALIB_FIX_K1": cv2.CALIB_FIX_K1,
    "CALIB_FIX_K2": cv2.CALIB_FIX_K2,
    "CALIB_FIX_K3": cv2.CALIB_FIX_K3,
}
_NEEDS_GUESS = cv2.CALIB_FIX_FOCAL_LENGTH | cv2.CALIB_FIX_ASPECT_RATIO


def _frozen(array: np.ndarray) -> np.ndarray:
    array = np.array(array, np.float64)
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class Intrinsics:
    """A calibrated camera.

    K : (3, 3) float64 camera matrix ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``, px (pixel
        centres at integer coordinates).
    dist : (5,) float64 ``(k1, k2, p1, p2, k3)``, OpenCV's ``distCoeffs`` (dimensionless).
    image_size : (width, height), px.
    rms_px : RMS reprojection error over all corners of all views, px.
    per_view_rms_px : (V,) RMS reprojection error of each view, px.
    std : (9,) standard deviations of ``fx, fy, cx, cy`` (px) and ``k1, k2, p1, p2, k3``
        estimated by OpenCV from the residuals (0 for fixed parameters).
    rvecs : (V, 3) rotation vectors (rad) of the board in the camera frame, one per view.
    tvecs : (V, 3) board origin (first inner corner) in the camera frame, m.
    """

    K: np.ndarray
    dist: np.ndarray
    image_size: tuple[int, int]
    rms_px: float
    per_view_rms_px: np.ndarray
    std: np.ndarray
    rvecs: np.ndarray
    tvecs: np.ndarray

    def __post_init__(self) -> None:
        arrays = {
            name: _frozen(getattr(self, name))
            for name in ("K", "dist", "per_view_rms_px", "std", "rvecs", "tvecs")
        }
        n_views = arrays["per_view_rms_px"].shape[0] if arrays["per_view_rms_px"].ndim else -1
        expected = {
            "K": (3, 3),
            "dist": (5,),
            "per_view_rms_px": (n_views,),
            "std": (9,),
            "rvecs": (n_views, 3),
            "tvecs": (n_views, 3),
        }
        for name, shape in expected.items():
            if arrays[name].shape != shape:
                raise CalibrationError(
                    f"Intrinsics.{name} must have shape {shape}, got {arrays[name].shape}"
                )
            object.__setattr__(self, name, arrays[name])
        object.__setattr__(self, "image_size", _check_image_size(self.image_size))
        object.__setattr__(self, "rms_px", float(self.rms_px))

    @property
    def fx(self) -> float:
        """Focal length along image x (columns), px."""
        return float(self.K[0, 0])

    @property
    def fy(self) -> float:
        """Focal length along image y (rows), px."""
        return float(self.K[1, 1])

    @property
    def cx(self) -> float:
        """Principal point column, px."""
        return float(self.K[0, 2])

    @property
    def cy(self) -> float:
        """Principal point row, px."""
        return float(self.K[1, 2])

    @property
    def n_views(self) -> int:
        """Number of views calibrated from."""
        return int(self.per_view_rms_px.shape[0])


def _check_image_size(image_size: tuple[int, int]) -> tuple[int, int]:
    try:
        w, h = (int(n) for n in image_size)
    except (TypeError, ValueError):
        raise CalibrationError(
            f"image_size must be (width, height) in px, got {image_size!r}"
        ) from None
    if (w, h) != tuple(image_size) or w < 2 or h < 2:
        raise CalibrationError(
            f"image_size must be (width, height), whole px >= 2, got {image_size!r}"
        )
    return w, h


def _check_views(
    image_points: Sequence[np.ndarray], board: Checkerboard, size: tuple[int, int]
) -> list[np.ndarray]:
    if isinstance(image_points, np.ndarray) and image_points.ndim == 3:
        image_points = list(image_points)
    if not isinstance(image_points, Sequence):
        raise CalibrationError(
            f"image_points must be a list of (N, 2) arrays, one per view, got "
            f"{type(image_points).__name__}"
        )
    if len(image_points) < MIN_VIEWS:
        raise CalibrationError(
            f"need >= {MIN_VIEWS} views of the board to calibrate, got {len(image_points)}; "
            "capture more board poses (the thesis used 10)"
        )
    w, h = size
    views = []
    for index, points in enumerate(image_points):
        if points is None:
            raise CalibrationError(
                f"view {index} is None (board not found); drop the views find_corners missed"
            )
        pts = np.asarray(points, np.float64)
        if pts.ndim == 3 and pts.shape[1] == 1:  # OpenCV's (N, 1, 2)
            pts = pts[:, 0]
        if pts.shape != (board.n_corners, 2):
            raise CalibrationError(
                f"view {index} has shape {np.shape(points)}; a {board.cols} x {board.rows} board "
                f"needs ({board.n_corners}, 2) corner positions"
            )
        if not np.isfinite(pts).all():
            raise CalibrationError(f"view {index} has non-finite corner positions")
        outside = (pts[:, 0] < -0.5) | (pts[:, 0] > w - 0.5)
        outside |= (pts[:, 1] < -0.5) | (pts[:, 1] > h - 0.5)
        if outside.any():
            raise CalibrationError(
                f"view {index} has {int(outside.sum())} corners outside the {w} x {h} image; "
                "image_size is (width, height): swapped, or points of another image?"
            )
        views.append(pts.astype(np.float32).reshape(-1, 1, 2))
    return views


def _check_flags(flags: int, K_guess: np.ndarray | None) -> int:  # noqa: N803
    if isinstance(flags, bool) or not isinstance(flags, (int, np.integer)) or flags < 0:
        raise CalibrationError(
            f"flags must be a non-negative int of cv2.CALIB_* bits, got {flags!r}"
        )
    allowed = 0
    for bit in ALLOWED_FLAGS.values():
        allowed |= bit
    if flags & ~allowed:
        raise CalibrationError(
            f"flags {flags:#x} contain bits outside the five-coefficient model; valid: "
            f"{', '.join(ALLOWED_FLAGS)}"
        )
    if flags & _NEEDS_GUESS and K_guess is None:
        raise CalibrationError(
            "CALIB_FIX_FOCAL_LENGTH and CALIB_FIX_ASPECT_RATIO take their values from K_guess; "
            "pass K_guess"
        )
    if K_guess is not None:
        flags |= cv2.CALIB_USE_INTRINSIC_GUESS
    elif flags & cv2.CALIB_USE_INTRINSIC_GUESS:
        raise CalibrationError("CALIB_USE_INTRINSIC_GUESS needs K_guess; pass it")
    return int(flags)


def calibrate_intrinsics(
    image_points: Sequence[np.ndarray],
    board: Checkerboard,
    image_size: tuple[int, int],
    *,
    flags: int = 0,
    K_guess: np.ndarray | None = None,  # noqa: N803
) -> Intrinsics:
    """Calibrate one camera from views of ``board``.

    image_points : one (N, 2) array of corner positions (px) per view, N = ``board.n_corners``
        in :meth:`Checkerboard.object_points` order (as :func:`find_corners` returns them);
        at least :data:`MIN_VIEWS` views.
    image_size : (width, height) of the images, px.
    flags : ``cv2.CALIB_*`` bits from :data:`ALLOWED_FLAGS` (default 0: all nine intrinsic
        parameters free).
    K_guess : (3, 3) initial camera matrix (turns on ``CALIB_USE_INTRINSIC_GUESS``); needed by
        ``CALIB_FIX_FOCAL_LENGTH`` / ``CALIB_FIX_ASPECT_RATIO``.
    """
    if not isinstance(board, Checkerboard):
        raise CalibrationError(f"board must be a Checkerboard, got {type(board).__name__}")
    size = _check_image_size(image_size)
    views = _check_views(image_points, board, size)
    flags = _check_flags(flags, K_guess)
    if K_guess is None:
        K0 = np.eye(3)  # noqa: N806
    else:
        K0 = np.array(K_guess, np.float64)  # noqa: N806
        if K0.shape != (3, 3) or not np.isfinite(K0).all() or K0[0, 0] <= 0 or K0[1, 1] <= 0:
            raise CalibrationError(
                f"K_guess must be a finite (3, 3) camera matrix with fx, fy > 0, got {K0.tolist()}"
            )
    objects = [board.object_points().astype(np.float32)] * len(views)
    try:
        rms, K, dist, rvecs, tvecs, std, _, per_view = cv2.calibrateCameraExtended(  # noqa: N806
            objects, views, size, K0, np.zeros(5), flags=flags
        )
    except cv2.error as exc:
        raise CalibrationError(
            f"cv2.calibrateCamera failed ({exc.err}); the views may be degenerate (all board "
            "poses parallel, or too few corners spread over the image): vary the board's tilt"
        ) from None
    dist = np.asarray(dist, np.float64).ravel()
    if dist.shape != (5,) or not (np.isfinite(K).all() and np.isfinite(dist).all()):
        raise CalibrationError("cv2.calibrateCamera returned a non-finite result; vary the views")
    return Intrinsics(
        K=K,
        dist=dist,
        image_size=size,
        rms_px=float(rms),
        per_view_rms_px=np.asarray(per_view, np.float64).ravel(),
        std=np.asarray(std, np.float64).ravel()[:9],
        rvecs=np.asarray(rvecs, np.float64).reshape(-1, 3),
        tvecs=np.asarray(tvecs, np.float64).reshape(-1, 3),
    )
