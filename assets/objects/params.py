"""Shape parameters of the five categories and how they are drawn from real-world ranges.

Each category has a frozen dataclass of dimensions (metres). A sampler draws one from a
:class:`numpy.random.Generator` together with the mass (kg), the colours (RGBA in [0, 1]) and
whether the surface is glazed. Ranges are typical household sizes (engineering estimates; the
sourced v2 families are in :mod:`ipbench.assets.objects.families`):

* juice bottle (PET): diameter 65-90 mm, height 200-290 mm with the cap, filled 0.5-1.05 kg.
  The filled mass is drawn uniformly, then diameter and proportions are drawn until the
  height that holds that much juice (1040 kg/m^3 in the body, shoulder and neck, plus a
  35 g bottle) is in range: light bottles come out slim and short.
* milk carton (gable top): square base 70-95 mm, total height 220-265 mm, filled 1.0-1.5 kg
  (milk 1030 kg/m^3 up to the shoulder, plus a 30 g carton): the mass is drawn uniformly,
  then bases until the shoulder height that holds it gives a total height in range (heavy
  cartons get wide bases; a 95 mm base only fits a mass near 1.5 kg).
* bowl: rim diameter 140-170 mm, height 50-80 mm, wall 4.5-5.5 mm, 0.25-0.40 kg.
* mug: diameter 75-90 mm, height 90-110 mm, wall 4.5-5.5 mm, handle reach 30-35 mm,
  0.30-0.35 kg.
* juice box (Tetra Brik): interpolates from 63 x 40 x 88 mm to 53 x 38 x 110 mm
  (width x depth x height), a straw glued on the +y face, 0.20-0.23 kg.

Bowl, mug and juice-box masses grow with size (plus a little noise) inside their range.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "BottleShape",
    "CartonShape",
    "BowlShape",
    "MugShape",
    "JuiceBoxShape",
    "Shape",
    "Sample",
    "MASS_RANGES",
    "sample_shape",
]

_RGBA = tuple[float, float, float, float]

MASS_RANGES: dict[str, tuple[float, float]] = {
    "juice_bottle": (0.50, 1.05),
    "milk_carton": (1.00, 1.50),
    "bowl": (0.25, 0.40),
    "mug": (0.30, 0.35),
    "juice_box": (0.20, 0.23),
}
"""Mass range per category, kg."""


@dataclass(frozen=True)
class BottleShape:
    """PET juice bottle; heights measured from the bottom, m."""

    radius: float  # body
    height: float  # total, with the cap
    body_top: float  # where the shoulder starts
    neck_bottom: float  # where the shoulder ends
    neck_radius: float
    cap_bottom: float
    cap_radius: float
    label_bottom: float
    label_top: float


@dataclass(frozen=True)
class CartonShape:
    """Gable-top carton; the ridge runs along x, m."""

    base: float  # side of the square base
    shoulder: float  # height of the box part
    gable: float  # rise of the roof above the shoulder
    fin: float  # height of the sealed fin above the ridge
    fin_thickness: float
    band_bottom: float
    band_top: float


@dataclass(frozen=True)
class BowlShape:
    """Conical bowl; the wall is straight in profile, m."""

    rim_radius: float  # outer radius at the rim
    foot_radius: float  # radius of the flat bottom
    height: float  # total
    wall: float  # wall thickness
    bottom: float  # bottom thickness


@dataclass(frozen=True)
class MugShape:
    """Cylindrical mug with a D-shaped handle on +x, m."""

    radius: float  # outer
    height: float
    wall: float
    bottom: float
    handle_reach: float  # how far the handle sticks out of the wall
    handle_radius: float  # radius of the handle's round section
    handle_top: float  # height of the upper attachment
    handle_bottom: float  # height of the lower attachment


@dataclass(frozen=True)
class JuiceBoxShape:
    """Tetra Brik box with a straw glued diagonally on its +y face, m."""

    width: float  # x
    depth: float  # y
    height: float  # z
    straw_radius: float
    straw_margin: float  # distance of the straw ends from the face's edges
    straw_mirror: bool  # straw rising towards -x instead of +x


Shape = BottleShape | CartonShape | BowlShape | MugShape | JuiceBoxShape


@dataclass(frozen=True)
class Sample:
    """What a sampler draws for one instance (colours are RGBA in [0, 1], mass in kg)."""

    shape: Shape
    mass: float
    rgba: _RGBA
    accent_rgba: _RGBA
    specular: bool


_JUICE = [(1.0, 0.55, 0.05), (0.98, 0.82, 0.18), (0.78, 0.1, 0.12), (0.5, 0.75, 0.2)]
_CAPS = [(0.95, 0.95, 0.95), (0.1, 0.5, 0.15), (0.95, 0.45, 0.05), (0.8, 0.1, 0.1), (0.1, 0.2, 0.6)]
_BANDS = [
    (0.1, 0.3, 0.75),
    (0.8, 0.12, 0.12),
    (0.15, 0.55, 0.2),
    (0.95, 0.75, 0.1),
    (0.1, 0.6, 0.8),
]
_CERAMIC = [
    (0.95, 0.95, 0.92),
    (0.93, 0.88, 0.76),
    (0.55, 0.72, 0.85),
    (0.12, 0.22, 0.45),
    (0.55, 0.65, 0.5),
    (0.75, 0.38, 0.25),
    (0.15, 0.15, 0.15),
    (0.6, 0.6, 0.62),
    (0.95, 0.8, 0.3),
    (0.9, 0.6, 0.65),
]
_BRIGHT = [(1.0, 0.5, 0.0), (1.0, 0.85, 0.0), (0.9, 0.1, 0.2), (0.2, 0.75, 0.2), (0.6, 0.2, 0.7)]


def _colour(rng: np.random.Generator, palette: list, jitter: float = 0.04) -> _RGBA:
    base = np.asarray(palette[int(rng.integers(len(palette)))], float)
    rgb = np.clip(base + rng.uniform(-jitter, jitter, 3), 0.0, 1.0)
    return (float(rgb[0]), float(rgb[1]), float(rgb[2]), 1.0)


def _graded_mass(category: str, size01: float, rng: np.random.Generator) -> float:
    lo, hi = MASS_RANGES[category]
    t = float(np.clip(0.8 * size01 + 0.2 * rng.random(), 0.0, 1.0))
    return lo + (hi - lo) * t


def _bottle(rng: np.random.Generator) -> Sample:
    lo, hi = MASS_RANGES["juice_bottle"]
    found = False
    while not found:  # draw the filled mass, then proportions and the height that holds it
        mass = rng.uniform(lo, hi)
        for _ in range(500):
            r = rng.uniform(0.0325, 0.045)
            cap_r, cap_h = rng.uniform(0.0145, 0.0195), rng.uniform(0.014, 0.022)
            neck_r = cap_r - 0.0015
            neck_h = rng.uniform(0.008, 0.018)
            frac = rng.uniform(0.22, 0.35)  # shoulder share of the height below the neck
            # volume = length * per_length + neck, length = height below the neck
            per_length = np.pi * (r * r * (1 - frac) + frac / 3 * (r * r + r * neck_r + neck_r**2))
            neck = np.pi * neck_r**2 * neck_h
            length = ((mass - 0.035) / 1040.0 - neck) / per_length
            if 0.200 <= length + neck_h + cap_h <= 0.290:
                found = True
                break
    h = length + neck_h + cap_h
    neck_bottom = length
    body_top = (1 - frac) * length
    label_bottom = body_top * rng.uniform(0.15, 0.3)
    label_top = body_top * rng.uniform(0.7, 0.9)
    shape = BottleShape(
        r, h, body_top, neck_bottom, neck_r, h - cap_h, cap_r, label_bottom, label_top
    )
    return Sample(shape, float(mass), _colour(rng, _JUICE), _colour(rng, _CAPS), False)


def _carton(rng: np.random.Generator) -> Sample:
    lo, hi = MASS_RANGES["milk_carton"]
    found = False
    while not found:  # draw the filled mass, then a base and the shoulder that holds it
        mass = rng.uniform(lo, hi)
        for _ in range(500):
            base = rng.uniform(0.070, 0.095)
            gable = 0.5 * base * np.tan(np.radians(rng.uniform(30.0, 40.0)))
            fin = rng.uniform(0.007, 0.010)
            shoulder = (mass - 0.030) / (1030.0 * base * base)
            if 0.220 <= shoulder + gable + fin <= 0.265:
                found = True
                break
    band_bottom = shoulder * rng.uniform(0.35, 0.5)
    band_top = band_bottom + shoulder * rng.uniform(0.15, 0.3)
    shape = CartonShape(
        base, shoulder, gable, fin, rng.uniform(0.002, 0.003), band_bottom, band_top
    )
    white = _colour(rng, [(0.95, 0.95, 0.93)], 0.02)
    return Sample(shape, float(mass), white, _colour(rng, _BANDS), False)


def _bowl(rng: np.random.Generator) -> Sample:
    rim, height = rng.uniform(0.070, 0.085), rng.uniform(0.050, 0.080)
    foot = rim * rng.uniform(0.38, 0.5)
    shape = BowlShape(rim, foot, height, rng.uniform(0.0045, 0.0055), rng.uniform(0.006, 0.009))
    size01 = 0.5 * (rim - 0.070) / 0.015 + 0.5 * (height - 0.050) / 0.030
    inner = _colour(rng, _CERAMIC) if rng.random() < 0.4 else None
    outer = _colour(rng, _CERAMIC)
    return Sample(shape, _graded_mass("bowl", size01, rng), outer, inner or outer, True)


def _mug(rng: np.random.Generator, index: int) -> Sample:
    r, height = rng.uniform(0.0375, 0.045), rng.uniform(0.090, 0.110)
    shape = MugShape(
        radius=r,
        height=height,
        wall=rng.uniform(0.0045, 0.0055),
        bottom=rng.uniform(0.006, 0.009),
        handle_reach=rng.uniform(0.030, 0.035),
        handle_radius=rng.uniform(0.0045, 0.006),
        handle_top=height * rng.uniform(0.75, 0.85),
        handle_bottom=height * rng.uniform(0.2, 0.3),
    )
    size01 = 0.5 * (r - 0.0375) / 0.0075 + 0.5 * (height - 0.090) / 0.020
    outer = _colour(rng, _CERAMIC)
    inner = _colour(rng, _CERAMIC) if rng.random() < 0.4 else outer
    glazed = index % 4 != 3  # instances 3, 7 and 11 are matte stoneware
    return Sample(shape, _graded_mass("mug", size01, rng), outer, inner, glazed)


def _juice_box(rng: np.random.Generator) -> Sample:
    t = rng.random()
    small, tall = np.array([0.063, 0.040, 0.088]), np.array([0.053, 0.038, 0.110])
    w, d, h = small + t * (tall - small)
    shape = JuiceBoxShape(
        float(w),
        float(d),
        float(h),
        straw_radius=rng.uniform(0.002, 0.0028),
        straw_margin=rng.uniform(0.006, 0.010),
        straw_mirror=bool(rng.random() < 0.5),
    )
    return Sample(
        shape, _graded_mass("juice_box", t, rng), _colour(rng, _BRIGHT), _straw(rng), False
    )


def _straw(rng: np.random.Generator) -> _RGBA:
    return _colour(rng, [(0.95, 0.95, 0.95), (0.95, 0.9, 0.6), (0.9, 0.3, 0.5)], 0.02)


def sample_shape(category: str, index: int, rng: np.random.Generator) -> Sample:
    """Draw one instance of ``category`` (a valid name) from ``rng``.

    ``index`` only decides the documented matte mugs (index % 4 == 3).
    """
    if category == "juice_bottle":
        return _bottle(rng)
    if category == "milk_carton":
        return _carton(rng)
    if category == "bowl":
        return _bowl(rng)
    if category == "mug":
        return _mug(rng, index)
    if category == "juice_box":
        return _juice_box(rng)
    raise ValueError(f"unknown category {category!r}")
