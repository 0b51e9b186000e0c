"""Drawing helpers of :mod:`ipbench.assets.objects.textures` (numpy + OpenCV only).

Images are (H, W, 3) uint8 RGB arrays, row 0 at the top; colours passed to the drawers are
RGB tuples in 0-255 (floats allowed). Coordinates are pixels, ``(x, y)`` = (column, row). The
noise fields are periodic in x (u), so whatever they fill wraps seamlessly around a cylinder;
the shape drawers clip at the borders of the array they are given, which may be a column
slice (a view) of a larger image, e.g. one panel of a label.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

__all__ = [
    "FONTS",
    "FRUITS",
    "Palette",
    "background",
    "fork",
    "panels",
    "Rgb",
    "barcode",
    "brand_word",
    "contrast_ink",
    "fruit",
    "landscape",
    "logo",
    "mix",
    "periodic_noise",
    "put_text",
    "splash",
    "text_block",
    "text_table",
    "wave_band",
    "wrap_blur",
    "words",
]

Rgb = tuple[float, float, float]
"""An RGB colour, 0-255 per channel."""

FONTS: tuple[int, ...] = (
    cv2.FONT_HERSHEY_SIMPLEX,
    cv2.FONT_HERSHEY_DUPLEX,
    cv2.FONT_HERSHEY_COMPLEX,
    cv2.FONT_HERSHEY_TRIPLEX,
    cv2.FONT_HERSHEY_SCRIPT_COMPLEX,
    cv2.FONT_HERSHEY_DUPLEX | cv2.FONT_ITALIC,
    cv2.FONT_HERSHEY_TRIPLEX | cv2.FONT_ITALIC,
)
"""Hershey fonts for brand words (the small print uses SIMPLEX / PLAIN)."""

_ONSETS = ("b", "d", "f", "g", "k", "l", "m", "n", "p", "r", "s", "t", "v", "z", "br", "st", "tr")
_VOWELS = ("a", "e", "i", "o", "u", "a", "o", "y")
_CODAS = ("", "", "", "n", "r", "x", "l", "s")
_AA = cv2.LINE_AA


def mix(a: Rgb, b: Rgb, t: float) -> Rgb:
    """Linear blend ``(1 - t) a + t b`` of two RGB colours."""
    return tuple(float((1.0 - t) * x + t * y) for x, y in zip(a, b, strict=True))  # type: ignore[return-value]


def contrast_ink(bg: Rgb) -> Rgb:
    """A dark or light ink, of ``bg``'s hue, that reads well on ``bg`` (luma contrast)."""
    luma = 0.299 * bg[0] + 0.587 * bg[1] + 0.114 * bg[2]
    return mix(bg, (20.0, 20.0, 25.0), 0.85) if luma > 110 else mix(bg, (250.0, 250.0, 245.0), 0.9)


