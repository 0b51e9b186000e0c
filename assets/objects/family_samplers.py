"""Draw one v2 instance of a family (ranges and sources: :mod:`.families`).

Each sampler draws the nominal volume and the dimensions the sources give, solves the free
height for the volume (drinks) or rejects draws whose brimful capacity falls outside the
published one (bowls, mugs), and sets the mass from the contents plus the container (drinks)
or from the ceramic shell's volume (bowls, mugs). :func:`capacity` is the inner volume the
checks use.
"""

from __future__ import annotations

import numpy as np

from ipbench.assets.objects.families import FAMILY_SPECS, FamilySpec
from ipbench.assets.objects.family_shapes import (
    BrikShape,
    FootedBowlShape,
    ProfileMugShape,
    SquareBottleShape,
)
from ipbench.assets.objects.params import (
    _BANDS,
    _BRIGHT,
    _CAPS,
    _CERAMIC,
    _JUICE,
    BottleShape,
    BowlShape,
    CartonShape,
    Sample,
    _colour,
    _straw,
)

__all__ = ["sample_family", "capacity", "revolved_volume"]

_JUICE_RHO, _MILK_RHO = 1040.0, 1030.0  # kg/m^3, as v1
_ML = 1e-6  # m^3 per ml


def revolved_volume(polygon: np.ndarray) -> float:
    """Volume (m^3) swept by a closed (r, z) polygon (m) revolving about the z axis (Pappus)."""
    p = np.asarray(polygon, float)
    r, z = p[:, 0], p[:, 1]
    r1, z1 = np.roll(r, -1), np.roll(z, -1)
    cross = r * z1 - r1 * z
    area = cross.sum() / 2
    centroid_r = ((r + r1) * cross).sum() / (6 * area)
    return float(abs(2 * np.pi * centroid_r * area))


def _mug_radius(s: ProfileMugShape, z: float) -> float:
    h2 = s.height / 2
    if z <= h2:
        return s.radius_bottom + (s.radius_middle - s.radius_bottom) * z / h2
    return s.radius_middle + (s.radius_top - s.radius_middle) * (z - h2) / h2


def _bowl_inner(rim, foot, h, t, tb, z0=0.0):
    beta = np.arctan2(rim - foot, h - tb)
    c = np.cos(beta)
    return [(0, z0 + tb), (foot - t * c, z0 + tb), (rim - t * c, z0 + h), (0, z0 + h)]


def _bowl_outer(rim, foot, h, t, tb, z0=0.0):
    beta = np.arctan2(rim - foot, h - tb)
    c, sn = np.cos(beta), np.sin(beta)
    return [
        (0, z0),
        (foot, z0),
        (foot, z0 + tb - t * sn),
        (rim, z0 + h - t * sn),
        (rim - t * c, z0 + h),
    ]


def _mug_section(s: ProfileMugShape) -> tuple[list, list]:
    """(outer, inner) (r, z) profiles of a profile mug."""
    zs = (0.0, s.height / 2, s.height)
    outer = [(_mug_radius(s, z), z) for z in zs]
    zi = (s.bottom, s.height / 2, s.height)
    inner = [(_mug_radius(s, z) - s.wall, z) for z in zi]
    return outer, inner


def capacity(shape) -> float:
    """Brimful inner volume of a container shape, m^3 (thin-walled drinks: the outer volume
    below the neck; briks and cartons: below the top / shoulder)."""
    if isinstance(shape, BottleShape | SquareBottleShape):
        r = shape.radius if isinstance(shape, BottleShape) else shape.side / 2
        area = np.pi * r * r
        if isinstance(shape, SquareBottleShape):
            area = shape.side**2 - (4 - np.pi) * shape.corner_radius**2
        rn = shape.neck_radius
        frac_area = area / (np.pi * r * r)
        shoulder = np.pi * (shape.neck_bottom - shape.body_top) / 3 * (r * r + r * rn + rn * rn)
        return float(area * shape.body_top + frac_area * shoulder)
    if isinstance(shape, CartonShape):
        return float(shape.base**2 * shape.shoulder)
    if isinstance(shape, BowlShape):
        s = shape
        return revolved_volume(_bowl_inner(s.rim_radius, s.foot_radius, s.height, s.wall, s.bottom))
    if isinstance(shape, FootedBowlShape):
        s = shape
        h = s.height - s.foot_height
        return revolved_volume(_bowl_inner(s.rim_radius, s.bowl_radius, h, s.wall, s.bottom))
    if isinstance(shape, ProfileMugShape):
        _, inner = _mug_section(shape)
        return revolved_volume([(0.0, inner[0][1]), *inner, (0.0, inner[-1][1])])
    if isinstance(shape, BrikShape):
        area = shape.width * shape.depth - 2 * shape.chamfer**2
        return float(area * shape.height)
    raise TypeError(f"no capacity for {type(shape).__name__}")


