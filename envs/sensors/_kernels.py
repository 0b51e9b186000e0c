"""Compiled per-pixel kernels of the depth sensor model (numba, single-threaded, no fast-math).

Each kernel fuses a chain of array operations of :mod:`ipbench.envs.sensors.depth_noise` or
:mod:`ipbench.envs.sensors.structured_light` into one pass over the image, with the same float32
operations in the same order, so its output is bit-identical to the chain it replaces (the
digest tests of both modules hold it to that); the chain is written in each docstring. One pass
instead of ~10 keeps the image in cache: 3-5x faster than the vectorised numpy/OpenCV chain on
the 2-core reference machine. No fast-math: no reassociation and no fused multiply-adds, so
the results do not depend on the processor's vector width. Compiled on first use and cached
next to this file (``cache=True``; a read-only install compiles once per process).

Element-wise kernels take flat views (``a.reshape(-1)`` of C-contiguous images) and never
write in place of an input: LLVM then vectorises them (a 2-D loop, a table look-up or an
aliased output keeps them scalar, 5-10x slower). Table look-ups stay in ``cv2.LUT``. Row-wise
kernels index row views ``a[r]`` (flat) with a loop variable, ``4 c + channel`` for
interleaved channels, and offsets as views (``a[k:]``): an index that LLVM cannot prove
non-negative keeps numba's negative-index check, which keeps the loop scalar (2-10x slower).
The block matcher's window sums (:func:`match_into`) repeat OpenCV's unnormalised
``boxFilter`` operation for operation, streamed row by row through a ring of row sums.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = [
    "axial_sigma_into",
    "cos_incidence_into",
    "disparity_slope_into",
    "lateral_resample_into",
    "match_into",
    "noisy_depth_into",
    "projector_lit_into",
    "reciprocal_into",
    "seen_dots_into",
    "shadowed_depth_into",
    "specular_drop_into",
]

_jit = numba.njit(cache=True, nogil=True, error_model="numpy")
_part = numba.njit(nogil=True, error_model="numpy")  # a part of kernels
_f32 = np.float32


@numba.njit(inline="always")
def _smaller_diff(back, fwd):
    """The one-sided difference of smaller magnitude, as ``back + (fwd - back) * cond``."""
    cond = _f32(1.0) if abs(fwd) < abs(back) else _f32(0.0)
    return back + (fwd - back) * cond


@numba.njit(inline="always")
def _reflect101(i, n):
    """``i`` reflected into ``[0, n)`` without repeating the edge (``cv2.borderInterpolate``
    with ``BORDER_REFLECT_101``: -1 -> 1, n -> n - 2)."""
    if n == 1:
        return 0
    while i < 0 or i >= n:
        i = -i if i < 0 else 2 * n - 2 - i
    return i


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
def reciprocal_into(x, out):
    """``out = 1 / x`` (float32, inf where x is 0), flat."""
    one = _f32(1.0)
    for i in range(x.size):
        out[i] = one / x[i]
    return out


@_part
def _match_terms_row(d, dots, slope, dmax2, tol, a, pad):
    """One row's four block-matching terms as float64 into ``pad`` (4 (W + 2a),), interleaved,
    with ``a`` reflected columns on each side (``BORDER_REFLECT_101``): ``wgt = d^2 dots``,
    ``wn = wgt`` where ``d >= dmax2 - (slope + tol)`` (else 0), ``wgt d``, ``wn d`` (float32).
    (Indices ``4 c + channel`` of a loop variable ``c``: LLVM then proves them non-negative and
    drops numba's negative-index checks, which keep a loop scalar; offsets are views.)"""
    w, zero, mid = d.size, _f32(0.0), pad[4 * a :]
    for c in range(w):
        di = d[c]
        wgt = (di * di) * dots[c]
        tl = slope[c] + tol
        wn = wgt if di >= dmax2[c] - tl else zero
        mid[4 * c] = wgt
        mid[4 * c + 1] = wn
        mid[4 * c + 2] = wgt * di
        mid[4 * c + 3] = wn * di
    right = pad[4 * (a + w) :]
    for j in range(a):
        src_l, src_r = 4 * _reflect101(j - a, w), 4 * _reflect101(w + j, w)
        for ch in range(4):
            pad[4 * j + ch] = mid[src_l + ch]
            right[4 * j + ch] = mid[src_r + ch]


@_part
def _row_sums4(pad, k, row):
    """k-wide window sums of the 4-channel row ``pad`` (4 (W + k - 1),) (float64, reflected
    borders) into ``row`` (4 W,), as OpenCV's ``RowSum<float, double>``: k = 3, 5 summed
    directly, else a running sum per channel, ``s += pad[j + k] - pad[j]`` (float64, in this
    order)."""
    w = row.size // 4
    if k == 3:
        p1, p2 = pad[4:], pad[8:]
        for i in range(4 * w):
            row[i] = (pad[i] + p1[i]) + p2[i]
        return
    if k == 5:
        p1, p2, p3, p4 = pad[4:], pad[8:], pad[12:], pad[16:]
        for i in range(4 * w):
            row[i] = (((pad[i] + p1[i]) + p2[i]) + p3[i]) + p4[i]
        return
    s0 = s1 = s2 = s3 = 0.0
    for j in range(k):
        s0 += pad[4 * j]
        s1 += pad[4 * j + 1]
        s2 += pad[4 * j + 2]
        s3 += pad[4 * j + 3]
    row[0], row[1], row[2], row[3] = s0, s1, s2, s3
    ahead, out = pad[4 * k :], row[4:]
    for c in range(w - 1):
        s0 += ahead[4 * c] - pad[4 * c]
        s1 += ahead[4 * c + 1] - pad[4 * c + 1]
        s2 += ahead[4 * c + 2] - pad[4 * c + 2]
        s3 += ahead[4 * c + 3] - pad[4 * c + 3]
        out[4 * c], out[4 * c + 1], out[4 * c + 2], out[4 * c + 3] = s0, s1, s2, s3


@_part
def _decide_row(sums, d, slope, dmax, rmax, tol, nd, frac, matched, lost):
    """One row's winners from its window sums ``(wgt, wn, wd, wnd)`` (:func:`match_into`)."""
    one, eps = _f32(1.0), _f32(1e-12)
    for c in range(d.size):
        wgt, wn, wd, wnd = sums[4 * c], sums[4 * c + 1], sums[4 * c + 2], sums[4 * c + 3]
        one_surface = dmax[c] - one / rmax[c] <= slope[c] + tol
        wn = wgt if one_surface else wn
        wnd = wd if one_surface else wnd
        wf = wgt - wn
        win = wn if wn >= wf else wf
        di = d[c]
        lost[c] = (win < wgt * frac) | (wgt < nd * di * di) | (di <= 0)
        total = wnd if wn >= wf else wd - wnd
        matched[c] = total / (win if win >= eps else eps)


@_jit
def match_into(d, dots, slope, tol, dmax, rmax, dmax2, k, min_dots, frac, matched, lost, bufs):
    """Block matching of a disparity image ``d`` (H, W) float32: window sums and winners.

    Terms per pixel (``dots``: 1 where a projector dot is seen): ``wgt = d^2 dots``; with ``tl
    = slope + tol``, ``near = d >= dmax2 - tl``; the channels ``(wgt, wn = wgt near, wd = wgt
    d, wnd = wn d)``, float32. Their k x k window sums are ``cv2.boxFilter(terms, -1, (k, k),
    normalize=False)``'s operation for operation: float64 row sums (:func:`_row_sums4`), then
    float64 running column sums, ``s = sum + new`` rounded to float32 and ``sum = s - old``,
    started from 0 with the first k - 1 rows, rows and columns reflected (``REFLECT_101``).

    Winner: a window whose disparity span ``dmax - 1 / rmax`` (k x k maxima of d and of 1 /
    d) is within ``tl`` is one surface (the near class is the whole window); else far class =
    ``wgt - wn``, ``near wins`` if ``wn >= wf``. ``lost`` if the winner holds less than
    ``frac`` of ``wgt``, if ``wgt < min_dots d^2`` or if ``d <= 0``; ``matched`` = the
    winner's weighted mean ``sum / max(win, 1e-12)``. ``bufs = (ring, colsum, pad, sums)``:
    float64 (k, 4 W) (the row sums of the last k rows), (4 W,) (their running column sums) and
    (4 (W + k - 1),) (a padded row of terms), float32 (4 W,) (a row's window sums); channels
    interleaved. Rows are streamed: the terms of a row are made where they are summed (twice
    for the k - 1 rows reflected at the borders).
    """
    h, w = d.shape
    a, w4 = k // 2, 4 * w
    tol, frac, nd = _f32(tol), _f32(frac), _f32(min_dots)
    ring, colsum, pad, sums = bufs
    for e in range(-a, h + a):  # rows of the image reflected by a rows; output row e - a
        y = _reflect101(e, h)
        _match_terms_row(d[y], dots[y], slope[y], dmax2[y], tol, a, pad)
        row = ring[(e + a) % k]
        _row_sums4(pad, k, row)
        if e < a:  # the first k - 1 rows start the column sums
            if e == -a:
                colsum[:] = 0.0
            for i in range(w4):
                colsum[i] += row[i]
            continue
        old = ring[(e + a + 1) % k]  # the row sums of row e - (k - 1)
        for i in range(w4):
            s = colsum[i] + row[i]
            sums[i] = np.float32(s)
            colsum[i] = s - old[i]
        r = e - a
        _decide_row(sums, d[r], slope[r], dmax[r], rmax[r], tol, nd, frac, matched[r], lost[r])
    return matched


@numba.njit(inline="always")
def _noisy_value(field, mean, inv_std, d, inv_fb, sigma, matched, q, inv_step, fb_q, quantise):
    """One pixel of :func:`noisy_depth_into`."""
    zero = _f32(0.0)
    s = ((inv_fb * d) * d) * sigma
    s = s * s - q
    f = ((field - mean) * inv_std) * np.sqrt(s if s > zero else zero) + matched
    return fb_q / np.rint(f * inv_step) if quantise else fb_q / f


@_jit
def noisy_depth_into(field, mean, inv_std, d, inv_fb, sigma, matched, q, step, fb_q, out):
    """Depth (m) from the matched disparity plus window-correlated disparity noise.

    ``field``: window sums of random bytes; ``f = (field - mean) inv_std`` (unit variance);
    ``base = (inv_fb d) d = d^2 / fb`` (px/m; ``cv2.multiply(d, d, scale=inv_fb)``); ``sd =
    sqrt(max((base sigma)^2 - q, 0))`` with ``q = step^2 / 12``; noisy disparity ``f sd +
    matched``, rounded to the ``step`` if ``step > 0`` (in units of the step: ``rint(x /
    step)``, then ``out = fb_q / that`` with ``fb_q = fb / step``; without a step ``fb_q =
    fb``). All float32, flat.
    """
    mean, inv_std, inv_fb, q, fb_q = _f32(mean), _f32(inv_std), _f32(inv_fb), _f32(q), _f32(fb_q)
    inv_step = _f32(1.0 / step) if step > 0 else _f32(1.0)
    if step > 0:
        for i in range(field.size):
            f, di, si, mi = field[i], d[i], sigma[i], matched[i]
            out[i] = _noisy_value(f, mean, inv_std, di, inv_fb, si, mi, q, inv_step, fb_q, True)
    else:
        for i in range(field.size):
            f, di, si, mi = field[i], d[i], sigma[i], matched[i]
            out[i] = _noisy_value(f, mean, inv_std, di, inv_fb, si, mi, q, inv_step, fb_q, False)
    return out


@_jit
def noisy_depth_drop_into(field, noise, d, sigma, matched, drop, out):
    """:func:`noisy_depth_into`, then 0 where the depth is missing: ``drop = (z, lost, cos,
    cos_graze, extra, lo, hi)`` drops pixels with ``z <= 0``, ``lost``, ``cos < cos_graze``
    (float32; -inf: none), ``extra`` (bool, e.g. specular) or the depth outside ``[lo, hi]``
    (``np.copyto(out, 0, where=...)``). ``noise = (mean, inv_std, inv_fb, q, step, fb_q)``:
    :func:`noisy_depth_into`'s numbers. All flat."""
    mean, inv_std, inv_fb, q, step, fb_q = noise
    z, lost, cosv, cos_graze, extra, lo, hi = drop
    mean, inv_std, inv_fb, q, fb_q = _f32(mean), _f32(inv_std), _f32(inv_fb), _f32(q), _f32(fb_q)
    inv_step = _f32(1.0 / step) if step > 0 else _f32(1.0)
    cos_graze, lo, hi, zero = _f32(cos_graze), _f32(lo), _f32(hi), _f32(0.0)
    if step > 0:
        for i in range(field.size):
            f, di, si, mi = field[i], d[i], sigma[i], matched[i]
            x = _noisy_value(f, mean, inv_std, di, inv_fb, si, mi, q, inv_step, fb_q, True)
            gone = (z[i] <= zero) | lost[i] | (cosv[i] < cos_graze) | extra[i]
            out[i] = zero if gone | (x < lo) | (x > hi) else x
    else:
        for i in range(field.size):
            f, di, si, mi = field[i], d[i], sigma[i], matched[i]
            x = _noisy_value(f, mean, inv_std, di, inv_fb, si, mi, q, inv_step, fb_q, False)
            gone = (z[i] <= zero) | lost[i] | (cosv[i] < cos_graze) | extra[i]
            out[i] = zero if gone | (x < lo) | (x > hi) else x
    return out


@_jit
def specular_drop_into(specular, cosv, cos_face, blobs, out):
    """(H, W) bool: the specular pixels that are missing, ``specular & (cos > cos_face | blob >
    0.5)`` (a mirror highlight where they face the camera, or inside a random blob). ``blobs =
    (use, field, dy, dx)``: ``blob[r, c] = field[r + dy, c + dx]`` (float32; not used if not
    ``use``)."""
    use, field, dy, dx = blobs
    face, half = _f32(cos_face), _f32(0.5)
    h, w = specular.shape
    for r in range(h):
        s, cr, o = specular[r], cosv[r], out[r]
        if use:
            blob = field[r + dy][dx:]
            for c in range(w):
                o[c] = s[c] & ((cr[c] > face) | (blob[c] > half))
        else:
            for c in range(w):
                o[c] = s[c] & (cr[c] > face)
    return out


@_jit
def lateral_resample_into(noisy, level, raw, lut, unit, out, scratch):
    """Lateral noise, then the unit's error (``apply_unit`` and the range cut after it).

    ``v[r, k] = noisy[r + dy, k + dx]`` (clamped to the image, as ``cv2.remap`` nearest with
    ``BORDER_REPLICATE``) in ``scratch``, ``dx = lut[level << 8 | raw[4 i]]``, ``dy =
    lut[level << 8 | raw[4 i + 2]]`` for pixel ``i = r W + k``; ``raw``: (4 H W,) uint8 random
    bytes, ``lut`` (65536,) int16 offsets (px). ``unit = (scaled, scale, offset, sx, sy, hi)``:
    if ``scaled``, ``v = v scale`` (float32), ``+ offset`` where v was > 0, 0 where not > 0;
    then ``out[r, k] = v[r - sy, k - sx]`` (0 outside) and 0 where ``> hi`` (``scaled =
    False``, ``sx = sy = 0``, ``hi = inf``: no unit, and ``scratch`` may be ``out``). The
    gather is a table look-up (scalar); the unit's pass is element-wise.
    """
    scaled, scale, offset, sx, sy, hi = unit
    scale, offset, hi, zero = _f32(scale), _f32(offset), _f32(hi), _f32(0.0)
    h, w = noisy.shape
    for r in range(h):
        lv, rw, v = level[r], raw[4 * w * r :], scratch[r]
        for k in range(w):
            key = np.int64(lv[k]) << 8
            x = min(max(k + np.int64(lut[key | rw[4 * k]]), 0), w - 1)
            y = min(max(r + np.int64(lut[key | rw[4 * k + 2]]), 0), h - 1)
            v[k] = noisy[y, x]
    if not scaled and sx == 0 and sy == 0 and hi == np.inf:
        if scratch is not out:  # (numba: the same array or not)
            out[:] = scratch
        return out
    k0, k1 = max(sx, 0), min(w + sx, w)  # the columns with a source column
    for r in range(h):
        o, y0 = out[r], r - sy
        if y0 < 0 or y0 >= h or k0 >= k1:
            for k in range(w):
                o[k] = zero
            continue
        for k in range(k0):
            o[k] = zero
        for k in range(k1, w):
            o[k] = zero
        src, dst = scratch[y0][k0 - sx :], o[k0:]
        if scaled:
            for k in range(k1 - k0):
                x = src[k]
                u = x * scale
                u = u + offset if x > zero else u
                u = u if u > zero else zero
                dst[k] = zero if u > hi else u
        else:
            for k in range(k1 - k0):
                x = src[k]
                dst[k] = zero if x > hi else x
    return out


@_jit
def shadowed_depth_into(z, fb, tol, mirror, out, scratch):
    """``out = z * lit`` (float32): z where the projector lights the pixel, by
    :func:`projector_lit_into`'s test (``mirror``: on the image mirrored left-right, i.e. the
    projector on the other side), else 0. ``scratch``: (4, W) float32; four rows' running
    minima at a time (independent chains)."""
    h, w = z.shape
    fb, tol, big, zero, one = _f32(fb), _f32(tol), _f32(1e30), _f32(0.0), _f32(1.0)
    x0, x1, x2, x3 = scratch[0], scratch[1], scratch[2], scratch[3]
    for r0 in range(0, h, 4):
        rows = min(4, h - r0)
        for j in range(4):  # x(p) = p - d along the scan, p from the projector's far side
            zr, xs = z[r0 + min(j, rows - 1)], scratch[j]
            if mirror:
                for p in range(w):
                    d = fb / zr[w - 1 - p]
                    xs[p] = _f32(p) - (zero if d > big else d)
            else:
                for p in range(w):
                    d = fb / zr[p]
                    xs[p] = _f32(p) - (zero if d > big else d)
        a0, a1, a2, a3 = x0[w - 1], x1[w - 1], x2[w - 1], x3[w - 1]
        for p in range(w - 2, -1, -1):  # x(p) < min over p' > p of x(p') - tol: lit
            v0, v1, v2, v3 = x0[p], x1[p], x2[p], x3[p]
            x0[p] = one if v0 < a0 - tol else zero
            x1[p] = one if v1 < a1 - tol else zero
            x2[p] = one if v2 < a2 - tol else zero
            x3[p] = one if v3 < a3 - tol else zero
            a0, a1 = (v0 if v0 < a0 else a0), (v1 if v1 < a1 else a1)
            a2, a3 = (v2 if v2 < a2 else a2), (v3 if v3 < a3 else a3)
        x0[w - 1] = x1[w - 1] = x2[w - 1] = x3[w - 1] = one
        for j in range(rows):
            zr, o, lit = z[r0 + j], out[r0 + j], scratch[j]
            if mirror:
                for c in range(w):
                    o[c] = zr[c] * lit[w - 1 - c]
            else:
                for c in range(w):
                    o[c] = zr[c] * lit[c]
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
