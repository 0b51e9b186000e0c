"""Procedural printed appearance of household objects: labels, carton prints, glazes.

:func:`make_texture` draws one deterministic RGB texture per ``(kind, seed, colours, size)``
from numpy noise and OpenCV shapes and Hershey text (no files, no fonts), rich in corners for
ORB/SIFT yet small enough for software rendering.

Layout conventions (for the UV mapping of the caller):

* The image is (H, W, 3) uint8 RGB, row 0 = top of the print, column 0 = u = 0. It is
  **seamless in u**: column 0 continues column W - 1, so u wraps once around a cylinder or
  the four sides of a box. Text reads left to right along +u (map +u so that it runs to the
  right when the surface is seen from outside).
* ``carton_print`` and ``box_print``: four faces side by side, each an equal quarter of u,
  in the order front, right, back, left (face k covers ``k W / 4 <= x < (k + 1) W / 4``).
* ``bottle_label``: the whole image is the label band; the brand panel starts at u = 0.
* ``glaze``: the outside of a bowl or mug; ``glass``: the body of a clear juice bottle,
  with a small printed label area somewhere in u.

Colours are RGB floats in [0, 1] (e.g. an instance's ``rgba[:3]``); ``base_rgb`` dominates
the print, ``accent_rgb`` draws bands, badges and patterns (a contrasting ink replaces it
when both are nearly the same).
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from ipbench.assets.objects import texture_parts as tp

__all__ = ["TEXTURE_KINDS", "TextureError", "make_texture"]

TEXTURE_KINDS: tuple[str, ...] = ("bottle_label", "carton_print", "box_print", "glaze", "glass")
_MIN_SIZE, _MAX_SIZE = 32, 2048  # valid range of H and W, px
_AA = cv2.LINE_AA


class TextureError(ValueError):
    """Bad argument to :func:`make_texture` (the message lists the valid values)."""


def _brand_panel(
    img: np.ndarray, rng: np.random.Generator, pal: tp.Palette, y0: float, y1: float, brand: str
) -> None:
    """Logo, brand word and a second line, centred in ``img`` (a panel) between rows y0, y1."""
    w, hh = img.shape[1], y1 - y0
    tp.logo(img, rng, (w / 2, y0 + 0.16 * hh), 0.14 * hh, pal.accent, pal.base)
    font = tp.FONTS[int(rng.integers(len(tp.FONTS)))]
    colour, outline = (pal.accent, pal.ink) if rng.random() < 0.5 else (pal.ink, None)
    if outline is None and rng.random() < 0.4:
        outline = pal.accent
    tp.put_text(img, brand, (w / 2, y0 + 0.52 * hh), (0.88 * w, 0.3 * hh), colour, font, outline)
    line = tp.words(rng, int(rng.integers(2, 4)))
    tp.put_text(img, line, (w / 2, y0 + 0.8 * hh), (0.8 * w, 0.08 * hh), pal.ink)
    ribbon = int(y0 + 0.92 * hh), max(2, int(0.06 * hh))
    cv2.rectangle(
        img,
        (int(0.15 * w), ribbon[0] - ribbon[1]),
        (int(0.85 * w), ribbon[0] + ribbon[1]),
        pal.accent,
        -1,
    )
    tp.put_text(
        img, tp.words(rng, 1).upper(), (w / 2, ribbon[0]), (0.6 * w, 1.3 * ribbon[1]), pal.on_accent
    )


def _fruit_panel(
    img: np.ndarray, rng: np.random.Generator, pal: tp.Palette, y0: float, y1: float
) -> None:
    """A splash with 1-3 shaded fruits in ``img`` (a panel) between rows y0 and y1."""
    w, hh = img.shape[1], y1 - y0
    r = min(0.22 * hh, 0.3 * w)
    tp.splash(img, rng, (w / 2, y0 + 0.55 * hh), 1.1 * r, tp.mix(pal.accent, pal.base, 0.35))
    n = int(rng.integers(1, 4))
    for k in range(n):
        dx = (k - (n - 1) / 2) * 0.9 * r
        tp.fruit(img, (w / 2 + dx, y0 + 0.6 * hh + rng.uniform(-0.1, 0.1) * r), 0.65 * r, pal.pop)


def _info_panel(
    img: np.ndarray,
    rng: np.random.Generator,
    pal: tp.Palette,
    y0: float,
    y1: float,
    barcode: bool,
    table: bool,
) -> None:
    """Small print: a nutrition table or text block, optionally a barcode below."""
    w, hh = img.shape[1], y1 - y0
    m = int(0.08 * w)
    bot = y1 - (0.3 * hh if barcode else 0.0)
    rect = (m, int(y0), w - 2 * m, int(bot - y0 - 0.04 * hh))
    if table:
        tp.text_table(img, rng, rect, pal.ink, int(rng.integers(5, 9)))
    else:
        tp.text_block(img, tp.fork(rng), rect, pal.ink, max(6.0, 0.065 * hh))
    if barcode:
        bw = int(min(0.8 * w, 0.5 * hh))
        tp.barcode(img, tp.fork(rng), ((w - bw) // 2, int(bot), bw, int(0.26 * hh)), pal.ink)


def _bands(img: np.ndarray, rng: np.random.Generator, pal: tp.Palette) -> tuple[float, float]:
    """Straight or wavy accent bands along the top and bottom; returns the free rows."""
    h = img.shape[0]
    top, bot = h * rng.uniform(0.06, 0.12), h * rng.uniform(0.06, 0.12)
    cv2.rectangle(img, (0, 0), (img.shape[1], int(top)), pal.accent, -1)
    if rng.random() < 0.5:
        cv2.rectangle(img, (0, int(h - bot)), (img.shape[1], h), pal.accent, -1)
    else:
        tp.wave_band(
            img,
            h - 0.6 * bot,
            bot,
            0.3 * bot,
            int(rng.integers(2, 6)),
            rng.uniform(0, 6.3),
            pal.accent,
        )
    cv2.line(
        img,
        (0, int(top + 0.03 * h)),
        (img.shape[1], int(top + 0.03 * h)),
        pal.ink,
        max(1, h // 128),
    )
    return top + 0.06 * h, h - 1.4 * bot


def _bottle_label(rng: np.random.Generator, pal: tp.Palette, h: int, w: int) -> np.ndarray:
    img = tp.background(rng, h, w, pal.base, 0.06)
    y0, y1 = _bands(img, rng, pal)
    brand = tp.brand_word(rng)
    fr = rng.uniform([0.34, 0.22, 0.2, 0.14], [0.4, 0.28, 0.26, 0.2])
    (a, b), (c, d), (e, f), (g, k) = tp.panels(w, fr)
    _brand_panel(img[:, a:b], rng, pal, y0, y1, brand)
    _fruit_panel(img[:, c:d], rng, pal, y0, y1)
    _info_panel(img[:, e:f], rng, pal, y0, y1, barcode=False, table=bool(rng.random() < 0.5))
    _info_panel(img[:, g:k], rng, pal, y0, y1, barcode=True, table=False)
    return img


def _faces(
    rng: np.random.Generator,
    pal: tp.Palette,
    img: np.ndarray,
    y0: float,
    y1: float,
    picture: Callable[[np.ndarray], None],
) -> np.ndarray:
    """Fill the 4 faces: front (brand), a side (table), back (picture, brand), a side (text)."""
    brand = tp.brand_word(rng)
    (a, b), (c, d), (e, f), (g, k) = tp.panels(img.shape[1], (1, 1, 1, 1))
    hh = y1 - y0
    _brand_panel(img[:, a:b], rng, pal, y0, y1 - 0.3 * hh, brand)
    sides = [img[:, c:d], img[:, g:k]]
    if rng.random() < 0.5:
        sides.reverse()
    _info_panel(sides[0], rng, pal, y0, y1, barcode=False, table=True)
    _info_panel(sides[1], rng, pal, y0, y1, barcode=True, table=False)
    back = img[:, e:f]
    tp.put_text(
        back,
        brand,
        (back.shape[1] / 2, y0 + 0.1 * hh),
        (0.8 * back.shape[1], 0.14 * hh),
        pal.ink,
        tp.FONTS[int(rng.integers(len(tp.FONTS)))],
    )
    picture(back)
    return img


def _carton_print(rng: np.random.Generator, pal: tp.Palette, h: int, w: int) -> np.ndarray:
    img = tp.background(rng, h, w, pal.base, 0.03)
    band = h * rng.uniform(0.14, 0.22)
    tp.wave_band(
        img,
        h - 0.5 * band,
        band,
        0.15 * band,
        4 * int(rng.integers(1, 3)),
        rng.uniform(0, 6.3),
        pal.accent,
    )
    y0, y1 = 0.06 * h, h - 1.15 * band
    sky, hills = tp.mix(pal.base, (150, 200, 250), 0.5), tp.mix(pal.accent, (60, 160, 60), 0.5)

    def picture(v: np.ndarray) -> None:
        pw = v.shape[1]
        rect = (int(0.1 * pw), int(y0 + 0.25 * (y1 - y0)), int(0.8 * pw), int(0.5 * (y1 - y0)))
        tp.landscape(v, rng, rect, (sky, hills, (250, 220, 60)))

    img = _faces(rng, pal, img, y0, y1, picture)
    front = img[:, : w // 4]  # the front's picture: a small landscape under the brand
    fw = front.shape[1]
    rect = (int(0.2 * fw), int(y1 - 0.28 * (y1 - y0)), int(0.6 * fw), int(0.25 * (y1 - y0)))
    tp.landscape(front, rng, rect, (sky, hills, pal.pop))
    return img


def _box_print(rng: np.random.Generator, pal: tp.Palette, h: int, w: int) -> np.ndarray:
    img = tp.background(rng, h, w, pal.base, 0.1)
    y0, y1 = _bands(img, rng, pal)
    panel = tp.mix(pal.base, (255, 255, 255), 0.35)  # a light panel for the small print
    for x0, x1 in tp.panels(w, (1, 1, 1, 1))[1::2]:
        m = max(2, (x1 - x0) // 16)
        cv2.rectangle(img, (x0 + m, int(y0)), (x1 - m, int(y1)), panel, -1)
    ink, pal.ink = pal.ink, tp.contrast_ink(panel)

    def picture(v: np.ndarray) -> None:
        _fruit_panel(v, rng, pal, y0 + 0.2 * (y1 - y0), y1)

    img = _faces(rng, pal, img, y0, y1, picture)
    pal.ink = ink
    front = img[:, : w // 4]
    _fruit_panel(front, rng, pal, y0 + 0.55 * (y1 - y0), y1 + 0.05 * h)
    return img


def _glaze(rng: np.random.Generator, pal: tp.Palette, h: int, w: int) -> np.ndarray:
    img = tp.background(rng, h, w, pal.base, 0.04).astype(np.float32)
    speck = tp.mix(pal.base, pal.ink, rng.uniform(0.5, 0.8))  # iron specks of stoneware
    sub = tp.fork(rng)  # size-dependent draw counts: keep the rest of the design fixed
    img[sub.random((h, w), dtype=np.float32) < sub.uniform(0.003, 0.015)] = speck
    for x, y in sub.random((int(h * w * sub.uniform(2e-4, 6e-4)), 2)) * [w, h]:
        for dx in (-w, 0, w):  # bigger specks, drawn 3x to wrap
            cv2.circle(img, (int(x) + dx, int(y)), 1 + int(x) % 2, speck, -1)
    img = tp.wrap_blur(np.clip(img, 0, 255).astype(np.uint8), 0.6)
    style = rng.choice(
        ["plain", "crackle", "bands", "dots", "motif"], p=[0.2, 0.15, 0.25, 0.2, 0.2]
    )
    dark = tp.mix(pal.base, (0, 0, 0), 0.35)
    if style == "crackle":
        for _ in range(int(rng.integers(12, 30))):  # random-walk hairlines, drawn 3x to wrap
            steps = rng.normal(0, 1, (12, 2)) * [w / 40, h / 40] + [w / 60, 0]
            pts = np.cumsum(steps, axis=0) + rng.random(2) * [w, h]
            for dx in (-w, 0, w):
                cv2.polylines(img, [(pts + [dx, 0]).round().astype(np.int32)], False, dark, 1, _AA)
    elif style == "bands":
        y = h * rng.uniform(0.05, 0.2)
        for _ in range(int(rng.integers(2, 5))):
            t = max(1, int(h * rng.uniform(0.01, 0.08)))
            cv2.rectangle(img, (0, int(y)), (w, int(y) + t), pal.accent, -1)
            y += t + h * rng.uniform(0.05, 0.25)
    elif style in ("dots", "motif"):
        n = int(rng.integers(6, 14)) if style == "dots" else int(rng.integers(3, 7))
        rows = int(rng.integers(2, 5)) if style == "dots" else 1
        r = 0.3 * w / n if style == "dots" else min(0.3 * w / n, 0.25 * h)
        for j in range(rows):
            y = h * (j + 0.5) / rows if style == "dots" else h * rng.uniform(0.35, 0.6)
            for i in range(n):
                x = w * (i + 0.5 * (1 + j % 2)) / n  # staggered, inside the period
                if style == "dots":
                    for dx in (-w, 0, w):
                        cv2.circle(img, (int(x) + dx, int(y)), max(1, int(r)), pal.accent, -1, _AA)
                else:
                    tp.logo(img, rng, (x, y), r, pal.accent, tp.mix(pal.base, pal.accent, 0.2))
        if style == "motif":
            for y in (h * 0.12, h * 0.88):
                cv2.line(img, (0, int(y)), (w, int(y)), pal.accent, max(1, h // 60), _AA)
    return img


def _glass(rng: np.random.Generator, pal: tp.Palette, h: int, w: int) -> np.ndarray:
    img = tp.background(rng, h, w, pal.base, 0.05, pulp=0.06)
    x = np.arange(w) / w
    hl = np.clip(np.cos(2 * np.pi * (x - rng.random())), 0, 1) ** 12  # a vertical highlight
    cols = np.flatnonzero(hl > 0.004)
    a = np.float32(0.45) * hl[cols].astype(np.float32)[None, :, None]
    img[:, cols] = img[:, cols] * (1 - a) + 255 * a
    light = tp.mix(pal.base, (255, 255, 255), 0.6)
    for _ in range(int(rng.integers(10, 25))):  # bubbles near the top
        c = (int(rng.random() * w), int(rng.uniform(0.05, 0.35) * h))
        rad = max(1, int(rng.uniform(0.006, 0.02) * h))
        for dx in (-w, 0, w):
            cv2.circle(img, (c[0] + dx, c[1]), rad, light, 1, _AA)
    lw, lh = int(w * rng.uniform(0.25, 0.35)), int(h * rng.uniform(0.35, 0.5))
    lx, ly = int(rng.uniform(0.05, 0.6) * w), int(rng.uniform(0.1, 0.9 - lh / h) * h)
    paper = tp.mix(pal.base, (250, 250, 245), rng.uniform(0.55, 0.85))
    shadow = tp.mix(pal.base, (0, 0, 0), 0.5)
    cv2.rectangle(img, (lx + 2, ly + 2), (lx + lw + 2, ly + lh + 2), shadow, -1)  # embossed
    cv2.rectangle(img, (lx, ly), (lx + lw, ly + lh), paper, -1)
    cv2.rectangle(img, (lx, ly), (lx + lw, ly + lh), pal.accent, max(1, h // 80))
    label = img[ly : ly + lh, lx : lx + lw]
    lpal = tp.Palette(rng, np.divide(paper, 255.0), np.divide(pal.accent, 255.0))
    _brand_panel(label, rng, lpal, 0.06 * lh, 0.94 * lh, tp.brand_word(rng))
    return img


_MAKERS = {
    "bottle_label": _bottle_label,
    "carton_print": _carton_print,
    "box_print": _box_print,
    "glaze": _glaze,
    "glass": _glass,
}


def _check_colour(name: str, value: object) -> tuple[float, float, float]:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        arr = np.full(0, np.nan)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)) or arr.min() < 0 or arr.max() > 1:
        raise TextureError(f"{name} must be 3 RGB floats in [0, 1] (e.g. rgba[:3]), got {value!r}")
    return (float(arr[0]), float(arr[1]), float(arr[2]))


def make_texture(
    kind: str,
    seed: int,
    base_rgb: tuple[float, float, float],
    accent_rgb: tuple[float, float, float],
    size: tuple[int, int] = (256, 256),
) -> np.ndarray:
    """One procedural texture: (H, W, 3) uint8 RGB, C-contiguous, ``(H, W) = size`` px.

    ``kind`` is one of :data:`TEXTURE_KINDS`; ``seed`` (an int >= 0) draws the design (the
    same arguments give the same bytes); ``base_rgb`` / ``accent_rgb`` are RGB in [0, 1];
    H and W are ints in 32-2048. See the module docstring for the
    layout in u and v. Raises :class:`TextureError` on a bad argument.
    """
    if not isinstance(kind, str) or kind not in _MAKERS:
        raise TextureError(f"unknown texture kind {kind!r}; valid kinds: {list(TEXTURE_KINDS)}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise TextureError(f"seed must be an int >= 0, got {seed!r}")
    ok = isinstance(size, tuple | list) and len(size) == 2
    if not ok or not all(
        isinstance(s, int | np.integer) and not isinstance(s, bool) and _MIN_SIZE <= s <= _MAX_SIZE
        for s in size
    ):
        raise TextureError(
            f"size must be (H, W) with ints in [{_MIN_SIZE}, {_MAX_SIZE}] px, got {size!r}"
        )
    base, accent = _check_colour("base_rgb", base_rgb), _check_colour("accent_rgb", accent_rgb)
    rng = np.random.default_rng([int(seed), TEXTURE_KINDS.index(kind)])  # kinds differ
    img = _MAKERS[kind](rng, tp.Palette(rng, base, accent), int(size[0]), int(size[1]))
    return np.ascontiguousarray(img, dtype=np.uint8)
