"""Structured-light depth noise of an ASUS Xtion Pro Live / Microsoft Kinect v1.

Turns an ideal z-depth image (as rendered) into what such a sensor returns. Every effect can be
switched off in :class:`DepthNoiseConfig`; all randomness comes from the caller's
``numpy.random.Generator`` (same state and inputs, same output). ``theta`` is the incidence
angle between the surface normal and the camera ray, estimated from the depth image itself
(:func:`cos_incidence`). In order:

1. Axial noise (Nguyen, Izadi & Lovell 2012, Kinect v1): ``sigma_z = 0.0012 + 0.0019 (z -
   0.4)^2`` m (z in m), plus ``0.0001 / sqrt(z) * theta^2 / (pi/2 - theta)^2`` m.
2. Disparity quantisation: disparity ``d = fx b / z`` (baseline ``b = 0.075`` m, ``fx`` of the
   image in px) is rounded to 1/8 px, ``z = fx b / d``: depth steps of ``z^2 / (fx b) / 8``.
3. Missing depth (0): at discontinuities (3x3 neighbourhood spanning > 3 cm; the pattern is
   shadowed or broken there) with probability 0.7; at grazing incidence ``theta > 80 deg``; on
   specular surfaces (mask from the caller, e.g. glazed ceramics) where they face the camera
   within 25 deg (mirror highlight of the IR projector), plus random ~8 px blobs over ~30 % of
   the rest; and outside ``[0.45, 3.5]`` m. The datasheet says 0.8-3.5 m, but the sensor
   returns depth from ~0.45 m in practice, which close-range wrist views rely on.
4. Lateral noise (Nguyen et al. 2012): ``sigma_L = 0.8 + 0.035 theta / (pi/2 - theta)`` px;
   each pixel takes the depth at a rounded Gaussian offset (nearest neighbour), which jags
   depth edges and hole borders.

Structured-light effects (:mod:`ipbench.envs.sensors.structured_light`, sources there), all off in
``DepthNoiseConfig()`` (``Sorting-v0``/``v1`` keep their exact output) and on in
:data:`STRUCTURED_LIGHT`: the projector shadow (needs a depth image rendered from the projector,
:attr:`DepthNoiseModel.projector_offset`; shadowed pixels are missing input); 9x9 block matching
in disparity with window-correlated Gaussian disparity noise calibrated to Nguyen's sigma_z,
which *replaces* 1. and the edge drop-out of 3. (quantisation 2., grazing, specular and range
drop-outs and lateral noise 4. stay, in that order); and a per-unit depth scale / offset and
depth-to-RGB shift (:meth:`DepthNoiseModel.draw_unit`, applied last). Ranges of the preset: scale
+-1 %, offset +-1 cm (at most 2 cm at 1 m, 4.5 cm at 3.5 m: Boehm, "Accuracy investigation for
structured-light based consumer 3D sensors", 18 PrimeSense/Xtion units, repeatability a few mm,
absolute accuracy off by up to a few cm), shift +-2 px per axis (estimate: the ROS openni
drivers correct a nominal (5, 4) px IR-to-depth offset of the 9x7 correlation window and expose
it per unit "to allow tweaking"; the per-unit residual is not published there).

The angle terms use ``theta <= 89 deg`` (axial) and ``<= 80 deg`` (lateral). Gaussian deviates
come from inverse-CDF tables indexed by random integers (65 536 quantiles for the axial noise,
256 for the lateral offsets), several times faster than ``rng.standard_normal``; probabilities
have a resolution of 1/256. A 640x480 frame takes ~3 ms on one core (:data:`STRUCTURED_LIGHT`:
~5.5 ms; the random words it does not use are skipped by advancing the generator past them).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import statistics
from dataclasses import dataclass
from types import SimpleNamespace

import cv2
import numpy as np

from . import _kernels as _k
from .structured_light import (
    BlockMatcher,
    UnitError,
    draw_unit_error,
    noise_numbers,
    projector_lit,
    shadowed_depth,
)

__all__ = [
    "DEFAULT_CONFIG",
    "SENSOR_EFFECTS",
    "STRUCTURED_LIGHT",
    "DepthNoiseConfig",
    "DepthNoiseModel",
    "SensorError",
    "UnitError",
    "axial_sigma",
    "cos_incidence",
    "lateral_sigma_px",
    "without_effect",
]

_MAX_THETA, _MAX_THETA_LATERAL = math.radians(89.0), math.radians(80.0)  # angle-term caps
_K3 = np.ones((3, 3), np.uint8)


class SensorError(ValueError):
    """Root exception of the sensor modules; messages list the valid options."""


@dataclass(frozen=True)
class DepthNoiseConfig:
    """Parameters of :class:`DepthNoiseModel` (units in the comments); Xtion defaults."""

    enabled: bool = True  # False: ideal depth, only clipped to [min_range_m, max_range_m]
    axial_a: float = 0.0012  # m; sigma_z = a + b (z - c)^2
    axial_b: float = 0.0019  # 1/m
    axial_c: float = 0.4  # m
    axial_angle_k: float = 0.0001  # m^1.5; + k / sqrt(z) theta^2 / (pi/2 - theta)^2 (0: off)
    lateral_sigma_px: float = 0.8  # px; std of the lateral sampling offset
    lateral_angle_k_px: float = 0.035  # px; + k theta / (pi/2 - theta) (both 0: no lateral)
    baseline_m: float = 0.075  # m; projector-camera baseline
    disparity_step_px: float = 1.0 / 8.0  # px; disparity resolution (0: no quantisation)
    min_range_m: float = 0.45  # m; nearer depth is missing
    max_range_m: float = 3.5  # m; farther depth is missing
    edge_threshold_m: float = 0.03  # m; 3x3 depth span that marks a discontinuity
    edge_dropout: float = 0.7  # probability that a discontinuity pixel is missing (0: off)
    grazing_angle_deg: float = 80.0  # deg; depth missing beyond this incidence (90: off)
    specular_facing_deg: float = 25.0  # deg; specular pixels missing below this incidence
    specular_dropout: float = 0.3  # fraction of the other specular pixels lost in blobs
    specular_blob_px: int = 8  # px; size of the specular blobs
    # Structured-light effects (module structured_light), off by default:
    projector_shadow: bool = False  # surfaces the projector cannot light get no depth
    projector_side: int = 1  # +1: projector at +x (OpenCV frame) of the IR camera; -1: at -x
    shadow_tolerance: float = 0.01  # relative depth margin of the shadow test
    block_matching: bool = False  # replaces axial noise and edge drop-out (module docstring)
    bm_window_px: int = 9  # px; correlation window (odd)
    bm_pattern_cell_px: int = 3  # px; one projector dot per cell of this size
    bm_pattern_seed: int = 0  # the dot pattern (a device constant)
    bm_min_dots: int = 4  # fewer seen dots in the window: lost
    bm_match_fraction: float = 2.0 / 3.0  # winner's share of the window's weighted dots
    bm_surface_tol_px: float = 1.0  # px; disparity gap that separates two surfaces
    unit_scale_max: float = 0.0  # per-unit depth scale error drawn in [-x, x] (fraction)
    unit_offset_max_m: float = 0.0  # m; per-unit depth offset drawn in [-x, x]
    unit_shift_max_px: int = 0  # px; per-unit depth-to-RGB shift drawn in [-x, x] per axis

    def __post_init__(self) -> None:
        nonneg = "axial_a axial_b axial_angle_k lateral_sigma_px lateral_angle_k_px"
        rules = [(nonneg + " disparity_step_px min_range_m edge_threshold_m", 0, math.inf)]
        rules += [("edge_dropout specular_dropout", 0, 1), ("specular_blob_px", 1, 1e9)]
        rules += [("shadow_tolerance unit_scale_max", 0, 0.5), ("bm_match_fraction", 0.5, 1)]
        rules += [("bm_pattern_cell_px bm_min_dots", 1, 1e9), ("bm_window_px", 3, 99)]
        rules += [("unit_offset_max_m bm_surface_tol_px unit_shift_max_px", 0, 1e9)]
        if self.projector_side not in (-1, 1) or self.bm_window_px % 2 == 0:
            raise SensorError(
                f"DepthNoiseConfig.projector_side={self.projector_side!r} (valid: -1, 1) or "
                f"bm_window_px={self.bm_window_px!r} (valid: odd, 3-99)"
            )
        rules += [("grazing_angle_deg specular_facing_deg", 0, 90), ("baseline_m", 1e-9, 1e9)]
        rules += [("max_range_m", self.min_range_m + 1e-9, math.inf)]
        for names, lo, hi in rules:
            for name in names.split():
                if not lo <= getattr(self, name) <= hi:
                    value = getattr(self, name)
                    raise SensorError(f"DepthNoiseConfig.{name}={value!r}; valid: [{lo:g}, {hi:g}]")


DEFAULT_CONFIG = DepthNoiseConfig()
"""The Xtion model of ``Sorting-v0``/``v1`` (no structured-light effects); never changes."""

STRUCTURED_LIGHT = DepthNoiseConfig(
    projector_shadow=True,
    block_matching=True,
    unit_scale_max=0.01,
    unit_offset_max_m=0.01,
    unit_shift_max_px=2,
)
"""Every effect on (``Sorting-v2``): the module docstring's numbers and sources."""

