"""Print orientation of v2 objects: ``ObjectModel(upright_prints=True)`` shows every print
upright and unmirrored; the default model keeps the released mapping (each print mirrored top
to bottom) byte for byte.

The rendering tests build one instance with :func:`~ipbench.assets.objects.add_object`, swap
the printed part's texture for a white image with a red mark near its top-left corner (rows
``0 .. H/4``, columns ``W/64 .. 3W/32``: the top of the print where its text starts) and look at
the part from the front (+x, the side where u = 0 and a carton's front face are). Upright, the
mark lies in the upper half of the part; column 0 lies at u = 0, which is the left edge of a
carton's or box's front face and the front meridian of a bottle with the print running to the
right, so the mark lies left of a front face's centre and right of a bottle's axis (a print
mirrored left to right would put it on a side face, out of sight, or on the other side).
"""

from __future__ import annotations

import hashlib
import warnings

import mujoco
import numpy as np
import pytest

from ipbench.assets.objects import add_object, get_instance, instances
from ipbench.assets.objects.family_geometry import TEXTURE_SIZES, family_parts
from ipbench.assets.objects.family_geometry import _parts as released_parts
from ipbench.assets.objects.geometry import object_geometry
from ipbench.assets.objects.object_model import ObjectModel
from ipbench.assets.objects.textures import make_texture

UPRIGHT = ObjectModel(upright_prints=True)
H, W = 120, 160  # rendered image, px
V2 = instances(catalog="v2")

# (category, index, textured part, side of the part's centre where the mark's column lies)
PRINTED = [
    ("juice_bottle", 0, "label", "right"),  # round bottle: u = 0 faces the camera
    ("juice_bottle", 8, "label", "right"),  # square bottle: u = 0 at the front face's middle
    ("juice_bottle", 16, "body", "right"),  # clear glass bottle with its printed label
    ("milk_carton", 0, "sides", "left"),  # u = 0 at the front face's left edge
    ("juice_box", 0, "box", "left"),
    ("juice_box", 24, "box", "left"),  # prisma: u = 0 mid-way along the front-left chamfer
]

RELEASED_TEXCOORDS_SHA256 = "af8dc59e0f3ae383cc68ad4b3cebb707395dbea376a5318d5dbeb0ca4896a6db"
"""SHA-256 over every v2 instance's textured parts (name, suffix, texcoords rounded to 1e-9)
as released."""


