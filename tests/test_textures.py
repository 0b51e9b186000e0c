"""Procedural object textures: determinism, layout, seamlessness, features and errors."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ipbench.assets.objects.textures import TEXTURE_KINDS, TextureError, make_texture

# Catalogue-like (base, accent) pairs: label/juice, carton white + band, box print + straw...
COLOURS = {
    "bottle_label": ((0.95, 0.6, 0.1), (0.1, 0.3, 0.7)),
    "carton_print": ((0.95, 0.95, 0.93), (0.1, 0.4, 0.8)),
    "box_print": ((0.2, 0.75, 0.2), (0.95, 0.95, 0.95)),
    "glaze": ((0.6, 0.75, 0.85), (0.15, 0.25, 0.5)),
    "glass": ((0.95, 0.55, 0.05), (0.2, 0.5, 0.2)),
}
PRINT_KINDS = ("bottle_label", "carton_print", "box_print")
# Minimum ORB keypoints (ORB_create(1000)) on a 256x512 texture, over seeds 0-5 and the
# colours above; measured minima (30 seeds, random colours): prints ~870, glass ~620,
# glaze ~190 (a plain speckled glaze); the thresholds keep a 2-3x margin.
MIN_ORB = {"bottle_label": 400, "carton_print": 400, "box_print": 400, "glass": 250, "glaze": 80}
SIZE = (256, 512)


def _tex(kind: str, seed: int = 0, size: tuple[int, int] = SIZE) -> np.ndarray:
    return make_texture(kind, seed, *COLOURS[kind], size=size)


def test_kinds_listed() -> None:
    assert set(PRINT_KINDS + ("glaze", "glass")) <= set(TEXTURE_KINDS)


@pytest.mark.parametrize("kind", TEXTURE_KINDS)
def test_shape_dtype_and_determinism(kind: str) -> None:
    img = _tex(kind, 7, (96, 200))
    assert img.shape == (96, 200, 3) and img.dtype == np.uint8 and img.flags.c_contiguous
    assert img.tobytes() == _tex(kind, 7, (96, 200)).tobytes()


@pytest.mark.parametrize("kind", TEXTURE_KINDS)
def test_seeds_give_different_designs(kind: str) -> None:
    imgs = [_tex(kind, s, (128, 256)).astype(np.int16) for s in range(3)]
    for a, b in ((0, 1), (0, 2), (1, 2)):
        assert np.abs(imgs[a] - imgs[b]).mean() > 3.0  # visibly different, not just grain


def test_kinds_differ_for_one_seed() -> None:
    a = make_texture("bottle_label", 1, (0.9, 0.5, 0.1), (0.1, 0.2, 0.7), (128, 256))
    b = make_texture("box_print", 1, (0.9, 0.5, 0.1), (0.1, 0.2, 0.7), (128, 256))
    assert np.abs(a.astype(np.int16) - b).mean() > 3.0


def _seam_ratio(img: np.ndarray) -> float:
    """Mean |column 0 - column W-1| over the largest step between the 2 columns on each side
    (+1 level): ~<1 where the print continues, >>1 at a cut through a design."""
    f = img.astype(np.float32)

    def step(a: int, b: int) -> float:
        return float(np.abs(f[:, a] - f[:, b]).mean())

    return step(0, -1) / (max(step(0, 1), step(1, 2), step(-2, -1), step(-3, -2)) + 1.0)


@pytest.mark.parametrize("kind", TEXTURE_KINDS)
def test_seamless_in_u(kind: str) -> None:
    for seed in range(4):
        img = _tex(kind, seed)
        assert _seam_ratio(img) < 1.5, seed  # measured <= 0.91 over 200 textures
        f = img.astype(np.float32)
        neighbours = np.abs(np.diff(f, axis=1)).mean(axis=(0, 2))  # (W - 1,) column steps
        assert np.abs(f[:, 0] - f[:, -1]).mean() <= max(np.percentile(neighbours, 95), 1.0)


def test_seam_check_detects_a_cut() -> None:
    img = _tex("bottle_label", 0)  # the brand panel spans u = 0 .. ~0.35 W
    cut = np.roll(img, -img.shape[1] // 6, axis=1)[:, :-37]  # edges through the brand word
    assert _seam_ratio(cut) > 2.0


@pytest.mark.parametrize("kind", TEXTURE_KINDS)
def test_orb_features(kind: str) -> None:
    orb = cv2.ORB_create(1000)
    counts = [
        len(orb.detect(cv2.cvtColor(_tex(kind, s), cv2.COLOR_RGB2GRAY), None)) for s in range(6)
    ]
    assert min(counts) >= MIN_ORB[kind], counts


@pytest.mark.parametrize("kind", PRINT_KINDS)
def test_base_colour_dominates(kind: str) -> None:
    base, accent = COLOURS[kind]
    for seed in range(4):
        mean = _tex(kind, seed, (128, 256)).reshape(-1, 3).mean(axis=0) / 255.0
        assert np.linalg.norm(mean - base) < np.linalg.norm(mean - accent), (seed, mean)


def test_glaze_has_plain_and_patterned_mugs() -> None:
    spread = [
        float(_tex("glaze", s, (64, 128)).reshape(-1, 3).std(axis=0).mean()) for s in range(12)
    ]
    assert min(spread) < 12.0 < max(spread)  # some only speckled, some printed


def test_bad_kind_lists_valid_kinds() -> None:
    with pytest.raises(TextureError, match="valid kinds.*bottle_label.*glass"):
        make_texture("vase", 0, (1, 1, 1), (0, 0, 0))
    assert issubclass(TextureError, ValueError)


@pytest.mark.parametrize("size", [(16, 256), (256, 4096), (256,), (12.5, 64), "big", (True, 64)])
def test_bad_size_says_valid_range(size: object) -> None:
    with pytest.raises(TextureError, match=r"size must be \(H, W\).*\[32, 2048\]"):
        make_texture("glaze", 0, (1, 1, 1), (0, 0, 0), size)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "colour", [(1.2, 0, 0), (0.5, 0.5), (0, 0, float("nan")), "red", (255, 0, 0)]
)
def test_bad_colour_says_valid_range(colour: object) -> None:
    with pytest.raises(TextureError, match=r"base_rgb must be 3 RGB floats in \[0, 1\]"):
        make_texture("glass", 0, colour, (0, 0, 0))  # type: ignore[arg-type]
    with pytest.raises(TextureError, match=r"accent_rgb must be 3 RGB floats in \[0, 1\]"):
        make_texture("glass", 0, (0, 0, 0), colour)  # type: ignore[arg-type]


@pytest.mark.parametrize("seed", [-1, 1.5, "3", None])
def test_bad_seed(seed: object) -> None:
    with pytest.raises(TextureError, match="seed must be an int >= 0"):
        make_texture("glass", seed, (0, 0, 0), (1, 1, 1))  # type: ignore[arg-type]