_EFFECT_OFF: dict[str, dict[str, object]] = {
    "projector_shadow": {"projector_shadow": False},
    "block_matching": {"block_matching": False},
    "axial_noise": {"axial_a": 0.0, "axial_b": 0.0, "axial_angle_k": 0.0},
    "quantisation": {"disparity_step_px": 0.0},
    "lateral_noise": {"lateral_sigma_px": 0.0, "lateral_angle_k_px": 0.0},
    "grazing": {"grazing_angle_deg": 90.0},
    "specular": {"specular_facing_deg": 0.0, "specular_dropout": 0.0},
    "unit_depth_error": {"unit_scale_max": 0.0, "unit_offset_max_m": 0.0},
    "registration": {"unit_shift_max_px": 0},
}
SENSOR_EFFECTS: tuple[str, ...] = tuple(_EFFECT_OFF)
"""The switchable effects of :data:`STRUCTURED_LIGHT` (``axial_noise``: the disparity noise
with block matching on), for :func:`without_effect`."""


def without_effect(config: DepthNoiseConfig, effect: str) -> DepthNoiseConfig:
    """``config`` with ``effect`` (one of :data:`SENSOR_EFFECTS`) switched off."""
    if effect not in _EFFECT_OFF:
        raise SensorError(f"unknown sensor effect {effect!r}; valid: {list(SENSOR_EFFECTS)}")
    return dataclasses.replace(config, **_EFFECT_OFF[effect])


