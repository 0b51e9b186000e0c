"""Lens distortion of the cameras: turns an ideal pinhole render into what a real lens gives.

Model: Brown-Conrady with OpenCV's five coefficients ``(k1, k2, p1, p2, k3)``. A ray with
ideal normalised image coordinates ``(x, y) = (X / Z, Y / Z)`` (camera frame, OpenCV axes) and
``r^2 = x^2 + y^2`` lands at

    x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
    y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y

and at pixel ``K @ (x_d, y_d, 1)``: the model maps *ideal to distorted*, as
``cv2.projectPoints``. The distorted image at output pixel ``p_d`` therefore shows the ideal
image at ``p_u = model^-1(p_d)``, which ``cv2.undistortPointsIter`` computes (iteratively, to
1e-6 px here); :func:`distortion_maps` holds these ``p_u`` and :func:`distort_image` remaps
the render with them. ``cv2.undistort`` (whose ``initUndistortRectifyMap`` maps go the other
way, ideal output pixel -> distorted source pixel) undoes it with the same ``K`` and
coefficients. Output pixels whose ideal source falls outside the render are 0 (for depth: no
return); render with a wider ``ideal_K`` (same focal length, a margin) to fill them, as barrel
distortion pulls content in from outside the pinhole frame.

Presets (normalised coefficients do not depend on the image resolution, only on ``K``'s
scaling with it):

- :data:`XTION_RGB`: the Glasgow CloPeMa robot's own calibration of its wrist Xtion's RGB
  camera (640 x 480, fx 540.9 px, plumb_bob model): ``(0.020598, -0.098738, -0.001657,
  0.000591, 0)``; gerac83/ug_bluerobot
  ``clopema_description/calibration_UG/xtion1_rgb_camera.yaml``. No published distortion of the
  Xtion's IR (depth) camera was found; a depth image rendered from the RGB camera takes the same
  maps, with ``cv2.INTER_NEAREST``.
- :data:`D5100_35MM`: the head's lens is not documented in the CloPeMa description; the head
  model uses a 35 mm lens (``fovy`` 25.1 deg). The standard Nikon DX 35 mm lens is the AF-S DX
  Nikkor 35mm f/1.8G; lensfun's profile of it, measured on a DX body (crop factor 1.528, the
  D5100's format), is PTLens ``a = 0.003, b = -0.017, c = 0.005`` at 35 mm (lensfun/lensfun
  ``data/db/slr-nikon.xml``). :meth:`LensDistortion.from_ptlens` converts it (least squares on
  the radial displacement over the frame): ``k1 = -0.1535, k2 = -0.5833, k3 = 2.973``, no
  tangential terms (lensfun has none); fit residual <= 2.4e-4 of the focal length (1.7 px at
  the D5100's 4928 x 3264 with 7308 px, 0.35 px at a 1024 px wide render). Barrel: -0.9 % at
  the middle of the long edge, -2.7 % at the corner (80 px at full resolution).
  Cross-checks: photozone.de's test of the same lens on DX reports "moderate barrel distortion
  at around 1.7 %"; lensfun's full-frame (Nikon D3) profile of it gives -1.0 % at the DX
  corner: the same order of magnitude.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import cv2
import numpy as np

from .depth_noise import SensorError

__all__ = [
    "D5100_35MM",
    "INTERPOLATIONS",
    "XTION_RGB",
    "LensDistortion",
    "distort_image",
    "distortion_maps",
]

INTERPOLATIONS = {
    cv2.INTER_NEAREST: "cv2.INTER_NEAREST",
    cv2.INTER_LINEAR: "cv2.INTER_LINEAR",
    cv2.INTER_CUBIC: "cv2.INTER_CUBIC",
    cv2.INTER_LANCZOS4: "cv2.INTER_LANCZOS4",
}
_ITER_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-6)
_INVERSE_TOL_PX = 1e-3  # largest |model(p_u) - p_d| accepted in the maps, px
_CACHE_SIZE = 8  # maps of 8 image sizes / cameras (1024 x 680 px: 5.6 MB each)


@dataclass(frozen=True)
class LensDistortion:
    """Brown-Conrady coefficients in OpenCV's order (dimensionless; radial k1, k2, k3 and
    tangential p1, p2 act on normalised image coordinates, see the module docstring)."""

    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    k3: float = 0.0

    def __post_init__(self) -> None:
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise SensorError(f"{field.name} must be a real number, got {value!r}")
            if not math.isfinite(value):
                raise SensorError(f"{field.name} must be finite, got {value}")
            object.__setattr__(self, field.name, float(value))

    @property
    def coefficients(self) -> np.ndarray:
        """(5,) float64 ``(k1, k2, p1, p2, k3)``, OpenCV's ``distCoeffs``."""
        return np.array([self.k1, self.k2, self.p1, self.p2, self.k3])

    def distort_normalized(self, xy: np.ndarray) -> np.ndarray:
        """(N, 2) ideal normalised coordinates ``(X / Z, Y / Z)`` -> (N, 2) distorted ones."""
        xy = np.asarray(xy, np.float64)
        if xy.ndim != 2 or xy.shape[1] != 2:
            raise SensorError(f"xy must be (N, 2) normalised coordinates, got shape {xy.shape}")
        x, y = xy[:, 0], xy[:, 1]
        r2 = x * x + y * y
        radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x)
        yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y
        return np.stack([xd, yd], axis=1)

    @classmethod
    def from_ptlens(
        cls,
        a: float,
        b: float,
        c: float,
        *,
        focal_mm: float,
        crop_factor: float,
        aspect_ratio: float = 1.5,
    ) -> LensDistortion:
        """Radial ``(k1, k2, k3)`` fitted to a lensfun / Hugin PTLens profile.

        PTLens: ``R_d = R_u (a R_u^3 + b R_u^2 + c R_u + d)``, ``d = 1 - a - b - c``, radii in
        units of half the frame height ``h`` (lensfun: ``h = hypot(36, 24) / crop_factor /
        hypot(aspect_ratio, 1) / 2`` mm), ideal to distorted. With ``s = focal_mm / h`` and the
        paraxial focal length ``focal_mm * d`` (lensfun's "real focal"), the radial factor in
        OpenCV's normalised radius ``r`` is ``1 + (c s r + b s^2 r^2 + a s^3 r^3) / d``; the
        Brown terms ``k1 r^2 + k2 r^4 + k3 r^6`` are fitted to it by least squares on the
        radial displacement at a grid of points over the frame (uniform in area).
        """
        for name, value in (("focal_mm", focal_mm), ("crop_factor", crop_factor)):
            if not (math.isfinite(value) and value > 0):
                raise SensorError(f"{name} must be positive, got {value}")
        if not (math.isfinite(aspect_ratio) and aspect_ratio >= 1):
            raise SensorError(f"aspect_ratio is long / short side (>= 1), got {aspect_ratio}")
        d = 1.0 - a - b - c
        if not d > 0:
            raise SensorError(f"PTLens 1 - a - b - c must be positive, got {d}")
        h = math.hypot(36.0, 24.0) / crop_factor / math.hypot(aspect_ratio, 1.0) / 2.0
        s, f = focal_mm / h, focal_mm * d
        u, v = np.meshgrid(
            np.linspace(-aspect_ratio * h, aspect_ratio * h, 151), np.linspace(-h, h, 101)
        )
        r = np.hypot(u, v).ravel() / f
        excess = (c * s * r + b * s**2 * r**2 + a * s**3 * r**3) / d
        design = np.stack([r**3, r**5, r**7], axis=1)
        k1, k2, k3 = np.linalg.lstsq(design, r * excess, rcond=None)[0]
        return cls(k1=float(k1), k2=float(k2), k3=float(k3))


