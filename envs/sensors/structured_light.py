"""Projector shadow, disparity-domain block matching and per-unit error of a Kinect v1 / Xtion.

Used by :class:`ipbench.envs.sensors.depth_noise.DepthNoiseModel` (switches and numbers live in its
``DepthNoiseConfig``); all randomness comes from the caller's ``numpy.random.Generator``.

**Geometry.** The IR projector sits ``b = 0.075`` m beside the IR camera along the camera's x
axis (Khoshelham & Oude Elberink 2012; ROS ``kinect_calibration/technical``), on its +x side
(OpenCV frame: the sensor's right, the viewer's left when facing it; iFixit / ROS photos of the
Kinect: projector, RGB, IR camera from the viewer's left), so shadows fall on the left of
objects in the image. A point at depth ``z`` seen at camera pixel ``(u, v)`` is at projector
pixel ``(u - s d, v)`` with disparity ``d = f b / z`` and ``s = +1`` (``-1``: projector on -x).

**Projector shadow** (:func:`projector_lit`; BlenSor / render_kinect occlusion by the projector
offset): shadow mapping against a depth image rendered from the projector's pose with the same
intrinsics; a camera pixel is lit if the projector's depth at ``(u - s d, v)`` (nearest pixel)
is not nearer than ``z (1 - tolerance)``. The shadow beside an occluder is
``f b (1 / z_fg - 1 / z_bg)`` px wide. Rays leaving the projector image count as lit (the real
projector's field covers the camera's).

**Block matching** (:class:`BlockMatcher`; 9x9 correlation window: ROS
``kinect_calibration/technical``, simkinect, Landau et al.). A binary dot pattern fixed in
projector coordinates (one dot at a seeded random position in every 3x3 px cell, ~1/9 of the
pixels: the same on every unit, like the diffractive element) is seen at camera pixel
``(u, v)`` if the pattern has a dot at ``(u - s d, v)``. A dot's weight is its IR intensity,
``~ 1 / z^2`` (inverse square law, i.e. ``~ d^2``). A pixel is on the *near* class if its
disparity is within ``tol`` of the largest disparity in its 17x17 neighbourhood (which holds
every 9x9 window containing it); ``tol = surface_tol_px + 8 sqrt(2) d (tan(theta) +
sin(beta)) / f`` px, the span of a plane's disparity over 8 px at incidence ``theta`` and ray
angle ``beta``, so tilted planes stay one surface. In each 9x9 window the class with the larger
weighted dot sum wins; the pixel is lost if the window holds fewer than ``min_dots`` seen dots
or the winner less than ``match_fraction`` (2/3: its correlation peak must carry twice the dot
energy of the rest; simkinect's stricter ``n_valid > n_total / 1.2`` leaves ~7 px hole bands
at every edge) of the weighted dots, or if the pixel itself has no return. Otherwise its
disparity is the winner's weighted mean. So edges fatten towards the nearer, brighter surface
by 1-2 px where it dominates the window, corners round (a quarter window never dominates), a
1-3 px band at each depth edge is lost, and parts narrower than ~4 px vanish into the
background (3/9 of a window never wins).

**Disparity noise** (Barron & Malik 2013 / ICL-NUIM style, :func:`noisy_depth`): Gaussian
in disparity, correlated over the 9x9 window (box-filtered white noise rescaled to unit std),
with ``sigma_d^2 = (sigma_z f b / z^2)^2 - q^2 / 12``: Nguyen et al. 2012 measured the
sensor's *output*, which already holds the ``q = 1/8`` px quantisation (uniform error, variance
``q^2 / 12``), so that part is subtracted before the output is quantised again (0 if
negative). Then disparity is rounded to ``q`` and ``z = f b / d``.

**Per-unit error** (:class:`UnitError`): a depth scale and offset, ``z' = z (1 + scale) +
offset``, and a whole-pixel shift of depth relative to RGB, drawn once per sensor unit.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from types import SimpleNamespace

import cv2
import numpy as np

from . import _kernels as _k

__all__ = [
    "BlockMatcher",
    "UnitError",
    "apply_unit",
    "disparity",
    "dot_pattern",
    "noise_numbers",
    "noisy_depth",
    "draw_unit_error",
    "projector_lit",
    "projector_visible",
    "shadowed_depth",
]


@dataclass(frozen=True)
class UnitError:
    """Systematic error of one sensor unit, constant over an episode.

    ``depth_scale`` (fraction) and ``depth_offset_m`` (m): ``z' = z (1 + depth_scale) +
    depth_offset_m``. ``shift_px`` (px, ``(dx, dy)``): the depth image's content moves ``dx``
    px right and ``dy`` px down relative to the RGB image (uncovered pixels: missing).
    """

    depth_scale: float = 0.0
    depth_offset_m: float = 0.0
    shift_px: tuple[int, int] = (0, 0)


def draw_unit_error(
    rng: np.random.Generator, scale_max: float, offset_max_m: float, shift_max_px: int
) -> UnitError:
    """A :class:`UnitError` uniform in ``[-scale_max, scale_max]``, ``[-offset_max_m,
    offset_max_m]`` m and integer ``[-shift_max_px, shift_max_px]`` px per axis (4 draws)."""
    s, o = rng.uniform(-1.0, 1.0, size=2)
    dx, dy = rng.integers(-shift_max_px, shift_max_px, size=2, endpoint=True)
    return UnitError(float(s * scale_max), float(o * offset_max_m), (int(dx), int(dy)))


def apply_unit(depth: np.ndarray, unit: UnitError) -> np.ndarray:
    """``depth`` (H, W) float32 m, 0 = missing, with ``unit``'s error (in place if unshifted).
    (:class:`~ipbench.envs.sensors.depth_noise.DepthNoiseModel` applies the same in its lateral
    pass.)"""
    if unit.depth_scale != 0.0 or unit.depth_offset_m != 0.0:
        valid = np.greater(depth, 0).view(np.uint8)
        depth *= np.float32(1.0 + unit.depth_scale)
        cv2.add(depth, unit.depth_offset_m, dst=depth, mask=valid)
        cv2.threshold(depth, 0, 0, cv2.THRESH_TOZERO, dst=depth)  # negative -> 0 (missing)
    dx, dy = unit.shift_px
    if dx == 0 and dy == 0:
        return depth
    h, w = depth.shape
    out = np.zeros_like(depth)
    if abs(dx) < w and abs(dy) < h:
        out[max(dy, 0) : h + min(dy, 0), max(dx, 0) : w + min(dx, 0)] = depth[
            max(-dy, 0) : h + min(-dy, 0), max(-dx, 0) : w + min(-dx, 0)
        ]
    return out


@functools.lru_cache(maxsize=4)
def _grid(shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) float32 column and row index maps."""
    h, w = shape
    u = np.ascontiguousarray(np.broadcast_to(np.arange(w, dtype=np.float32), (h, w)))
    v = np.ascontiguousarray(np.broadcast_to(np.arange(h, dtype=np.float32)[:, None], (h, w)))
    return u, v


