"""The compiled sensor kernels against the numpy/OpenCV chains they replace, bit for bit.

The stored digests (``test_structured_light.py``) hold the whole model on five images and the
default window; these tests hold each fused stage on adversarial inputs (wide dynamic range,
holes, other window sizes, both projector sides, odd image sizes, every bit generator), where
a reordered floating-point sum or a skipped random word would show.
"""

import cv2
import numpy as np
import pytest

from ipbench.envs.sensors.depth_noise import (
    STRUCTURED_LIGHT,
    DepthNoiseConfig,
    DepthNoiseModel,
    _random_bytes,
    _random_words,
)
from ipbench.envs.sensors.structured_light import (
    BlockMatcher,
    UnitError,
    apply_unit,
    dot_pattern,
    noisy_depth,
    projector_visible,
    shadowed_depth,
)

F32 = np.float32


def disparities(shape, seed):
    """Disparities over 5 decades (px) with 10 % holes: float64 sums of them are not exact."""
    rng = np.random.default_rng(seed)
    d = np.exp(rng.uniform(-3, 8, shape)) * (rng.random(shape) > 0.1)
    return d.astype(F32), (rng.random(shape) * 3).astype(F32)


def reference_match(d, slope, sign, k, tol=1.0, min_dots=4, frac=2.0 / 3.0):
    """The matcher as a numpy/OpenCV chain (dilations, 4-channel box filter, float32 rule)."""
    h, w = d.shape
    kernel = np.ones((k, k), np.uint8)
    with np.errstate(divide="ignore"):
        pair9 = cv2.dilate(np.dstack([d, F32(1) / d]), kernel)
    dmax17 = cv2.dilate(np.ascontiguousarray(pair9[..., 0]), kernel)
    cols = np.rint(np.arange(w, dtype=F32) - F32(sign) * d).astype(np.int64) % w
    dots = dot_pattern((h, w))[np.arange(h)[:, None], cols]
    wgt, tl = (d * d) * dots, slope + F32(tol)
    single = pair9[..., 0] - F32(1) / pair9[..., 1] <= tl
    wn = np.where(d >= dmax17 - tl, wgt, F32(0))
    stack = np.ascontiguousarray(np.dstack([wgt, wn, wgt * d, wn * d]))
    wgt, wn, wd, wnd = np.moveaxis(cv2.boxFilter(stack, -1, (k, k), normalize=False), 2, 0)
    wn, wnd = np.where(single, wgt, wn), np.where(single, wd, wnd)
    wf = wgt - wn
    near = wn >= wf
    win = np.where(near, wn, wf)
    lost = (win < wgt * F32(frac)) | (wgt < F32(min_dots - 0.5) * d * d) | (d <= 0)
    total = np.where(near, wnd, wd - wnd)
    return total / np.maximum(win, F32(1e-12)), lost


def same_bits(a, b):
    return a.dtype == b.dtype and np.array_equal(a.view(np.uint8), b.view(np.uint8))


@pytest.mark.parametrize("k", [3, 5, 7, 9, 11])
@pytest.mark.parametrize("sign", [1, -1])
@pytest.mark.parametrize("shape", [(480, 640), (37, 23)])
def test_block_matcher_equals_the_opencv_chain(k, sign, shape):
    d, slope = disparities(shape, seed=k + sign)
    matched, lost = BlockMatcher(window_px=k).match(d, slope, sign)
    want_matched, want_lost = reference_match(d, slope, sign, k)
    assert same_bits(matched, want_matched)
    np.testing.assert_array_equal(lost, want_lost)


def test_noisy_depth_equals_the_opencv_chain():
    rng = np.random.default_rng(3)
    d, _ = disparities((120, 160), seed=3)
    matched = (d + rng.normal(0, 0.3, d.shape)).astype(F32)
    sigma = (rng.random(d.shape) * 0.01).astype(F32)
    random_bytes = rng.integers(0, 256, d.shape, dtype=np.uint8)
    fb, k = 43.5, 9
    for step in (0.125, 0.0):
        got = noisy_depth(random_bytes, sigma, d, matched, fb, step, k, np.empty_like(d))
        field = cv2.boxFilter(random_bytes, cv2.CV_32F, (k, k), normalize=False)
        f = (field - F32(k * k * 127.5)) * F32(1 / (k * np.sqrt((256**2 - 1) / 12.0)))
        s = cv2.multiply(d, d, scale=1.0 / fb) * sigma
        s = s * s - F32(step**2 / 12)
        x = f * np.sqrt(np.maximum(s, F32(0))) + matched
        with np.errstate(divide="ignore"):
            want = F32(fb / step) / np.rint(x * F32(1 / step)) if step else F32(fb) / x
        assert same_bits(got, want), step