def _angle_ratio(theta, cap: float = _MAX_THETA) -> np.ndarray:
    theta = np.minimum(np.asarray(theta, dtype=np.float64), cap)
    return theta / (np.pi / 2 - theta)


def axial_sigma(z, theta=None, config: DepthNoiseConfig = DEFAULT_CONFIG) -> np.ndarray:
    """Axial noise std (m) at depth ``z`` (m), incidence ``theta`` (rad; None: no angle term)."""
    z = np.asarray(z, dtype=np.float64)
    sigma = config.axial_a + config.axial_b * (z - config.axial_c) ** 2
    if theta is not None:
        sigma = sigma + config.axial_angle_k / np.sqrt(z) * _angle_ratio(theta) ** 2
    return sigma


def lateral_sigma_px(theta=0.0, config: DepthNoiseConfig = DEFAULT_CONFIG) -> np.ndarray:
    """Lateral noise std (px) at incidence ``theta`` (rad)."""
    ratio = _angle_ratio(theta, _MAX_THETA_LATERAL)
    return config.lateral_sigma_px + config.lateral_angle_k_px * ratio


def cos_incidence(depth: np.ndarray, fx: float, fy: float, cx=None, cy=None) -> np.ndarray:
    """(H, W) float32 cos(incidence angle) of a (H, W) z-depth image (m), from its gradients.

    ``fx``, ``fy``, ``cx``, ``cy``: intrinsics in px, principal point by default at the image
    centre ``((W - 1) / 2, (H - 1) / 2)``. Meaningless at missing pixels.
    """
    z = np.ascontiguousarray(depth, dtype=np.float32)
    buffers = [np.empty_like(z) for _ in range(3)]
    return np.minimum(_cos_incidence(z, float(fx), float(fy), cx, cy, *buffers), np.float32(1))