def periodic_noise(rng: np.random.Generator, h: int, w: int, cells: tuple[int, int]) -> np.ndarray:
    """(h, w) float32 value noise in ~[0, 1], smooth over ``cells`` = (rows, cols) cells.

    Bicubic interpolation of a random grid, three periods side by side, to at most 1/4 of
    the size, then bilinear to (h, w) and the middle period cut out: periodic in x, column
    0 continues column w - 1.
    """
    grid = rng.random((max(cells[0], 1) + 1, max(cells[1], 1)), dtype=np.float32)
    ws, hs = max(w // 4, 4 * grid.shape[1]), max(h // 4, 4 * grid.shape[0])
    small = cv2.resize(np.tile(grid, (1, 3)), (3 * ws, hs), interpolation=cv2.INTER_CUBIC)
    big = cv2.resize(small, (3 * w, h), interpolation=cv2.INTER_LINEAR)
    return big[:, w : 2 * w]


def wrap_blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian blur (``sigma`` px) that wraps around in x (seamless), replicating in y."""
    pad = int(3 * sigma) + 1
    big = cv2.copyMakeBorder(img, 0, 0, pad, pad, cv2.BORDER_WRAP)
    return np.ascontiguousarray(cv2.GaussianBlur(big, (0, 0), sigma)[:, pad:-pad])


def _syllables(rng: np.random.Generator, n: int) -> str:
    on = rng.integers(len(_ONSETS), size=n)
    vo = rng.integers(len(_VOWELS), size=n)
    return "".join(_ONSETS[i] + _VOWELS[j] for i, j in zip(on, vo, strict=True))


def brand_word(rng: np.random.Generator) -> str:
    """A pronounceable 2-3 syllable word, upper or title case (e.g. ``"BRAVOLIN"``)."""
    n = int(rng.integers(2, 4))
    word = _syllables(rng, n) + _CODAS[int(rng.integers(len(_CODAS)))]
    return word.upper() if rng.random() < 0.6 else word.title()


def words(rng: np.random.Generator, n: int) -> str:
    """``n`` short random words and numbers, e.g. ``"dravo 12g tesa"`` (small print)."""
    out = []
    for _ in range(n):
        r = rng.random()
        if r < 0.2:
            out.append(f"{int(rng.integers(1, 999))}{rng.choice(['g', 'mg', '%', 'ml', ''])}")
        else:
            out.append(_syllables(rng, int(rng.integers(1, 3))))
    text = " ".join(out)
    return text.upper() if rng.random() < 0.3 else text


def put_text(
    img: np.ndarray,
    text: str,
    center: tuple[float, float],
    box: tuple[float, float],
    colour: Rgb,
    font: int = cv2.FONT_HERSHEY_SIMPLEX,
    outline: Rgb | None = None,
) -> tuple[int, int]:
    """Draw ``text`` centred at ``center``, scaled to fit ``box`` = (width, height) px.

    The stroke grows with the size; ``outline`` draws a contrasting rim around the strokes.
    Returns the drawn (width, height) in px.
    """
    (w1, h1), _ = cv2.getTextSize(text, font, 1.0, 1)
    scale = max(min(box[0] / max(w1, 1), box[1] / max(h1, 1)), 0.05)
    thick = max(1, int(round(scale * 1.6)))
    (tw, th), _ = cv2.getTextSize(text, font, scale, thick)
    org = (int(center[0] - tw / 2), int(center[1] + th / 2))
    if outline is not None:
        cv2.putText(img, text, org, font, scale, outline, thick + 2 + thick // 2, _AA)
    cv2.putText(img, text, org, font, scale, colour, thick, _AA)
    return tw, th


def logo(
    img: np.ndarray,
    rng: np.random.Generator,
    center: tuple[float, float],
    r: float,
    fg: Rgb,
    bg: Rgb,
) -> None:
    """A badge of radius ``r`` px: a disc or ring with a star, polygon or initial inside."""
    c = (int(center[0]), int(center[1]))
    cv2.circle(img, c, int(r), bg, -1, _AA)
    cv2.circle(img, c, int(r), fg, max(1, int(r / 8)), _AA)
    kind = int(rng.integers(3))
    n = int(rng.integers(5, 9))
    ang = rng.uniform(0, 2 * np.pi) + np.linspace(0, 2 * np.pi, 2 * n, endpoint=False)
    if kind == 0:  # star
        rad = np.where(np.arange(2 * n) % 2 == 0, 0.72 * r, 0.32 * r)
    elif kind == 1:  # polygon
        ang, rad = ang[::2], np.full(n, 0.62 * r)
    else:  # an initial on a small disc
        cv2.circle(img, c, int(0.6 * r), fg, -1, _AA)
        letter = chr(int(rng.integers(65, 91)))
        put_text(img, letter, center, (0.8 * r, 0.7 * r), bg, cv2.FONT_HERSHEY_DUPLEX)
        return
    pts = np.column_stack([center[0] + rad * np.cos(ang), center[1] + rad * np.sin(ang)])
    cv2.fillPoly(img, [pts.round().astype(np.int32)], fg, _AA)


def fruit(img: np.ndarray, center: tuple[float, float], r: float, colour: Rgb) -> None:
    """A shaded fruit-like disc of radius ``r`` px with a highlight, leaf and stem."""
    cx, cy = center
    dark, light = mix(colour, (0, 0, 0), 0.45), mix(colour, (255, 255, 255), 0.35)
    cv2.circle(img, (int(cx), int(cy)), int(r), dark, -1, _AA)
    for k in range(1, 5):  # shading: shrinking discs moving towards the highlight
        t = k / 4
        c = (int(cx - 0.25 * r * t), int(cy - 0.25 * r * t))
        cv2.circle(img, c, max(1, int(r * (1 - 0.55 * t))), mix(colour, light, t), -1, _AA)
    hl = (int(cx - 0.4 * r), int(cy - 0.4 * r))
    cv2.ellipse(
        img, hl, (max(1, int(0.2 * r)), max(1, int(0.1 * r))), -40, 0, 360, (255, 255, 250), -1, _AA
    )
    top = (int(cx), int(cy - r))
    cv2.line(
        img, top, (int(cx + 0.1 * r), int(cy - 1.3 * r)), (90, 60, 30), max(1, int(r / 8)), _AA
    )
    leaf = (int(cx + 0.35 * r), int(cy - 1.15 * r))
    cv2.ellipse(
        img,
        leaf,
        (max(1, int(0.35 * r)), max(1, int(0.14 * r))),
        -25,
        0,
        360,
        (40, 140, 50),
        -1,
        _AA,
    )


def splash(
    img: np.ndarray, rng: np.random.Generator, center: tuple[float, float], r: float, colour: Rgb
) -> None:
    """An irregular splash blob of mean radius ``r`` px with a few drops around it."""
    n = 24
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    rad = r * (0.75 + 0.45 * rng.random(n)) * np.where(np.arange(n) % 3 == 0, 1.25, 1.0)
    pts = np.column_stack([center[0] + rad * np.cos(ang), center[1] + 0.8 * rad * np.sin(ang)])
    cv2.fillPoly(img, [pts.round().astype(np.int32)], colour, _AA)
    for _ in range(int(rng.integers(3, 7))):
        a, d = rng.uniform(0, 2 * np.pi), r * rng.uniform(1.3, 1.7)
        c = (int(center[0] + d * np.cos(a)), int(center[1] + 0.8 * d * np.sin(a)))
        cv2.circle(img, c, max(1, int(r * rng.uniform(0.06, 0.14))), colour, -1, _AA)


def barcode(
    img: np.ndarray, rng: np.random.Generator, rect: tuple[int, int, int, int], ink: Rgb
) -> None:
    """A barcode on a white patch in ``rect`` = (x, y, width, height) px, digits below."""
    x, y, w, h = rect
    cv2.rectangle(img, (x, y), (x + w, y + h), (250, 250, 250), -1)
    unit = max(1, w // 60)
    bx, bh = x + 2 * unit, int(h * 0.72)
    while bx < x + w - 3 * unit:
        bw = unit * int(rng.integers(1, 4))
        if rng.random() < 0.55:
            cv2.rectangle(img, (bx, y + unit), (bx + bw - 1, y + bh), ink, -1)
        bx += bw
    digits = "".join(str(d) for d in rng.integers(0, 10, 12))
    put_text(
        img, digits, (x + w / 2, y + 0.86 * h), (0.9 * w, 0.2 * h), ink, cv2.FONT_HERSHEY_PLAIN
    )


def text_block(
    img: np.ndarray,
    rng: np.random.Generator,
    rect: tuple[int, int, int, int],
    ink: Rgb,
    line_h: float,
) -> None:
    """Left-aligned lines of small print (``line_h`` px per line) filling ``rect``."""
    x, y, w, h = rect
    font = cv2.FONT_HERSHEY_SIMPLEX
    scale = max(line_h / 30.0, 0.2)
    for k in range(max(1, int(h // line_h))):
        text = words(rng, int(rng.integers(3, 7)))
        (tw, _), _ = cv2.getTextSize(text, font, scale, 1)
        while tw > w and " " in text:  # drop words until the line fits
            text = text.rsplit(" ", 1)[0]
            (tw, _), _ = cv2.getTextSize(text, font, scale, 1)
        cv2.putText(img, text, (x, int(y + (k + 0.8) * line_h)), font, scale, ink, 1, _AA)


def text_table(
    img: np.ndarray,
    rng: np.random.Generator,
    rect: tuple[int, int, int, int],
    ink: Rgb,
    rows: int,
) -> None:
    """A framed nutrition-facts-like table of ``rows`` rows (name left, amount right)."""
    x, y, w, h = rect
    cv2.rectangle(img, (x, y), (x + w, y + h), ink, max(1, w // 60))
    row_h = h / (rows + 1)
    put_text(
        img,
        words(rng, 2).upper(),
        (x + w / 2, y + row_h / 2),
        (0.8 * w, 0.6 * row_h),
        ink,
        cv2.FONT_HERSHEY_DUPLEX,
    )
    font = cv2.FONT_HERSHEY_SIMPLEX
    for k in range(1, rows + 1):
        ry = int(y + k * row_h)
        cv2.line(img, (x, ry), (x + w, ry), ink, 1)
        base = int(ry + 0.75 * row_h)
        amount = f"{rng.uniform(0, 40):.1f}{rng.choice(['g', 'mg', '%'])}"
        for text, left in ((words(rng, 1), True), (amount, False)):  # name | amount halves
            (tw, th), _ = cv2.getTextSize(text, font, 1.0, 1)
            scale = max(min(0.6 * row_h / th, (0.45 * w - 3) / tw), 0.15)
            tx = x + 3 if left else x + w - 3 - int(tw * scale)
            cv2.putText(img, text, (tx, base), font, scale, ink, 1, _AA)


def wave_band(
    img: np.ndarray, y: float, thick: float, amp: float, periods: int, phase: float, colour: Rgb
) -> None:
    """A horizontal band ``thick`` px thick around ``y`` that undulates ``amp`` px with an
    integer number of ``periods`` across the full width (so it wraps seamlessly)."""
    w = img.shape[1]
    xs = np.arange(-2, w + 3, 2, dtype=np.float64)
    mid = y + amp * np.sin(2 * np.pi * periods * xs / w + phase)
    top = np.column_stack([xs, mid - thick / 2])
    bottom = np.column_stack([xs[::-1], mid[::-1] + thick / 2])
    cv2.fillPoly(img, [np.vstack([top, bottom]).round().astype(np.int32)], colour, _AA)


def landscape(
    img: np.ndarray,
    rng: np.random.Generator,
    rect: tuple[int, int, int, int],
    colours: tuple[Rgb, Rgb, Rgb],
) -> None:
    """A framed picture in ``rect`` = (x, y, w, h) px: sky, a sun and 2-3 layers of hills.

    ``colours`` = (sky, hills, sun); the nearer hills are darker.
    """
    x, y, w, h = rect
    sky, hills, sun = colours
    cv2.rectangle(img, (x, y), (x + w, y + h), sky, -1)
    sc = (int(x + w * rng.uniform(0.2, 0.8)), int(y + h * rng.uniform(0.2, 0.4)))
    cv2.circle(img, sc, max(2, int(h * rng.uniform(0.1, 0.18))), sun, -1, _AA)
    xs = np.linspace(x, x + w, 24)
    layers = int(rng.integers(2, 4))
    for k in range(layers):
        y0 = (
            y
            + h * (0.45 + 0.18 * k)
            + h * 0.08 * np.sin(xs / w * rng.uniform(3, 8) + rng.uniform(0, 6))
        )
        pts = np.vstack([np.column_stack([xs, y0]), [[x + w, y + h], [x, y + h]]])
        tone = mix(hills, (0, 0, 0), 0.15 * k)
        cv2.fillPoly(img, [pts.round().astype(np.int32)], tone, _AA)
    cv2.rectangle(img, (x, y), (x + w, y + h), mix(hills, (0, 0, 0), 0.5), max(1, w // 50))


FRUITS: tuple[Rgb, ...] = (
    (240, 120, 20),
    (220, 30, 40),
    (250, 210, 30),
    (110, 190, 40),
    (120, 40, 130),
    (250, 160, 60),
)
"""Fruit colours of the pictures (RGB 0-255)."""


class Palette:
    """The colours of one texture, 0-255: base, accent, ink (readable on base), pop (fruit)."""

    def __init__(self, rng: np.random.Generator, base: Sequence[float], accent: Sequence[float]):
        self.base: Rgb = tuple(255.0 * float(c) for c in base)  # type: ignore[assignment]
        acc: Rgb = tuple(255.0 * float(c) for c in accent)  # type: ignore[assignment]
        if float(np.abs(np.subtract(acc, self.base)).sum()) < 90.0:  # too close: contrast
            acc = mix(self.base, contrast_ink(self.base), 0.7)
        self.accent = acc
        self.ink = contrast_ink(self.base)
        self.on_accent = contrast_ink(acc)
        self.pop = FRUITS[int(rng.integers(len(FRUITS)))]


def fork(rng: np.random.Generator) -> np.random.Generator:
    """A child generator (one draw of ``rng``) for parts whose number of draws depends on
    the size, so that one seed gives the same design at every size."""
    return np.random.default_rng(int(rng.integers(2**63)))


def background(
    rng: np.random.Generator, h: int, w: int, colour: Rgb, var: float, pulp: float = 0.0
) -> np.ndarray:
    """(h, w, 3) uint8 of ``colour`` with low-frequency shading (+-``var``), paper grain and,
    if ``pulp`` > 0, a +-``pulp`` fine mottling (6 px cells)."""
    shade = periodic_noise(rng, h, w, (3, 6))  # shade in 1/200 units: uint8 holds 0-1.27
    shade *= np.float32(400.0 * var)
    shade += np.float32(200.0 * (1.0 - var - pulp) - 3.0)
    sub = fork(rng)
    shade += sub.random((h, w), dtype=np.float32) * np.float32(6.0)  # grain: +-1.5 %
    if pulp > 0:
        fine = periodic_noise(sub, h, w, (max(1, h // 6), max(1, w // 6)))
        shade += fine * np.float32(400.0 * pulp)
    gain = np.asarray(colour, np.float32).reshape(3, 1) / np.float32(200.0)
    return cv2.transform(cv2.convertScaleAbs(shade)[:, :, None], gain)  # saturates to 0-255


def panels(w: int, fractions: Sequence[float]) -> list[tuple[int, int]]:
    """Split [0, w) into consecutive (x0, x1) panels of the given (normalised) fractions."""
    edges = np.round(np.cumsum([0.0, *fractions]) / sum(fractions) * w).astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True)]
