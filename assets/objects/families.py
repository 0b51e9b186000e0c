"""The v2 catalogue's shape families: real product types per category, with sourced ranges.

Tags: [DOC] a published number, [DOC, weak] a retail or blog page, [DER] derived from a
published number, [EST] an engineering estimate with no published source.
Sizes in mm below, m in the code. Fill volumes are the nominal (labelled) ones; every sampler
draws the nominal volume and the container dimensions from the ranges, then the free height
so that the container holds the nominal volume plus a headspace, and rejects draws outside the
published envelope.

juice_bottle (juice 1040 kg/m^3, as v1)
  * ``round_pet`` — 0.5-1.0 L round PET (0.5 L: Ø 65-70 x 200-235 incl. cap
    [DOC, weak] glasscraftbottle.com; 1 L: Ø 80-90 x 250-290 [EST]); 20-40 g of PET [EST].
  * ``square_pet`` — 1 L square PET with rounded edges: "squared, round or rectangular"
    PET juice bottles of 200 ml-1.5 L (CDI 1998, *The Packaging of Fruit Juice*, card 8
    [DOC]); side 72-82, corner radius 8-14, height 240-290 [EST].
  * ``glass_short`` — 250 ml glass: the squat round 500 ml glass juice bottle, 185 x Ø 78,
    420-450 g empty (glasscraftbottle.com size guide [DOC, weak]) scaled to 250 ml by
    0.5^(1/3): 147 x Ø 62 [DER]; drawn Ø 56-66 x 135-170, 0.20-0.29 kg of glass [DER/EST].
    Not marked specular: no published measure of structured light on glass bottles.
milk_carton (milk 1030 kg/m^3, as v1; headspace 0-8 % [EST])
  * ``gable_1l`` — 946 ml-1 L, base 2.75-2.8 in = 70-71 mm (US quart: printnpackage.com
    2.8 x 2.8 x 7.6 in, gifts-pack.com 2.75 x 2.75 x 7.5 in [DOC, weak]; 70 x 70 x 235
    [EST]); height 215-255.
  * ``gable_2l`` — 1.89-2 L, base 3.75-4 in = 95-102 mm, ≈ 9.5 in = 241 mm high (US half
    gallon, same pages); height 225-265.
  * ``gable_half_l`` — 473-500 ml, base 70-71 mm, 5.5-5.6 in = 140-142 mm high (US pint,
    same pages); height 125-150. Gable-top sizes ¼, ½, 1, 2 L: CDI 1998 card 5 [DOC].
bowl (ceramic 2300-2500 kg/m^3 [EST], mass = shell volume x density)
  * ``cereal`` — rim Ø 146-178 (5.75-7 in), brimful 16-22 fl oz = 473-651 ml
    (doughnutlounge.com "standard cereal bowl" [DOC, weak]); height 50-80 [EST].
  * ``shallow_soup`` — coupe soup bowl: rim Ø 178-190, from the 5.75-8.75 in soup-cereal bowl
    (reference.com / hunker.com [DOC, weak]) up to what the 0.21 m jaws can span; height
    38-50 ("up to 1.5 in deep" soup plate, same pages, and a little deeper [EST]); holds a
    8-12 oz soup serving (dimensions.com [DOC, weak]): brimful >= 237 ml.
  * ``noodle`` — rim Ø 170-180 (17-21 cm bowls for noodles for one, greatzakka.com
    [DOC, weak], capped at 180 so the 0.21 m jaws clear the rim), height 75-95 and foot
    0.45-0.55 of the rim [EST], brimful >= 2 cups = 473 ml
    (7-8 in "large/soup" bowls of 2-3 cups, thedonutwhole.com [DOC, weak]).
  * ``footed`` — rim Ø 140-170 [EST], height 65-90 with an 8-12 mm foot ring [EST],
    brimful >= 8 oz = 237 ml.
mug (ceramic as bowls; handle reach 28-35: Grace Teaware 12 oz mug, 4.55 in with handle
  over a 3.375 in top = 30 mm [DOC, weak], 30-35 [EST]; instances 3 and 7 of each
  family are matte stoneware, as v1's index % 4 == 3)
  * ``straight`` — Ø 75-90 x 90-115 (hotchickalatte.com [DOC, weak]), 8-15 oz = 237-443 ml
    brimful (familypanda.co mug ≈ 8 oz; tacowindow.com 11 oz = 325 ml, 15 oz = 443 ml [DOC,
    weak]).
  * ``tapered`` — rim Ø 3-4.5 in = 76-114 with a smaller bottom, 4-5 in = 100-125 high
    (rachelmariedavino.com, 15 oz mugs [DOC, weak]); bottom 0.70-0.85 of the rim [EST];
    11-16 oz = 325-473 ml.
  * ``barrel`` — rim = bottom Ø 75-88, belly 1.08-1.18 x rim, height 90-110 [EST];
    11-16 oz.
  * ``tall_latte`` — Ø 3.5-4 in = 89-102 x 4-5 in = 100-125 (15 oz cylindrical mug,
    rachelmariedavino.com) up to 150 for 16 oz latte mugs (thedonutwhole.com: 16 oz for
    lattes [DOC, weak]); Ø 80-95 x 120-150 [EST], 12-16 oz = 355-473 ml.
juice_box (juice 1040 kg/m^3; gross volume 1.0-1.1 x nominal [EST])
  * ``brik_200`` — v1's range: Tetra Brik Aseptic 200 Base 63 x 40 x 88 to Slim 53 x 38 x
    110 [EST], straw.
  * ``slim_250`` — the 200 Slim's 53 x 38-40 cross-section with the height that holds
    250 ml [DER]: 118-140, straw.
  * ``brik_1l`` — 1000 ml Tetra Brik (Base / Square shapes, 80-2000 ml: wikimili "Tetra Brik"
    [DOC]; 30 mm LightCap opening: dairyreporter.com 2011 [DOC]): width 78-97, depth 60-78,
    height 160-200 [EST], screw cap Ø 34-40 x 12-18 [EST]. No gable: a milk-carton look-alike.
  * ``prisma`` — Tetra Prisma Aseptic, "eight-sided", 250 and 330 ml (nspackaging.com 2009
    [DOC]): width 55-62, depth 45-52, chamfer 0.18-0.28 x depth, straw on 250 ml, cap on 330
    ml [EST].

**Split rule (fixed):** the last family of ``FAMILIES[category]`` is *novel* (held out of
training entirely); in every other family instances 0-5 are *train*, 6-7 *similar*.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "FAMILIES",
    "SPLITS",
    "INSTANCES_PER_FAMILY",
    "TRAIN_PER_FAMILY",
    "V1_FAMILY",
    "FamilySpec",
    "FAMILY_SPECS",
    "family_split",
]

FAMILIES: dict[str, tuple[str, ...]] = {
    "juice_bottle": ("round_pet", "square_pet", "glass_short"),
    "milk_carton": ("gable_1l", "gable_2l", "gable_half_l"),
    "bowl": ("cereal", "shallow_soup", "noodle", "footed"),
    "mug": ("straight", "tapered", "barrel", "tall_latte"),
    "juice_box": ("brik_200", "slim_250", "brik_1l", "prisma"),
}
"""v2 shape families per category; the last one of each is the novel (held-out) family."""

SPLITS: tuple[str, ...] = ("train", "similar", "novel")
"""train: perception may train on it; similar: new instance of a trained family; novel:
instance of a family never trained on."""

INSTANCES_PER_FAMILY: int = 8
"""v2 instances per family (indices ``8 k .. 8 k + 7`` are family ``k``)."""

TRAIN_PER_FAMILY: int = 6
"""In a non-novel family, instances 0-5 are train and 6-7 similar."""

V1_FAMILY: dict[str, str] = {
    "juice_bottle": "round_pet",  # 0.5-1.05 kg round PET bottles
    "milk_carton": "gable_1l",  # square 70-95 mm gable tops holding 1-1.5 L
    "bowl": "cereal",  # Ø 140-170 x 50-80 conical bowls
    "mug": "straight",  # cylindrical Ø 75-90 x 90-110
    "juice_box": "brik_200",  # 200 ml Base-to-Slim briks with a straw
}
"""The family each v1 category's single shape belongs to."""