def _cos_incidence(z, fx, fy, cx, cy, out, gu, gv) -> np.ndarray:
    """:func:`cos_incidence` (up to rounding, not clipped to 1) in ``out``; ``gu``, ``gv``:
    scratch (H, W) float32.

    Surface z(u, v), u and v from the principal point: normal ~ (fx z_u, fy z_v, -(z + u z_u
    + v z_v)), ray ~ (u / fx, v / fy, 1), normal . ray = -z: cos = z / (|normal| |ray|). The
    smaller one-sided difference is used: next to a discontinuity, the surface's own slope.
    """
    if min(z.shape) < 2:
        raise SensorError(f"depth must be at least 2x2 px, got {z.shape}")
    un, vn, r2 = _pixel_grid(z.shape, fx, fy, cx, cy)
    return _k.cos_incidence_into(z, fx, fy, un[0], vn[:, 0], r2, out, gu, gv)


@functools.lru_cache(maxsize=8)
def _pixel_grid(shape, fx, fy, cx, cy):
    """Per-image constants: (u - cx) / fx (1, W), (v - cy) / fy (H, 1), |ray|^2 (H, W)."""
    h, w = shape
    cx, cy = (w - 1) / 2 if cx is None else cx, (h - 1) / 2 if cy is None else cy
    un = ((np.arange(w) - cx) / fx).astype(np.float32)[None, :]
    vn = ((np.arange(h) - cy) / fy).astype(np.float32)[:, None]
    return un, vn, 1 + un**2 + vn**2


@functools.cache
def _normal_quantiles(n: int) -> np.ndarray:
    """``n`` equiprobable standard-normal quantiles, rescaled to unit variance (float64)."""
    q = np.array([statistics.NormalDist().inv_cdf((k + 0.5) / n) for k in range(n)])
    return q / q.std()