D5100_35MM = LensDistortion(k1=-0.1535, k2=-0.5833, k3=2.973)  # lensfun DX 35/1.8G, see above
XTION_RGB = LensDistortion(k1=0.020598, k2=-0.098738, p1=-0.001657, p2=0.000591, k3=0.0)


def _check_K(K: np.ndarray, name: str) -> np.ndarray:  # noqa: N802
    K = np.asarray(K, np.float64)  # noqa: N806
    if K.shape != (3, 3) or not np.isfinite(K).all():
        raise SensorError(f"{name} must be a finite (3, 3) camera matrix, got shape {K.shape}")
    zeros = (K[0, 1], K[1, 0], K[2, 0], K[2, 1])
    if not (K[0, 0] > 0 and K[1, 1] > 0 and K[2, 2] == 1 and not any(zeros)):
        raise SensorError(
            f"{name} must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0 (no skew), "
            f"got {K.tolist()}"
        )
    return K


def _check_size(size: tuple[int, int]) -> tuple[int, int]:
    try:
        w, h = (int(n) for n in size)
    except (TypeError, ValueError):
        raise SensorError(f"size must be (width, height) in px, got {size!r}") from None
    if (w, h) != tuple(size) or w < 1 or h < 1 or w >= 32767 or h >= 32767:
        raise SensorError(f"size must be (width, height), whole px in 1-32766, got {size!r}")
    return w, h


