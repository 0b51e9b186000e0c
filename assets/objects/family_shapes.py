"""Shape dataclasses of the v2 families that the v1 ones cannot describe (all lengths in m).

v2 also reuses the v1 shapes of :mod:`ipbench.assets.objects.params`: :class:`BottleShape`
(round PET and short glass bottles), :class:`CartonShape` (every gable-top carton) and
:class:`BowlShape` (cereal, shallow soup and noodle bowls). Object frame as in v1: origin at
the centre of the bottom face of the upright object, +z up.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["SquareBottleShape", "FootedBowlShape", "ProfileMugShape", "BrikShape"]


@dataclass(frozen=True)
class SquareBottleShape:
    """PET bottle of square cross-section with rounded vertical edges; heights from the
    bottom, m. The square body turns into the round neck over the shoulder."""

    side: float  # width across the flats of the body
    corner_radius: float  # radius of the rounded vertical edges
    height: float  # total, with the cap
    body_top: float  # where the shoulder starts
    neck_bottom: float  # where the shoulder ends
    neck_radius: float
    cap_bottom: float
    cap_radius: float
    label_bottom: float
    label_top: float


@dataclass(frozen=True)
class FootedBowlShape:
    """Conical bowl standing on a foot ring, m."""

    rim_radius: float  # outer radius at the rim
    bowl_radius: float  # radius of the flat underside of the bowl, on top of the foot
    foot_radius: float  # outer radius of the foot ring (<= bowl_radius)
    foot_height: float  # height of the foot ring
    height: float  # total, foot included
    wall: float  # wall thickness
    bottom: float  # thickness of the bowl's floor (above the foot)


@dataclass(frozen=True)
class ProfileMugShape:
    """Mug whose outer wall runs straight from the bottom to half height and on to the rim
    (straight: all radii equal; tapered: growing; barrel: bulged in the middle), with a
    D-shaped handle on +x, m."""

    radius_bottom: float  # outer, at z = 0
    radius_middle: float  # outer, at half height
    radius_top: float  # outer, at the rim
    height: float
    wall: float
    bottom: float
    handle_reach: float  # how far the handle sticks out beyond the widest radius
    handle_radius: float  # radius of the handle's round section
    handle_top: float  # height of the upper attachment
    handle_bottom: float  # height of the lower attachment


@dataclass(frozen=True)
class BrikShape:
    """Aseptic carton brick, m: a box (``chamfer`` 0, Tetra Brik) or an octagonal prism whose
    vertical edges are cut at 45 degrees (``chamfer`` > 0, the leg of the cut; Tetra Prisma).
    Optionally a straw glued on the +y face (``straw_radius`` > 0, as v1) or a screw cap on
    the top face (``cap_height`` > 0)."""

    width: float  # x
    depth: float  # y
    height: float  # z, without the cap
    chamfer: float
    straw_radius: float
    straw_margin: float  # distance of the straw ends from the face's edges
    straw_mirror: bool  # straw rising towards -x instead of +x
    cap_radius: float
    cap_height: float