@dataclass(frozen=True)
class FamilySpec:
    """Published numbers a family's instances are checked against.

    Attributes
    ----------
    nominal_ml : (lo, hi) nominal fill volume (drinks) or brimful capacity (bowls, mugs), ml.
    footprint_mm : (lo, hi) of the widest horizontal extent of the body (diameter, base side
        or box width, without handle or straw), mm.
    height_mm : (lo, hi) total height, mm.
    source : where the numbers come from (see the module docstring).
    """

    nominal_ml: tuple[float, float]
    footprint_mm: tuple[float, float]
    height_mm: tuple[float, float]
    source: str


FAMILY_SPECS: dict[tuple[str, str], FamilySpec] = {
    ("juice_bottle", "round_pet"): FamilySpec((500, 1000), (65, 90), (200, 290), "glasscraft"),
    ("juice_bottle", "square_pet"): FamilySpec((1000, 1000), (72, 82), (240, 290), "CDI 1998"),
    ("juice_bottle", "glass_short"): FamilySpec(
        (250, 250), (56, 66), (135, 170), "glasscraftbottle 500 ml x 0.5^(1/3)"
    ),
    ("milk_carton", "gable_1l"): FamilySpec((946, 1000), (70, 71), (215, 255), "US quart"),
    ("milk_carton", "gable_2l"): FamilySpec((1890, 2000), (95, 102), (225, 265), "US half gal"),
    ("milk_carton", "gable_half_l"): FamilySpec((473, 500), (70, 71), (125, 150), "US pint"),
    ("bowl", "cereal"): FamilySpec((473, 651), (146, 178), (50, 80), "doughnutlounge"),
    ("bowl", "shallow_soup"): FamilySpec((237, 1e9), (178, 190), (38, 50), "reference.com"),
    ("bowl", "noodle"): FamilySpec((473, 1e9), (170, 180), (75, 95), "greatzakka"),
    ("bowl", "footed"): FamilySpec((237, 1e9), (140, 170), (65, 90), "[EST]"),
    ("mug", "straight"): FamilySpec((237, 443), (75, 90), (90, 115), "hotchickalatte"),
    ("mug", "tapered"): FamilySpec((325, 473), (76, 114), (100, 125), "rachelmariedavino"),
    ("mug", "barrel"): FamilySpec((325, 473), (81, 104), (90, 110), "[EST]"),
    ("mug", "tall_latte"): FamilySpec((355, 473), (80, 95), (120, 150), "[EST]"),
    ("juice_box", "brik_200"): FamilySpec((200, 200), (53, 63), (88, 110), "[EST]"),
    ("juice_box", "slim_250"): FamilySpec((250, 250), (53, 53), (118, 140), "[DER]"),
    ("juice_box", "brik_1l"): FamilySpec((1000, 1000), (78, 97), (160, 200), "[EST]"),
    ("juice_box", "prisma"): FamilySpec((250, 330), (55, 62), (80, 140), "nspackaging"),
}
"""Per (category, family): the published envelope of its instances."""


def family_split(category: str, family: str, k: int) -> str:
    """Split of instance ``k`` (0-7) of ``family`` (a member of ``FAMILIES[category]``)."""
    if family == FAMILIES[category][-1]:
        return "novel"
    return "train" if k < TRAIN_PER_FAMILY else "similar"