@functools.lru_cache(maxsize=_CACHE_SIZE)
def _maps(
    K: tuple[float, ...],  # noqa: N803
    distortion: LensDistortion,
    size: tuple[int, int],
    ideal_K: tuple[float, ...],  # noqa: N803
) -> tuple[np.ndarray, np.ndarray]:
    w, h = size
    k_out, k_ideal = np.reshape(K, (3, 3)), np.reshape(ideal_K, (3, 3))
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    pixels = np.stack([u.ravel(), v.ravel()], axis=1)
    ideal = cv2.undistortPointsIter(
        pixels[:, None, :], k_out, distortion.coefficients, None, None, _ITER_CRITERIA
    ).reshape(-1, 2)
    # check the inversion: the model must send every found ideal point back to its pixel
    back = distortion.distort_normalized(ideal) * np.diag(k_out)[:2] + k_out[:2, 2]
    worst = float(np.abs(back - pixels).max()) if pixels.size else 0.0
    if not worst <= _INVERSE_TOL_PX:
        reach = float(np.hypot(*((pixels - k_out[:2, 2]) / np.diag(k_out)[:2]).T).max())
        raise SensorError(
            f"the distortion {distortion} cannot be inverted over a {w} x {h} image with this K "
            f"(residual {worst:.3g} px): out to the image corners (normalised radius "
            f"{reach:.2f}) the model folds back or its inverse does not converge; use the "
            "coefficients of a lens with this field of view (D5100_35MM: the D5100 + 35 mm "
            "frame, radius <= 0.41; XTION_RGB: the Xtion's, radius <= 0.75)"
        )
    source = ideal * np.diag(k_ideal)[:2] + k_ideal[:2, 2]
    map_x = source[:, 0].reshape(h, w).astype(np.float32)
    map_y = source[:, 1].reshape(h, w).astype(np.float32)
    map_x.setflags(write=False)
    map_y.setflags(write=False)
    return map_x, map_y


def distortion_maps(
    K: np.ndarray,  # noqa: N803
    distortion: LensDistortion,
    size: tuple[int, int],
    ideal_K: np.ndarray | None = None,  # noqa: N803
) -> tuple[np.ndarray, np.ndarray]:
    """``cv2.remap`` maps from an ideal render to the distorted image (cached per argument).

    K : (3, 3) camera matrix of the distorted (output) image, px.
    distortion : the lens.
    size : (width, height) of the output image, px.
    ideal_K : (3, 3) camera matrix of the ideal render, px (default ``K``; a wider render, e.g.
        a margin around the same principal point, fills the corners barrel distortion empties).
    Returns read-only (map_x, map_y), each (height, width) float32: output pixel ``(u, v)``
    shows the render at ``(map_x[v, u], map_y[v, u])``.
    """
    if not isinstance(distortion, LensDistortion):
        raise SensorError(f"distortion must be a LensDistortion, got {type(distortion).__name__}")
    k_out = _check_K(K, "K")
    k_ideal = k_out if ideal_K is None else _check_K(ideal_K, "ideal_K")
    key_out = tuple(float(x) for x in k_out.ravel())
    key_ideal = tuple(float(x) for x in k_ideal.ravel())
    return _maps(key_out, distortion, _check_size(size), key_ideal)


def distort_image(
    image: np.ndarray,
    K: np.ndarray,  # noqa: N803
    distortion: LensDistortion,
    *,
    interpolation: int = cv2.INTER_LINEAR,
    ideal_K: np.ndarray | None = None,  # noqa: N803
    size: tuple[int, int] | None = None,
) -> np.ndarray:
    """The image a lens with ``distortion`` gives of the scene of an ideal pinhole render.

    image : (H, W) or (H, W, C<=4) render (uint8, uint16, float32 or float64), taken with
        ``ideal_K`` (default ``K``).
    K : (3, 3) camera matrix of the output image, px.
    interpolation : one of :data:`INTERPOLATIONS`; ``cv2.INTER_NEAREST`` for depth images
        (never blends depths across an edge or with missing returns), bilinear for colour.
    size : (width, height) of the output, px (default: the image's).
    Returns the distorted image, same dtype and channels; pixels with no source in the render
    are 0.
    """
    image = np.asarray(image)
    if image.ndim not in (2, 3) or (image.ndim == 3 and not 1 <= image.shape[2] <= 4):
        raise SensorError(f"image must be (H, W) or (H, W, C) with C <= 4, got {image.shape}")
    if image.dtype not in (np.uint8, np.uint16, np.float32, np.float64):
        raise SensorError(
            f"image dtype {image.dtype} not supported; valid: uint8, uint16, float32, float64"
        )
    if isinstance(interpolation, bool) or interpolation not in INTERPOLATIONS:
        raise SensorError(
            f"unknown interpolation {interpolation!r}; valid: {', '.join(INTERPOLATIONS.values())}"
        )
    out_size = (image.shape[1], image.shape[0]) if size is None else size
    map_x, map_y = distortion_maps(K, distortion, out_size, ideal_K)
    out = cv2.remap(
        np.ascontiguousarray(image),
        map_x,
        map_y,
        interpolation,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=0,
    )
    return out.reshape(out.shape[:2] + image.shape[2:])