def _random_words(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n,) uint64 uniform words: ``rng.integers(0, 2**64 - 1, endpoint=True)``, read straight
    from a 64-bit bit generator (the same words and state, ~1.5x faster)."""
    if isinstance(rng.bit_generator, (np.random.PCG64, np.random.PCG64DXSM, np.random.SFC64)):
        return rng.bit_generator.random_raw(n)
    return rng.integers(0, 2**64 - 1, size=n, dtype=np.uint64, endpoint=True)


def _random_bytes(rng: np.random.Generator, n: int, spans) -> list[np.ndarray]:
    """Bytes ``[start, stop)`` of ``_random_words(rng, n).view(np.uint8)`` for each of the
    sorted ``spans``, leaving ``rng`` where drawing all ``n`` words leaves it. With PCG64 and
    PCG64DXSM (one word per step) only the words the spans touch are drawn; the others are
    skipped with ``advance`` (the same state, O(log n)), whose reset of the buffered 32-bit half
    word is undone. Other generators (or spans sharing a word): all ``n`` words are drawn."""
    bg, words = rng.bit_generator, [(a // 8, -(-b // 8)) for a, b in spans]
    apart = all(stop <= start for (_, stop), (start, _) in zip(words, words[1:], strict=False))
    if not (apart and isinstance(bg, (np.random.PCG64, np.random.PCG64DXSM))):
        raw = _random_words(rng, n).view(np.uint8)
        return [raw[a:b] for a, b in spans]
    state, out, pos = bg.state, [], 0
    for (a, b), (start, stop) in zip(spans, words, strict=True):
        if start > pos:
            bg.advance(start - pos)
        out.append(bg.random_raw(stop - start).view(np.uint8)[a - 8 * start : b - 8 * start])
        pos = stop
    if n > pos:
        bg.advance(n - pos)
    if state["has_uint32"]:
        now = bg.state
        now["has_uint32"], now["uinteger"] = state["has_uint32"], state["uinteger"]
        bg.state = now
    return out


def _workspace(h: int, w: int) -> SimpleNamespace:
    """Scratch buffers for one image shape (fresh large arrays cost page faults every frame)."""
    kinds = dict.fromkeys("cos f1 f2 f3 lut noisy zs byte_sums lateral".split(), np.float32)
    kinds |= {"level": np.uint8} | dict.fromkeys("drop edge mask".split(), bool)
    ws = {name: np.empty((h, w), t) for name, t in kinds.items()}
    extra = dict(field=None, sin_beta=None, grid_key=None, none=np.zeros((h, w), bool))
    return SimpleNamespace(**ws, **extra, shape=(h, w))


class DepthNoiseModel:
    """Seedable structured-light depth noise (module docstring). Not thread-safe (buffers)."""

    def __init__(self, config: DepthNoiseConfig = DEFAULT_CONFIG) -> None:
        if not isinstance(config, DepthNoiseConfig):
            raise SensorError(f"config must be a DepthNoiseConfig, got {type(config).__name__}")
        self.config = c = config
        theta = np.arccos(np.arange(256) / 255.0)  # incidence level i <-> cos(theta) = i / 255
        self._angle_lut = (c.axial_angle_k * _angle_ratio(theta) ** 2).astype(np.float32)
        sigma_l = lateral_sigma_px(theta, c)[:, None]  # offsets (px) at [level * 256 + byte]:
        self._lateral_lut = np.rint(sigma_l * _normal_quantiles(256)).astype(np.int16).ravel()
        self._gauss = _normal_quantiles(65536).astype(np.float32)
        self._cos_graze = np.float32(math.cos(math.radians(c.grazing_angle_deg)))
        self._cos_face = np.float32(math.cos(math.radians(c.specular_facing_deg)))
        self._edge_byte, self._blob_byte = (
            round(c.edge_dropout * 256),
            round(c.specular_dropout * 256),
        )
        self._ws: SimpleNamespace | None = None
        self._matcher = BlockMatcher(
            c.bm_window_px,
            c.bm_pattern_cell_px,
            c.bm_pattern_seed,
            c.bm_min_dots,
            c.bm_match_fraction,
            c.bm_surface_tol_px,
        )
        cap = math.radians(min(c.grazing_angle_deg, 85.0))
        self._tan_lut = np.tan(np.minimum(theta, cap)).astype(np.float32)  # level -> tan(theta)

    @property
    def projector_offset(self) -> tuple[float, float, float]:
        """The projector's position in the camera frame (m, OpenCV: x right, y down, z forward)."""
        return (self.config.projector_side * self.config.baseline_m, 0.0, 0.0)

    def draw_unit(self, rng: np.random.Generator) -> UnitError | None:
        """This sensor unit's systematic error (draw once per episode; 4 draws from ``rng``),
        or None (no draw) for a sensor without one (e.g. the default, v0/v1's)."""
        c = self.config
        if not (c.enabled and (c.unit_scale_max or c.unit_offset_max_m or c.unit_shift_max_px)):
            return None
        return draw_unit_error(rng, c.unit_scale_max, c.unit_offset_max_m, c.unit_shift_max_px)

    @property
    def uses_specular(self) -> bool:
        """Whether :meth:`apply` uses a specular mask (if not, it need not be rendered)."""
        c = self.config
        return c.enabled and (c.specular_facing_deg > 0 or c.specular_dropout > 0)

    def apply(
        self,
        depth: np.ndarray,
        fx: float,
        fy: float,
        rng: np.random.Generator,
        specular: np.ndarray | None = None,
        *,
        cx: float | None = None,
        cy: float | None = None,
        projector_depth: np.ndarray | None = None,
        unit: UnitError | None = None,
    ) -> np.ndarray:
        """Noisy copy of ``depth``: (H, W) float32 m, 0 = missing.

        ``depth``: (H, W) float ideal z-depth (m, 0 = no return, finite). ``fx``, ``fy``: focal
        lengths of this image (px); ``cx``, ``cy``: its principal point (px, default: the image
        centre), for incidence angles. ``rng``: all randomness. ``specular``: optional (H, W)
        bool mask of specular surfaces. ``projector_depth``: optional (H, W) z-depth rendered
        from :attr:`projector_offset` with the same intrinsics: with it the projector shadow is
        found by shadow mapping (:func:`~ipbench.envs.sensors.structured_light.projector_lit`, the
        reference), without it from ``depth`` alone along the scan lines
        (:func:`~ipbench.envs.sensors.structured_light.projector_visible`: no second render; they
        agree on 99.7 % of a cluttered scene's pixels). ``unit``: this unit's error
        (:meth:`draw_unit`; None: none). With ``enabled=False``: ``depth`` clipped to the range.
        """
        cfg, z = self.config, self._validate(depth, specular)
        lo, hi = np.float32(cfg.min_range_m), np.float32(cfg.max_range_m)
        if not cfg.enabled:
            return np.where((z < lo) | (z > hi), np.float32(0), z)
        if unit is not None and not isinstance(unit, UnitError):
            raise SensorError(f"unit must be a UnitError or None, got {type(unit).__name__}")
        if cfg.projector_shadow:
            b = self.projector_offset[0]
            if projector_depth is None:
                z = shadowed_depth(z, fx, b, out=self._workspace(z.shape).zs)
            else:
                zp = np.asarray(projector_depth)
                if zp.shape != z.shape or zp.dtype.kind != "f":
                    raise SensorError(
                        f"projector_depth must be a float array of shape {z.shape} rendered at "
                        f"offset {self.projector_offset}, or None (shadow from depth alone)"
                    )
                zp = np.ascontiguousarray(zp, dtype=np.float32)
                lit = projector_lit(z, zp, fx, b, cfg.shadow_tolerance)
                z = np.multiply(z, lit, dtype=np.float32)  # shadowed: 0 (z >= 0 and finite)
        return self._apply(z, float(fx), float(fy), rng, specular, cx, cy, unit)

    def _workspace(self, shape: tuple[int, int]) -> SimpleNamespace:
        """The scratch buffers for images of ``shape`` (made on the first one)."""
        if self._ws is None or self._ws.shape != shape:
            self._ws = _workspace(*shape)
        return self._ws

    def _apply(self, z, fx, fy, rng, specular, cx, cy, unit) -> np.ndarray:
        cfg = self.config
        lo, hi = np.float32(cfg.min_range_m), np.float32(cfg.max_range_m)
        (h, w), n, fx, fy = z.shape, z.size, float(fx), float(fy)
        ws = self._workspace((h, w))
        cosv = _cos_incidence(z, fx, fy, cx, cy, ws.cos, ws.f1, ws.f2)
        level = cv2.convertScaleAbs(cosv, dst=ws.level, alpha=255.0)  # rint(cos(theta) * 255)
        # 8 random bytes per pixel, planar: 2 axial noise, 4 lateral offsets, 1 edge drop-out.
        # Block matching uses plane 0 (its window-correlated noise) and planes 2-5 only.
        if cfg.block_matching:
            noise_bytes, lateral_bytes = _random_bytes(rng, n, [(0, n), (2 * n, 6 * n)])
        else:
            raw = _random_words(rng, n).view(np.uint8)
            lateral_bytes = raw[2 * n : 6 * n]

        # Axial noise, then disparity quantisation.
        angle_term = cv2.LUT(level, self._angle_lut, dst=ws.lut)
        abc = cfg.axial_a, cfg.axial_b, cfg.axial_c
        sigma = ws.f1
        _k.axial_sigma_into(z.reshape(-1), angle_term.reshape(-1), lo, *abc, sigma.reshape(-1))
        noisy = ws.noisy
        if cfg.block_matching:  # its noise is correlated over the window; with the drop-outs
            spec = self._specular_mask(cosv, rng, specular, ws)
            extra = ws.none if spec is None else spec
            self._block_match(z, fx, noisy, sigma, level, cx, cy, noise_bytes, cosv, extra)
            return self._lateral(noisy, level, lateral_bytes, unit)
        self._gauss.take(raw[: 2 * n].view(np.uint16), out=noisy.reshape(-1), mode="clip")
        noisy *= sigma
        noisy += z
        if cfg.disparity_step_px > 0:
            k = np.float32(fx * cfg.baseline_m / cfg.disparity_step_px)
            with np.errstate(divide="ignore", invalid="ignore"):
                np.divide(k, np.rint(np.divide(k, noisy, out=ws.f1), out=ws.f1), out=noisy)

        # Missing depth.
        drop, edge, mask = np.less_equal(z, 0, out=ws.drop), ws.edge, ws.mask
        if self._edge_byte > 0:
            spread = cv2.dilate(z, _K3, dst=ws.f1)
            np.subtract(spread, cv2.erode(z, _K3, dst=ws.f2), out=spread)
            np.greater(spread, np.float32(cfg.edge_threshold_m), out=edge)
            np.less(raw[6 * n : 7 * n].reshape(h, w), self._edge_byte, out=mask)
            drop |= np.logical_and(mask, edge, out=mask)
        if cfg.grazing_angle_deg < 90:
            drop |= np.less(cosv, self._cos_graze, out=mask)
        spec = self._specular_mask(cosv, rng, specular, ws)
        if spec is not None:
            drop |= spec
        drop |= np.less(noisy, lo, out=mask)
        drop |= np.greater(noisy, hi, out=mask)
        np.copyto(noisy, 0, where=drop)
        return self._lateral(noisy, level, lateral_bytes, unit)

    def _lateral(self, noisy, level, raw, unit) -> np.ndarray:
        """A new image: ``noisy`` sampled at a neighbour displaced by a rounded Gaussian offset
        (px, ``lut[level << 8 | byte]`` for x and y from bytes 4i and 4i + 2 of ``raw``; none
        without lateral noise: the table is 0), then ``unit``'s error (``apply_unit``) and the
        range cut after it (the unit measures depth; its range limits what it reports)."""
        if unit is None:
            terms = (False, 1.0, 0.0, 0, 0, math.inf)
        else:
            scaled = unit.depth_scale != 0.0 or unit.depth_offset_m != 0.0
            scale, (sx, sy) = float(np.float32(1.0 + unit.depth_scale)), unit.shift_px
            hi = float(np.float32(self.config.max_range_m))
            terms = (scaled, scale, float(unit.depth_offset_m), int(sx), int(sy), hi)
        out = np.empty_like(noisy)
        scratch = out if unit is None else self._ws.lateral
        return _k.lateral_resample_into(noisy, level, raw, self._lateral_lut, terms, out, scratch)

    def _block_match(self, z, fx, noisy, sigma, level, cx, cy, random_bytes, cosv, extra):
        """Block-matched depth plus disparity noise, quantised, in ``noisy``; 0 where it is
        missing (no return, lost by the matcher, grazing, ``extra`` or out of range)."""
        cfg, ws = self.config, self._ws
        fb = fx * cfg.baseline_m
        if ws.sin_beta is None or ws.sin_beta.shape != z.shape or ws.grid_key != (fx, cx, cy):
            r2 = np.broadcast_to(_pixel_grid(z.shape, fx, fx, cx, cy)[2], z.shape)
            ws.sin_beta, ws.grid_key = np.sqrt(1 - 1 / r2).astype(np.float32), (fx, cx, cy)
        # disparity (px; 0 where z is 0) and the bound 8 sqrt(2) |grad d| on its window span
        d, slope, tan = ws.f2, ws.f3, cv2.LUT(level, self._tan_lut, dst=ws.lut)
        flat = (x.reshape(-1) for x in (z, tan, ws.sin_beta))
        _k.disparity_slope_into(*flat, fb, 8 * math.sqrt(2) / fx, d.reshape(-1), slope.reshape(-1))
        matched, lost = self._matcher.match(d, slope, cfg.projector_side)
        step, k = cfg.disparity_step_px, cfg.bm_window_px
        b, sums = random_bytes.reshape(z.shape), ws.byte_sums  # exact integer sums
        cv2.boxFilter(b, cv2.CV_32F, (k, k), dst=sums, normalize=False)
        graze = self._cos_graze if cfg.grazing_angle_deg < 90 else np.float32(-np.inf)
        lo, hi = np.float32(cfg.min_range_m), np.float32(cfg.max_range_m)
        flat = (sums, d, sigma, matched, z, lost, cosv, extra, noisy)
        sums, d, sigma, matched, z, lost, cosv, extra, out = (x.reshape(-1) for x in flat)
        drop = (z, lost, cosv, graze, extra, lo, hi)
        _k.noisy_depth_drop_into(sums, noise_numbers(fb, step, k), d, sigma, matched, drop, out)

    def _specular_mask(self, cosv, rng, specular, ws) -> np.ndarray | None:
        """(H, W) bool: the specular pixels that are missing (draws from ``rng``), or None:
        a highlight (surface facing the camera) or inside a random blob."""
        if specular is None or not self.uses_specular or not specular.any():
            return None
        blobs = self._blobs(cosv.shape, rng, ws)
        return _k.specular_drop_into(specular, cosv, self._cos_face, blobs, ws.mask)

    def _blobs(self, shape, rng, ws) -> tuple:
        """``(use, field, dy, dx)`` of :func:`~ipbench.envs.sensors._kernels.specular_drop_into`:
        random cells of ``specular_blob_px`` px interpolated, with a margin for a random phase
        (``lh lw + 2`` draws), or none (no draws) without blobs."""
        (h, w), s = shape, self.config.specular_blob_px
        if self._blob_byte <= 0:
            return False, ws.cos, 0, 0
        lh, lw = h // s + 3, w // s + 3
        cells = rng.integers(0, 255, size=lh * lw + 2, dtype=np.uint8, endpoint=True)
        dy, dx = int(cells[-2]) % s, int(cells[-1]) % s
        cells = (cells[:-2].reshape(lh, lw) < self._blob_byte).astype(np.float32)
        if ws.field is None or ws.field.shape != ((lh - 1) * s, (lw - 1) * s):
            ws.field = np.empty(((lh - 1) * s, (lw - 1) * s), np.float32)
        cv2.resize(cells, ws.field.shape[::-1], dst=ws.field, interpolation=cv2.INTER_LINEAR)
        return True, ws.field, dy, dx

    @staticmethod
    def _validate(depth, specular) -> np.ndarray:
        z = np.asarray(depth)
        if z.ndim != 2 or z.dtype.kind != "f":
            raise SensorError(f"depth must be a (H, W) float array, got {z.dtype} {z.shape}")
        if specular is not None and (specular.shape != z.shape or specular.dtype != bool):
            raise SensorError(f"specular must be a bool array of shape {z.shape}")
        return np.ascontiguousarray(z, dtype=np.float32)

    def expected_std(self, z: float, fx: float) -> float:
        """Std (m) of the noisy depth of a fronto-parallel plane at ``z`` (m), on the optical axis.

        Exact under the model: Gaussian axial noise (``theta = 0``), then disparity quantisation
        with this ``fx`` (px): about ``sqrt(sigma_z^2 + dz^2 / 12)``. Off-axis pixels see the
        plane at the ray angle, which adds < 1 % at 30 deg.
        """
        cfg = self.config
        sigma = float(axial_sigma(z, 0.0, cfg))
        if not cfg.enabled or cfg.disparity_step_px <= 0:
            return sigma if cfg.enabled else 0.0
        k = fx * cfg.baseline_m / cfg.disparity_step_px  # z = k / m for an integer level m
        m = np.arange(math.floor(k / (z + 10 * sigma)), math.ceil(k / (z - 10 * sigma)) + 1)
        cdf = np.vectorize(statistics.NormalDist(z, sigma).cdf)
        p = cdf(k / np.maximum(m - 0.5, 1e-9)) - cdf(k / (m + 0.5))  # P(level m)
        mean = (p * k / m).sum() / p.sum()
        return float(math.sqrt((p * (k / m - mean) ** 2).sum() / p.sum()))