def _in(value_m: float, mm: tuple[float, float]) -> bool:
    return mm[0] * 1e-3 - 1e-9 <= value_m <= mm[1] * 1e-3 + 1e-9


def _holds(volume: float, ml: tuple[float, float]) -> bool:
    return ml[0] * _ML <= volume <= ml[1] * _ML


def _bottle(rng: np.random.Generator, spec: FamilySpec, glass: bool) -> Sample:
    while True:
        nominal = rng.uniform(*spec.nominal_ml) * _ML
        if glass:
            r = rng.uniform(*spec.footprint_mm) * 5e-4
            neck_r = rng.uniform(0.013, 0.019)  # wide-mouth juice finish (38 mm) [EST]
            cap_r, cap_h = neck_r + 0.0015, rng.uniform(0.012, 0.016)
            frac = rng.uniform(0.10, 0.22)
        else:
            t = (nominal / _ML - 500.0) / 500.0  # 0.5 L: Ø 65-70, 1 L: Ø 80-90 (families.py)
            r = rng.uniform(0.0325 + 0.0075 * t, 0.035 + 0.010 * t)
            cap_r = rng.uniform(0.0145, 0.0195)
            neck_r, cap_h = cap_r - 0.0015, rng.uniform(0.014, 0.022)
            frac = rng.uniform(0.22, 0.35)
        neck_h = rng.uniform(0.008, 0.018)
        brim = nominal * rng.uniform(1.03, 1.08)  # headspace [EST]
        per_length = np.pi * (r * r * (1 - frac) + frac / 3 * (r * r + r * neck_r + neck_r**2))
        length = brim / per_length
        h = length + neck_h + cap_h
        if _in(h, spec.height_mm):
            break
    body_top, label_bottom = (1 - frac) * length, 0.0
    label_bottom = body_top * rng.uniform(0.15, 0.3)
    label_top = body_top * rng.uniform(0.7, 0.9)
    shape = BottleShape(r, h, body_top, length, neck_r, h - cap_h, cap_r, label_bottom, label_top)
    tare = rng.uniform(0.20, 0.29) if glass else rng.uniform(0.020, 0.040)
    mass = nominal * _JUICE_RHO + tare
    return Sample(shape, float(mass), _colour(rng, _JUICE), _colour(rng, _CAPS), False)


def _square_bottle(rng: np.random.Generator, spec: FamilySpec) -> Sample:
    while True:
        nominal = rng.uniform(*spec.nominal_ml) * _ML
        side, corner = rng.uniform(*spec.footprint_mm) * 1e-3, rng.uniform(0.008, 0.014)
        cap_r = rng.uniform(0.0145, 0.0195)
        neck_r, cap_h, neck_h = cap_r - 0.0015, rng.uniform(0.014, 0.022), rng.uniform(0.008, 0.018)
        frac = rng.uniform(0.18, 0.30)
        area = side**2 - (4 - np.pi) * corner**2
        rr = side / 2
        shoulder_per = area / (np.pi * rr * rr) * np.pi / 3 * (rr * rr + rr * neck_r + neck_r**2)
        length = nominal * rng.uniform(1.03, 1.08) / (area * (1 - frac) + shoulder_per * frac)
        h = length + neck_h + cap_h
        if _in(h, spec.height_mm):
            break
    body_top = (1 - frac) * length
    shape = SquareBottleShape(
        side, corner, h, body_top, length, neck_r, h - cap_h, cap_r,
        body_top * rng.uniform(0.15, 0.3), body_top * rng.uniform(0.7, 0.9),
    )  # fmt: skip
    mass = nominal * _JUICE_RHO + rng.uniform(0.030, 0.045)
    return Sample(shape, float(mass), _colour(rng, _JUICE), _colour(rng, _CAPS), False)