def _mark(h: int, w: int) -> np.ndarray:
    img = np.full((h, w, 3), 255, np.uint8)
    img[: h // 4, w // 64 : 3 * w // 32] = (255, 0, 0)
    return img


def _render_mark(inst, suffix: str, model: ObjectModel) -> tuple[np.ndarray, np.ndarray]:
    """(mark mask, part mask), (H, W) bool, of ``inst``'s part ``suffix`` seen from +x."""
    spec = mujoco.MjSpec()
    spec.visual.headlight.ambient = [0.5, 0.5, 0.5]
    spec.visual.headlight.diffuse = [0.5, 0.5, 0.5]
    add_object(spec, inst, "obj", model=model)
    part = next(p for p in object_geometry(inst, model).visual if p.suffix == suffix)
    lo, hi = part.vertices.min(0), part.vertices.max(0)
    centre, extent = (lo + hi) / 2, float(np.max(hi - lo))
    dist = extent / (0.6 * 2 * np.tan(np.radians(15)))  # the part fills ~60 % of the height
    spec.worldbody.add_camera(
        name="front", pos=[centre[0] + dist, centre[1], centre[2]], xyaxes=[0, 1, 0, 0, 0, 1]
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model_ = spec.compile()
    tex = model_.texture(f"obj_{suffix}_tex")
    th, tw = int(model_.tex_height[tex.id]), int(model_.tex_width[tex.id])
    adr = int(model_.tex_adr[tex.id])
    model_.tex_data[adr : adr + th * tw * 3] = _mark(th, tw).ravel()
    data = mujoco.MjData(model_)
    mujoco.mj_forward(model_, data)
    option = mujoco.MjvOption()
    option.geomgroup[:] = [0, 0, 1, 0, 0, 0]  # visual geoms only
    with mujoco.Renderer(model_, H, W) as renderer:
        renderer.update_scene(data, camera="front", scene_option=option)
        rgb = renderer.render().astype(int)
        renderer.enable_segmentation_rendering()
        renderer.update_scene(data, camera="front", scene_option=option)
        seg = renderer.render()
    on_part = (seg[..., 0] == model_.geom(f"obj_{suffix}_visual").id) & (
        seg[..., 1] == mujoco.mjtObj.mjOBJ_GEOM
    )
    red = (
        (rgb[..., 0] > 100) & (rgb[..., 1] < 0.5 * rgb[..., 0]) & (rgb[..., 2] < 0.5 * rgb[..., 0])
    )
    return red & on_part, on_part


def _where(mark: np.ndarray, part: np.ndarray) -> tuple[float, float]:
    """Mark centroid relative to the part's silhouette: (row, column) in [0, 1] (0: top, left)."""
    assert part.sum() > 200, "the part should fill a good share of the image"
    assert mark.sum() >= 10, "the mark should be visible from the front"
    pr, pc = np.nonzero(part)
    mr, mc = np.nonzero(mark)
    row = (mr.mean() - pr.min()) / (pr.max() - pr.min())
    col = (mc.mean() - pc.min()) / (pc.max() - pc.min())
    return float(row), float(col)


@pytest.mark.parametrize(("category", "index", "suffix", "side"), PRINTED)
def test_upright_model_shows_the_print_upright_and_unmirrored(category, index, suffix, side):
    inst = get_instance(category, index, "v2")
    row, col = _where(*_render_mark(inst, suffix, UPRIGHT))
    assert row < 0.5, f"{inst.name}: the print's top should be in the upper half, at {row:.2f}"
    assert (col < 0.5) if side == "left" else (col > 0.5), (inst.name, col)


@pytest.mark.parametrize(("category", "index", "suffix", "side"), PRINTED)
def test_default_model_keeps_the_released_top_to_bottom_mirror(category, index, suffix, side):
    inst = get_instance(category, index, "v2")
    row, col = _where(*_render_mark(inst, suffix, ObjectModel()))
    assert row > 0.5, f"{inst.name}: the released print's top lies in the lower half, at {row:.2f}"
    assert (col < 0.5) if side == "left" else (col > 0.5), (inst.name, col)


def _v_rises(part) -> bool:
    v, z = part.texcoords[:, 1], part.vertices[:, 2]
    return float(np.mean((v - v.mean()) * (z - z.mean()))) > 0


def test_upright_puts_row_zero_on_top_of_every_textured_part():
    """Labels, prints, glass, glaze and mug handles alike: v falls with height upright."""
    for inst in V2:
        for part in object_geometry(inst, UPRIGHT).visual:
            if part.texture is not None:
                assert not _v_rises(part), (inst.name, part.suffix)


def test_upright_changes_only_v_and_keeps_the_images():
    for inst in V2:
        default, _ = family_parts(inst)
        upright, _ = family_parts(inst, upright_prints=True)
        for d, u in zip(default, upright, strict=True):
            if d.texture is None:
                assert u.texture is None and u.texcoords is None
                continue
            np.testing.assert_array_equal(u.texture, d.texture)
            np.testing.assert_array_equal(u.texcoords[:, 0], d.texcoords[:, 0])
            flipped = d.suffix != "handle"  # a handle's v already runs down from its top
            want = 1.0 - d.texcoords[:, 1] if flipped else d.texcoords[:, 1]
            np.testing.assert_array_equal(u.texcoords[:, 1], want, err_msg=inst.name)
            assert _v_rises(d) == flipped, (inst.name, d.suffix)


def test_default_model_textures_and_texcoords_are_the_released_ones():
    """The default parts equal the released builders' texcoords and the released texture seeds,
    and their texcoords hash to the released digest."""
    digest = hashlib.sha256()
    for inst in V2:
        built = {
            s: (uv, kind) for s, (_, _, uv), kind in released_parts(inst.shape, inst.family)[0]
        }
        for part in object_geometry(inst).visual:
            if part.texture is None:
                continue
            uv, kind = built[part.suffix]
            np.testing.assert_array_equal(part.texcoords, np.asarray(uv, float))
            text = f"ipbench.objects/v2/texture/{inst.name}/{kind}"
            seed = int.from_bytes(hashlib.sha256(text.encode()).digest()[:8], "little")
            base, accent = inst.rgba[:3], inst.accent_rgba[:3]
            if kind == "bottle_label":
                base, accent = accent, base
            image = make_texture(kind, seed, base, accent, TEXTURE_SIZES[kind])
            np.testing.assert_array_equal(part.texture, image, err_msg=inst.name)
            digest.update(f"{inst.name}/{part.suffix}".encode())
            digest.update(np.round(part.texcoords, 9).tobytes())
    assert digest.hexdigest() == RELEASED_TEXCOORDS_SHA256