@pytest.mark.parametrize("baseline", [0.075, -0.075])
@pytest.mark.parametrize("shape", [(480, 640), (7, 5)])
def test_shadowed_depth_is_depth_times_projector_visible(baseline, shape):
    rng = np.random.default_rng(5)
    z = (rng.uniform(0.4, 4.0, shape) * (rng.random(shape) > 0.05)).astype(F32)
    z[: shape[0] // 2, shape[1] // 3 : shape[1] // 2] = 0.5  # an occluder
    got = shadowed_depth(z, 570.0, baseline, np.empty_like(z))
    want = np.multiply(z, projector_visible(z, 570.0, baseline), dtype=F32)
    assert same_bits(got, want)


@pytest.mark.parametrize(
    "unit",
    [
        UnitError(-0.0034, 0.0068, (-1, -2)),
        UnitError(0.01, -0.01, (0, 0)),
        UnitError(0.0, 0.0, (2, 1)),
        UnitError(0.0, 0.005, (700, 0)),
        UnitError(0.0, 0.0, (0, 0)),
        UnitError(-0.4, -0.9, (0, -3)),
    ],
)
def test_unit_error_in_the_lateral_pass_equals_apply_unit(unit):
    """The unit's error is applied in the lateral resampling's pass: the same as applying
    ``apply_unit`` and the range cut to the image without it (the model before fusing)."""
    model = DepthNoiseModel(STRUCTURED_LIGHT)
    z = np.random.default_rng(6).uniform(0.45, 3.6, (120, 160)).astype(F32)
    got = model.apply(z, 570.0, 570.0, np.random.default_rng(1), unit=unit)
    want = apply_unit(model.apply(z, 570.0, 570.0, np.random.default_rng(1)), unit)
    want = cv2.threshold(want, float(F32(STRUCTURED_LIGHT.max_range_m)), 0, cv2.THRESH_TOZERO_INV)
    assert same_bits(got, want[1])


def test_specular_mask_equals_the_numpy_chain():
    rng = np.random.default_rng(8)
    cosv = rng.random((60, 80)).astype(F32)
    specular = rng.random((60, 80)) < 0.5
    for dropout in (0.3, 0.0):
        model = DepthNoiseModel(DepthNoiseConfig(specular_dropout=dropout))
        model.apply(np.ones((60, 80), F32), 570.0, 570.0, np.random.default_rng(0))
        got = model._specular_mask(cosv, np.random.default_rng(2), specular, model._ws).copy()
        use, field, dy, dx = model._blobs(cosv.shape, np.random.default_rng(2), model._ws)
        drop = cosv > model._cos_face
        if use:
            drop |= field[dy : dy + 60, dx : dx + 80] > F32(0.5)
        np.testing.assert_array_equal(got, specular & drop)


def plain(state):
    """A bit generator's state with its arrays as lists (comparable with ``==``)."""
    if isinstance(state, dict):
        return {key: plain(value) for key, value in state.items()}
    return state.tolist() if isinstance(state, np.ndarray) else state


BIT_GENERATORS = [np.random.PCG64, np.random.PCG64DXSM, np.random.SFC64, np.random.MT19937]


@pytest.mark.parametrize("bit_generator", BIT_GENERATORS)
@pytest.mark.parametrize("n", [640 * 480, 1001, 3])
@pytest.mark.parametrize("half_word", [False, True])
def test_random_bytes_skip_words_but_not_the_stream(bit_generator, n, half_word):
    """The bytes of the spans are those of the full draw, and the generator ends where the full
    draw leaves it (also with a buffered 32-bit half word, which ``advance`` would drop)."""
    a, b = np.random.Generator(bit_generator(11)), np.random.Generator(bit_generator(11))
    if half_word:
        for g in (a, b):
            g.integers(0, 2**32, size=3, dtype=np.uint32)
    spans = [(0, n), (2 * n, 6 * n)]
    got = _random_bytes(a, n, spans)
    raw = _random_words(b, n).view(np.uint8)
    for (start, stop), part in zip(spans, got, strict=True):
        np.testing.assert_array_equal(part, raw[start:stop])
    assert plain(a.bit_generator.state) == plain(b.bit_generator.state)
    assert (
        a.integers(0, 2**32, size=5, dtype=np.uint32).tolist()
        == b.integers(0, 2**32, size=5, dtype=np.uint32).tolist()
    )