def _carton(rng: np.random.Generator, spec: FamilySpec, tare: tuple[float, float]) -> Sample:
    while True:
        nominal = rng.uniform(*spec.nominal_ml) * _ML
        base = rng.uniform(*spec.footprint_mm) * 1e-3
        gable = 0.5 * base * np.tan(np.radians(rng.uniform(30.0, 40.0)))
        fin = rng.uniform(0.007, 0.010)
        shoulder = nominal * rng.uniform(1.0, 1.08) / (base * base)
        if _in(shoulder + gable + fin, spec.height_mm):
            break
    band_bottom = shoulder * rng.uniform(0.35, 0.5)
    band_top = band_bottom + shoulder * rng.uniform(0.15, 0.3)
    shape = CartonShape(
        base, shoulder, gable, fin, rng.uniform(0.002, 0.003), band_bottom, band_top
    )
    mass = nominal * _MILK_RHO + rng.uniform(*tare)
    white = _colour(rng, [(0.95, 0.95, 0.93)], 0.02)
    return Sample(shape, float(mass), white, _colour(rng, _BANDS), False)


def _ceramic_mass(outer: list, inner: list, rng: np.random.Generator) -> float:
    return revolved_volume([*outer, *inner[::-1]]) * rng.uniform(2300.0, 2500.0)


def _bowl(rng: np.random.Generator, spec: FamilySpec, foot: tuple[float, float]) -> Sample:
    while True:
        rim = rng.uniform(*spec.footprint_mm) * 5e-4
        h = rng.uniform(*spec.height_mm) * 1e-3
        shape = BowlShape(
            rim, rim * rng.uniform(*foot), h, rng.uniform(0.0045, 0.0055), rng.uniform(0.006, 0.009)
        )
        if _holds(capacity(shape), spec.nominal_ml):
            break
    s = shape
    outer = _bowl_outer(s.rim_radius, s.foot_radius, s.height, s.wall, s.bottom)
    inner = _bowl_inner(s.rim_radius, s.foot_radius, s.height, s.wall, s.bottom)[1:3]
    mass = _ceramic_mass(outer, inner, rng)
    inside = _colour(rng, _CERAMIC) if rng.random() < 0.4 else None
    glaze = _colour(rng, _CERAMIC)
    return Sample(shape, float(mass), glaze, inside or glaze, True)


def _footed_bowl(rng: np.random.Generator, spec: FamilySpec) -> Sample:
    while True:
        rim = rng.uniform(*spec.footprint_mm) * 5e-4
        h, fh = rng.uniform(*spec.height_mm) * 1e-3, rng.uniform(0.008, 0.012)
        bowl_r = rim * rng.uniform(0.40, 0.5)
        shape = FootedBowlShape(
            rim, bowl_r, bowl_r * rng.uniform(0.8, 0.95), fh, h,
            rng.uniform(0.0045, 0.0055), rng.uniform(0.006, 0.009),
        )  # fmt: skip
        if _holds(capacity(shape), spec.nominal_ml):
            break
    s, hb = shape, shape.height - shape.foot_height
    outer = _bowl_outer(s.rim_radius, s.bowl_radius, hb, s.wall, s.bottom, s.foot_height)
    inner = _bowl_inner(s.rim_radius, s.bowl_radius, hb, s.wall, s.bottom, s.foot_height)[1:3]
    ring = [(0, 0), (s.foot_radius, 0), (s.foot_radius, s.foot_height), (0, s.foot_height)]
    mass = _ceramic_mass(outer, inner, rng) + revolved_volume(ring) * 0.35 * 2400.0
    glaze = _colour(rng, _CERAMIC)
    inside = _colour(rng, _CERAMIC) if rng.random() < 0.4 else glaze
    return Sample(shape, float(mass), glaze, inside, True)