@functools.lru_cache(maxsize=4)
def dot_pattern(shape: tuple[int, int], cell_px: int = 3, seed: int = 0) -> np.ndarray:
    """(H, W) float32 0/1 projector pattern: one dot per ``cell_px`` square cell, at a position
    drawn from ``seed`` (a device constant, not per-frame randomness); it tiles periodically."""
    h, w = shape
    ch, cw = -(-h // cell_px), -(-w // cell_px)
    rng = np.random.default_rng(seed)
    pos = rng.integers(0, cell_px, size=(2, ch, cw))
    pattern = np.zeros((ch * cell_px, cw * cell_px), np.float32)
    rows = np.arange(ch)[:, None] * cell_px + pos[0]
    cols = np.arange(cw)[None, :] * cell_px + pos[1]
    pattern[rows, cols] = 1.0
    return np.ascontiguousarray(pattern[:h, :w])


def disparity(fb: float, depth: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """(H, W) float32 ``fb / depth`` (px for ``fb = f b``), 0 where ``depth`` is 0."""
    with np.errstate(divide="ignore"):
        out = np.divide(np.float32(fb), depth, out=out)
    return cv2.threshold(out, 1e30, 0, cv2.THRESH_TOZERO_INV, dst=out)[1]  # inf -> 0


def projector_lit(
    depth: np.ndarray,
    projector_depth: np.ndarray,
    fx: float,
    baseline_m: float,
    tolerance: float = 0.01,
) -> np.ndarray:
    """(H, W) bool: pixels the projector lights (module docstring; shadow mapping).

    ``depth``, ``projector_depth``: (H, W) float32 z-depth (m, 0 = nothing) from the camera and
    from the projector (same intrinsics, ``baseline_m`` along the camera's x axis, signed);
    ``fx`` in px; ``tolerance``: relative depth margin (shadow-map bias).
    """
    u, v = _grid(depth.shape)
    map_x = np.subtract(u, disparity(fx * baseline_m, depth), dtype=np.float32)  # u - s d
    seen = cv2.remap(projector_depth, map_x, v, cv2.INTER_NEAREST, borderValue=0.0)
    lit = np.greater_equal(seen, depth * np.float32(1.0 - tolerance))
    lit |= seen <= 0
    return lit


def projector_visible(
    depth: np.ndarray, fx: float, baseline_m: float, tolerance_px: float = 0.05
) -> np.ndarray:
    """(H, W) bool: pixels the projector lights, from the camera's own ``depth`` (no render).

    Rectified geometry: a point at pixel ``(u, v)`` with disparity ``d = f |b| / z`` is at
    projector column ``x = u - s d`` (``s`` = sign of ``baseline_m``: +1, projector at +x).
    Whatever hides it from the projector lies on the same projector ray, nearer, so it is
    seen by the camera at ``u' = x + s d' `` beyond ``u`` (``u' > u`` for ``s = +1``) with
    ``x(u') <= x(u)``: the pixel is lit iff ``x(u) < min over u' beyond u of x(u')``
    (``- tolerance_px``), a running minimum along the row. Exact for occluders the camera
    sees (it agrees with :func:`projector_lit`'s shadow map on rendered scenes, see the tests);
    surfaces facing away from the projector come out shadowed, as they are. The shadow beside
    an occluder is ``f b (1 / z_fg - 1 / z_bg)`` px wide. Pixels without depth: lit (moot).

    The running minimum is one compiled pass per row (exactly ``np.minimum.accumulate``'s).
    """
    s = 1 if baseline_m > 0 else -1
    z = np.ascontiguousarray(depth if s > 0 else depth[:, ::-1])  # mirrored: the same test
    lit = np.empty(z.shape, bool)
    _k.projector_lit_into(z, fx * abs(baseline_m), tolerance_px, lit)
    return lit if s > 0 else lit[:, ::-1]


def shadowed_depth(
    depth: np.ndarray, fx: float, baseline_m: float, out: np.ndarray, tolerance_px: float = 0.05
) -> np.ndarray:
    """``depth * projector_visible(depth, fx, baseline_m, tolerance_px)`` (float32, in ``out``):
    0 where the projector does not light the pixel; one compiled pass. ``depth``: (H, W)
    C-contiguous float32."""
    fb, scratch = fx * abs(baseline_m), np.empty((4, depth.shape[1]), np.float32)
    return _k.shadowed_depth_into(depth, fb, tolerance_px, baseline_m <= 0, out, scratch)


def noise_numbers(fb: float, step_px: float, k: int) -> tuple[float, ...]:
    """``(mean, 1 / std, 1 / fb, q, step_px, fb_q)`` of :func:`noisy_depth`: the mean and std
    of a sum of ``k^2`` uniform bytes, ``q = step^2 / 12``, ``fb_q = fb / step`` (``fb`` if
    ``step_px`` is 0)."""
    mean, std = k * k * 127.5, k * math.sqrt((256**2 - 1) / 12.0)
    fb_q = fb / step_px if step_px > 0 else fb
    return mean, 1.0 / std, 1.0 / fb, step_px**2 / 12.0, step_px, fb_q


def noisy_depth(
    random_bytes: np.ndarray,
    sigma_z: np.ndarray,
    disparity: np.ndarray,
    matched: np.ndarray,
    fb: float,
    step_px: float,
    k: int,
    out: np.ndarray,
) -> np.ndarray:
    """(H, W) float32 depth (m, in ``out``): ``matched`` disparity plus disparity noise
    correlated over a ``k`` x ``k`` window, quantised to ``step_px``; ``fb / 0`` where the
    noisy disparity rounds to 0 (the caller drops it as out of range).

    ``random_bytes``: (H, W) uint8 uniform random bytes; their window sums, standardised, are
    the unit-variance correlated field (a sum of ``k^2`` = 81 uniform terms: Gaussian for all
    purposes here, and one box filter instead of a Gaussian draw per pixel). ``sigma_z``:
    Nguyen's axial std (m) per pixel; ``disparity``: ``f b / z`` (px); ``matched``: the block
    matcher's disparity (px); ``fb``: ``f b`` (px m); ``step_px``: quantisation step (px, 0:
    none). ``sigma_d = sqrt(max((sigma_z d^2 / (f b))^2 - step^2 / 12, 0))``.
    """
    field = cv2.boxFilter(random_bytes, cv2.CV_32F, (k, k), normalize=False)
    mean, inv_std, inv_fb, q, step, fb_q = noise_numbers(fb, step_px, k)
    field, disparity, sigma_z, matched, flat_out = (
        x.reshape(-1) for x in (field, disparity, sigma_z, matched, out)
    )
    args = (mean, inv_std, disparity, inv_fb, sigma_z, matched, q, step, fb_q)
    _k.noisy_depth_into(field, *args, flat_out)
    return out


class BlockMatcher:
    """Vectorised 9x9 block matching of disparity images (module docstring); reuses buffers."""

    def __init__(
        self,
        window_px: int = 9,
        cell_px: int = 3,
        seed: int = 0,
        min_dots: int = 4,
        match_fraction: float = 2.0 / 3.0,
        surface_tol_px: float = 1.0,
    ) -> None:
        self.window_px, self.cell_px, self.seed = window_px, cell_px, seed
        self.min_dots, self.match_fraction, self.surface_tol_px = (
            min_dots,
            match_fraction,
            surface_tol_px,
        )
        self._kernel = np.ones((window_px, window_px), np.uint8)
        self._ws: SimpleNamespace | None = None

    def match(
        self, disparity: np.ndarray, slope: np.ndarray, sign: int = 1
    ) -> tuple[np.ndarray, np.ndarray]:
        """(matched disparity (px), lost (bool)), both (H, W), valid until the next call.

        ``disparity``: (H, W) float32 ``f b / z`` (px, 0 = no return); ``slope``: (H, W)
        float32 ``8 sqrt(2) |grad d|`` bound (px) added to the surface tolerance;
        ``sign``: projector side (+1: +x).
        """
        d, (h, w), k = disparity, disparity.shape, self.window_px
        if self._ws is None or self._ws.shape != (h, w):
            f32, pad = np.float32, w + k - 1
            names = "matched dmax rmax dmax2 rec dots".split()
            self._ws = SimpleNamespace(
                shape=(h, w),
                **{name: np.empty((h, w), f32) for name in names},
                lost=np.empty((h, w), bool),
                sums=(*(np.empty(n) for n in ((k, 4 * w), 4 * w, 4 * pad)), np.empty(4 * w, f32)),
            )
        ws = self._ws
        # Near class: within tol of the largest disparity of the (2k - 1)^2 neighbourhood (two
        # k x k dilations); a window whose own disparity span (max d - 1 / max(1 / d), a pixel
        # without return counting as 0) is within tol is one surface. Dots seen: the pattern at
        # projector column u - s d (nearest), weight ~ 1 / z^2 ~ d^2. The window sums of (wgt,
        # wn, wd, wnd) and the winner of each window (the class with more dot energy; too few
        # dots: less energy than min_dots dots at the pixel's own disparity) in one pass.
        _k.reciprocal_into(d.reshape(-1), ws.rec.reshape(-1))
        for src, dst in ((d, ws.dmax), (ws.rec, ws.rmax), (ws.dmax, ws.dmax2)):
            cv2.dilate(src, self._kernel, dst=dst)
        _k.seen_dots_into(d, dot_pattern((h, w), self.cell_px, self.seed), sign, ws.dots)
        terms = (ws.dots, slope, self.surface_tol_px, ws.dmax, ws.rmax, ws.dmax2, k)
        rule = (self.min_dots - 0.5, self.match_fraction)
        _k.match_into(d, *terms, *rule, ws.matched, ws.lost, ws.sums)
        return ws.matched, ws.lost
