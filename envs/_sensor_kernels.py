"""Compiled per-pixel kernels of the depth sensor model (numba, single-threaded, no fast-math).

Each kernel fuses a chain of array operations of :mod:`ipbench.envs.depth_noise` or
:mod:`ipbench.envs.structured_light` into one pass over the image, with the same float32
operations in the same order, so its output is bit-identical to the chain it replaces (the
digest tests of both modules hold it to that); the chain is written in each docstring. One pass
instead of ~10 keeps the image in cache: 3-5x faster than the vectorised numpy/OpenCV chain on
the 2-core reference machine. No fast-math: no reassociation and no fused multiply-adds, so
the results do not depend on the processor's vector width. Compiled on first use and cached
next to this file (``cache=True``; a read-only install compiles once per process).

Element-wise kernels take flat views (``a.reshape(-1)`` of C-contiguous images) and never
write in place of an input: LLVM then vectorises them (a 2-D loop, a table look-up or an
aliased output keeps them scalar, 5-10x slower). Table look-ups stay in ``cv2.LUT``.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = [
    "axial_sigma_into",
    "cos_incidence_into",
    "disparity_slope_into",
    "lateral_resample_into",
    "match_decide_into",
    "match_weights_into",
    "noisy_depth_into",
    "pair_with_reciprocal_into",
    "projector_lit_into",
    "seen_dots_into",
]

_jit = numba.njit(cache=True, nogil=True, error_model="numpy")
_f32 = np.float32


@numba.njit(inline="always")
def _smaller_diff(back, fwd):
    """The one-sided difference of smaller magnitude, as ``back + (fwd - back) * cond``."""
    cond = _f32(1.0) if abs(fwd) < abs(back) else _f32(0.0)
    return back + (fwd - back) * cond


@_jit
def cos_incidence_into(z, fx, fy, un, vn, r2, out, gu, gv):
    """(H, W) float32 cos(incidence) of z-depth ``z`` in ``out`` (not clipped to 1).

    ``un`` (W,), ``vn`` (H,): normalised pixel coordinates; ``r2`` (H, W): ``1 + un^2 + vn^2``;
    ``gu``, ``gv``: (H, W) scratch. Chain: ``gu = fx * smaller one-sided x difference`` (border
    columns: the only one), ``gv`` likewise along y with ``fy``; ``out = z / sqrt((((un gu + z)
    + vn gv)^2 + gu^2 + gv^2) r2 + 1e-30)``. Requires H, W >= 2.
    """
    h, w = z.shape
    sx, sy = _f32(fx), _f32(fy)
    for r in range(h):
        gu[r, 0] = (z[r, 1] - z[r, 0]) * sx
        for c in range(1, w - 1):
            gu[r, c] = _smaller_diff(z[r, c] - z[r, c - 1], z[r, c + 1] - z[r, c]) * sx
        gu[r, w - 1] = (z[r, w - 1] - z[r, w - 2]) * sx
    for c in range(w):
        gv[0, c] = (z[1, c] - z[0, c]) * sy
        gv[h - 1, c] = (z[h - 1, c] - z[h - 2, c]) * sy
    for r in range(1, h - 1):
        for c in range(w):
            gv[r, c] = _smaller_diff(z[r, c] - z[r - 1, c], z[r + 1, c] - z[r, c]) * sy
    tiny = _f32(1e-30)
    for r in range(h):
        v = vn[r]
        for c in range(w):
            a, b, zc = gu[r, c], gv[r, c], z[r, c]
            o = un[c] * a + zc
            o = o + v * b
            o = o * o
            o = o + a * a
            o = o + b * b
            o = o * r2[r, c] + tiny
            out[r, c] = zc / np.sqrt(o)
    return out


@_jit
def axial_sigma_into(z, angle_term, lo, a, b, c, out):
    """Nguyen's axial std (m): ``out = (angle_term / sqrt(max(z, lo)) + b (z - c)^2) + a``.

    ``angle_term``: the angle term per pixel (``cv2.LUT`` of the incidence level); float32.
    """
    lo, a, b, c = _f32(lo), _f32(a), _f32(b), _f32(c)
    for i in range(z.size):
        zi = z[i]
        dz = zi - c
        out[i] = (angle_term[i] / np.sqrt(zi if zi > lo else lo) + (dz * dz) * b) + a
    return out


@_jit
def disparity_slope_into(z, tan_theta, sin_beta, fb, scale, d_out, slope_out):
    """Disparity ``d = fb / z`` (0 where z is 0: inf, or beyond 1e30, as ``cv2.threshold``
    ``THRESH_TOZERO_INV``) and the bound on its span over a window ``((tan_theta + sin_beta)
    d) scale`` (px); float32."""
    fb, scale, big, zero = _f32(fb), _f32(scale), _f32(1e30), _f32(0.0)
    for i in range(z.size):
        d = fb / z[i]
        d = zero if d > big else d
        d_out[i] = d
        slope_out[i] = ((tan_theta[i] + sin_beta[i]) * d) * scale
    return d_out


@_jit
def pair_with_reciprocal_into(d, pair):
    """``pair[2 i] = d[i]``, ``pair[2 i + 1] = 1 / d[i]`` (inf where d is 0); float32."""
    one = _f32(1.0)
    for i in range(d.size):
        pair[2 * i] = d[i]
        pair[2 * i + 1] = one / d[i]
    return pair


@_jit
def seen_dots_into(d, pattern, sign, dots):
    """(H, W) float32: ``pattern[v, rint(u - sign d)]``, the column wrapped (as ``cv2.remap``
    nearest with ``BORDER_WRAP``, which rounds half to even): the projector dot seen at each
    camera pixel (a table look-up: scalar, unlike the element-wise kernels)."""
    h, w = d.shape
    sgn = _f32(sign)
    for r in range(h):
        for k in range(w):
            col = int(np.rint(_f32(k) - sgn * d[r, k]))
            if col < 0 or col >= w:
                col %= w
            dots[r, k] = pattern[r, col]
    return dots


@_jit
def match_weights_into(d, dots, slope, tol, pair9, dmax17, stack, single):
    """Per-pixel terms of the block matcher, before the window sums.

    ``dots``: 1 where a projector dot is seen; ``wgt = d^2 dots``. With ``tl = slope + tol``
    and ``pair9`` the interleaved 9x9 maxima of ``(d, 1 / d)``: ``single = max d - 1 / max(1
    / d) <= tl`` (the window's disparity span, a pixel without return counting as 0);
    ``near = d >= dmax17 - tl``; ``stack[4 i:4 i + 4] = (wgt, wgt near, wgt d, wgt near d)``.
    """
    tol, one, zero = _f32(tol), _f32(1.0), _f32(0.0)
    for i in range(d.size):
        di = d[i]
        wgt = (di * di) * dots[i]
        tl = slope[i] + tol
        single[i] = np.uint8(pair9[2 * i] - one / pair9[2 * i + 1] <= tl)
        wn = wgt if di >= dmax17[i] - tl else zero
        stack[4 * i] = wgt
        stack[4 * i + 1] = wn
        stack[4 * i + 2] = wgt * di
        stack[4 * i + 3] = wn * di
    return stack


@_jit
def match_decide_into(sums, single, d, min_dots, match_fraction, matched, lost):
    """The winner of each window from its interleaved sums ``(wgt, wn, wd, wnd)``.

    Single-surface windows (``single``): the near class is the whole window. Far class = total
    - near; ``near wins`` if ``wn >= wf``; ``lost`` if the winner holds less than
    ``match_fraction`` of ``wgt``, if ``wgt < min_dots d^2`` (fewer dots' energy than
    ``min_dots`` dots at the pixel's own disparity) or if ``d <= 0``; ``matched`` = the
    winner's weighted mean disparity ``sum / max(win, 1e-12)``.
    """
    frac, eps, nd = _f32(match_fraction), _f32(1e-12), _f32(min_dots)
    for i in range(d.size):
        wgt, wn, wd, wnd = sums[4 * i], sums[4 * i + 1], sums[4 * i + 2], sums[4 * i + 3]
        one_surface = single[i] != 0
        wn = wgt if one_surface else wn
        wnd = wd if one_surface else wnd
        wf = wgt - wn
        win = wn if wn >= wf else wf
        di = d[i]
        lost[i] = (win < wgt * frac) | (wgt < nd * di * di) | (di <= 0)
        total = wnd if wn >= wf else wd - wnd
        matched[i] = total / (win if win >= eps else eps)
    return matched


@_jit
def noisy_depth_into(field, mean, inv_std, base, sigma, matched, q, step, fb_q, out):
    """Depth (m) from the matched disparity plus window-correlated disparity noise.

    ``field``: window sums of random bytes; ``f = (field - mean) inv_std`` (unit variance);
    ``base = d^2 / fb`` (px/m); ``sd = sqrt(max((base sigma)^2 - q, 0))`` with ``q = step^2 /
    12``; noisy disparity ``f sd + matched``, rounded to the ``step`` if ``step > 0`` (in
    units of the step: ``rint(x / step)``, then ``out = fb_q / that`` with ``fb_q = fb /
    step``; without a step ``fb_q = fb``). All float32, flat.
    """
    mean, inv_std, q, zero = _f32(mean), _f32(inv_std), _f32(q), _f32(0.0)
    inv_step, fb_q = _f32(1.0 / step) if step > 0 else _f32(1.0), _f32(fb_q)
    if step > 0:
        for i in range(field.size):
            s = base[i] * sigma[i]
            s = s * s - q
            f = ((field[i] - mean) * inv_std) * np.sqrt(s if s > zero else zero) + matched[i]
            out[i] = fb_q / np.rint(f * inv_step)
    else:
        for i in range(field.size):
            s = base[i] * sigma[i]
            s = s * s - q
            f = ((field[i] - mean) * inv_std) * np.sqrt(s if s > zero else zero) + matched[i]
            out[i] = fb_q / f
    return out


@_jit
def lateral_resample_into(noisy, level, raw, lut, out):
    """``out[v, u] = noisy[v + dy, u + dx]`` (clamped to the image, as ``cv2.remap`` nearest with
    ``BORDER_REPLICATE``), ``dx = lut[level << 8 | raw[4 i]]``, ``dy = lut[level << 8 | raw[4 i
    + 2]]`` for pixel ``i = v W + u``; ``raw``: (4 H W,) uint8 random bytes, ``lut`` (65536,)
    int16 offsets (px)."""
    h, w = noisy.shape
    for r in range(h):
        for k in range(w):
            i = 4 * (r * w + k)
            key = np.int64(level[r, k]) << 8
            x = min(max(k + np.int64(lut[key | raw[i]]), 0), w - 1)
            y = min(max(r + np.int64(lut[key | raw[i + 2]]), 0), h - 1)
            out[r, k] = noisy[y, x]
    return out


@_jit
def projector_lit_into(z, fb, tol, lit):
    """(H, W) bool: ``x(u) < min over u' > u of x(u') - tol`` along each row, ``x(u) = u - d``
    with ``d = fb / z`` (0 where z is 0); the last column is lit. The running minimum is
    exact, so this equals ``np.minimum.accumulate`` over the reversed rows."""
    h, w = z.shape
    fb, tol, big, zero = _f32(fb), _f32(tol), _f32(1e30), _f32(0.0)
    for r in range(h):
        lit[r, w - 1] = True
        d = fb / z[r, w - 1]
        ahead = _f32(w - 1) - (zero if d > big else d)
        for c in range(w - 2, -1, -1):
            d = fb / z[r, c]
            x = _f32(c) - (zero if d > big else d)
            lit[r, c] = x < ahead - tol
            ahead = x if x < ahead else ahead
    return lit