def _mug(rng: np.random.Generator, spec: FamilySpec, family: str, k: int) -> Sample:
    while True:
        h = rng.uniform(*spec.height_mm) * 1e-3
        if family == "tapered":
            top = rng.uniform(*spec.footprint_mm) * 5e-4
            bottom = top * rng.uniform(0.70, 0.85)
            radii = (bottom, (top + bottom) / 2, top)
        elif family == "barrel":
            rim = rng.uniform(0.075, 0.088) / 2
            radii = (rim, rim * rng.uniform(1.08, 1.18), rim)
        else:
            r = rng.uniform(*spec.footprint_mm) * 5e-4
            radii = (r, r, r)
        rh = rng.uniform(0.0045, 0.006)
        shape = ProfileMugShape(
            *radii, h, rng.uniform(0.0045, 0.0055), rng.uniform(0.006, 0.009),
            rng.uniform(0.028, 0.035), rh, h * rng.uniform(0.75, 0.85), h * rng.uniform(0.2, 0.3),
        )  # fmt: skip
        if _holds(capacity(shape), spec.nominal_ml):
            break
    outer, inner = _mug_section(shape)
    handle = np.pi * rh * rh * 1.6 * (shape.handle_top - shape.handle_bottom + shape.handle_reach)
    mass = _ceramic_mass([(0.0, 0.0), *outer], [(0.0, shape.bottom), *inner], rng)
    mass += handle * 2400.0
    glaze, inside = _colour(rng, _CERAMIC), _colour(rng, _CERAMIC)
    return Sample(shape, float(mass), glaze, inside if rng.random() < 0.4 else glaze, k % 4 != 3)


def _brik(rng: np.random.Generator, spec: FamilySpec, family: str) -> Sample:
    straw = (rng.uniform(0.002, 0.0028), rng.uniform(0.006, 0.010), bool(rng.random() < 0.5))
    cap = (0.0, 0.0)
    while True:
        nominal = rng.uniform(*spec.nominal_ml) * _ML
        chamfer = 0.0
        if family == "brik_200":
            t = rng.random()
            w, d, h = np.array([0.063, 0.040, 0.088]) + t * np.array([-0.010, -0.002, 0.022])
            break
        if family == "slim_250":
            w, d = 0.053, rng.uniform(0.038, 0.040)
        elif family == "brik_1l":
            w, d = rng.uniform(*spec.footprint_mm) * 1e-3, rng.uniform(0.060, 0.078)
            cap = (rng.uniform(0.017, 0.020), rng.uniform(0.012, 0.018))
        else:
            nominal = (250.0 if rng.random() < 0.5 else 330.0) * _ML
            w, d = rng.uniform(*spec.footprint_mm) * 1e-3, rng.uniform(0.045, 0.052)
            chamfer = d * rng.uniform(0.18, 0.28)
            if nominal > 300 * _ML:
                cap, straw = (rng.uniform(0.012, 0.014), rng.uniform(0.010, 0.014)), None
        if d > w:
            continue
        h = nominal * rng.uniform(1.0, 1.1) / (w * d - 2 * chamfer**2)
        if _in(h, spec.height_mm):
            break
    if cap[0] > 0:
        straw = None
    sr, sm, mirror = straw if straw is not None else (0.0, 0.0, False)
    shape = BrikShape(float(w), float(d), float(h), chamfer, sr, sm, mirror, *cap)
    tare = 0.028 if family == "brik_1l" else 0.010
    mass = nominal * _JUICE_RHO + tare * rng.uniform(0.85, 1.15)
    return Sample(shape, float(mass), _colour(rng, _BRIGHT), _straw(rng), False)


def sample_family(category: str, family: str, k: int, rng: np.random.Generator) -> Sample:
    """Draw instance ``k`` (0-7; it only decides the matte mugs) of a valid ``family``."""
    spec = FAMILY_SPECS[(category, family)]
    if category == "juice_bottle":
        if family == "square_pet":
            return _square_bottle(rng, spec)
        return _bottle(rng, spec, glass=family == "glass_short")
    if category == "milk_carton":
        tare = {"gable_1l": (0.028, 0.035), "gable_2l": (0.045, 0.060)}
        return _carton(rng, spec, tare.get(family, (0.020, 0.028)))
    if category == "bowl":
        if family == "footed":
            return _footed_bowl(rng, spec)
        return _bowl(rng, spec, {"noodle": (0.45, 0.55), "shallow_soup": (0.5, 0.6)}.get(
            family, (0.38, 0.5)))  # fmt: skip
    if category == "mug":
        return _mug(rng, spec, family, k)
    return _brik(rng, spec, family)
