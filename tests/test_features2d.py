"""2-D features: every type finds a textured patch again under rotation and scale.

The synthetic images here (procedural textured patches pasted into clutter) are shared by the
other active-vision tests (``from test_features2d import ...``).
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ipbench.perception.features2d import (
    FEATURE_TYPES,
    ActiveVisionError,
    detect,
    norm_of,
)
from ipbench.perception.matching import TrainSet, match, match_many

ALPHABET = list("ABCDEFGHKMNPRSTXYZ0123456789")


def textured_patch(seed: int, size: tuple[int, int] = (160, 200)) -> np.ndarray:
    """(H, W) uint8 'product label': smoothed noise at three scales, discs, boxes, text."""
    rng = np.random.default_rng(seed)
    h, w = size
    img = np.zeros((h, w), np.float32)
    for sigma in (1.5, 4.0, 10.0):
        noise = cv2.GaussianBlur(rng.standard_normal((h, w)).astype(np.float32), (0, 0), sigma)
        img += noise / (noise.std() + 1e-6)
    img = cv2.normalize(img, None, 40, 215, cv2.NORM_MINMAX).astype(np.uint8)
    for _ in range(6):
        centre = (int(rng.integers(0, w)), int(rng.integers(0, h)))
        cv2.circle(img, centre, int(rng.integers(5, 25)), int(rng.integers(0, 256)), -1)
        a, b = rng.integers(0, [w, h], size=(2, 2))
        cv2.rectangle(img, tuple(map(int, a)), tuple(map(int, b)), int(rng.integers(0, 256)), 2)
    for k in range(3):
        text = "".join(rng.choice(ALPHABET, 5))
        colour = 250 if k % 2 == 0 else int(rng.integers(0, 80))
        cv2.putText(img, text, (5, 40 + 45 * k), cv2.FONT_HERSHEY_SIMPLEX, 1.1, colour, 2)
    return img


def background(seed: int, shape: tuple[int, int] = (680, 1024)) -> np.ndarray:
    """(H, W) uint8 clutter: smooth noise (few strong features of its own)."""
    rng = np.random.default_rng(seed)
    noise = cv2.GaussianBlur(rng.standard_normal(shape).astype(np.float32), (0, 0), 6.0)
    return cv2.normalize(noise, None, 60, 190, cv2.NORM_MINMAX).astype(np.uint8)


def paste(
    scene: np.ndarray,
    patch: np.ndarray,
    centre: tuple[float, float],
    angle_deg: float = 0.0,
    scale: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """``scene`` with ``patch`` turned by ``angle_deg`` (counter-clockwise on screen, as
    ``cv2.getRotationMatrix2D``) and scaled about its centre, placed at ``centre``; and the
    (2, 3) patch-to-scene affine map."""
    h, w = patch.shape
    M = cv2.getRotationMatrix2D(((w - 1) / 2, (h - 1) / 2), angle_deg, scale)
    M[:, 2] += np.asarray(centre, float) - ((w - 1) / 2, (h - 1) / 2)
    H, W = scene.shape[:2]
    warped = cv2.warpAffine(patch, M, (W, H), flags=cv2.INTER_LINEAR)
    inside = cv2.warpAffine(np.full_like(patch, 255), M, (W, H), flags=cv2.INTER_NEAREST) > 0
    out = scene.copy()
    out[inside] = warped[inside]
    return out, M


def object_mask(shape: tuple[int, int], patch: np.ndarray, M: np.ndarray) -> np.ndarray:
    """(H, W) bool: where ``paste`` put ``patch`` with map ``M``."""
    full = np.full_like(patch, 255)
    return cv2.warpAffine(full, M, (shape[1], shape[0]), flags=cv2.INTER_NEAREST) > 0


@pytest.mark.parametrize("feature_type", FEATURE_TYPES)
def test_a_patch_is_found_again_turned_and_scaled(feature_type):
    patch = textured_patch(1)
    scene, M = paste(background(2), patch, (500, 300), angle_deg=30.0, scale=1.3)
    model = detect(patch, feature_type)
    found = detect(scene, feature_type)
    pairs = match(found, model)
    assert len(model) >= 50 and len(pairs) >= 30
    predicted = model.xy[pairs[:, 1]] @ M[:, :2].T + M[:, 2]
    error = np.linalg.norm(found.xy[pairs[:, 0]] - predicted, axis=1)
    correct = error < 3.0
    assert correct.sum() >= 30 and correct.mean() >= 0.7
    # keypoint angles turn with the patch in the image plane (x right, y down): by -30 deg
    turn = found.angle[pairs[correct, 0]] - model.angle[pairs[correct, 1]]
    median_turn = np.rad2deg(np.angle(np.median(np.exp(1j * np.deg2rad(turn)))))
    assert abs(median_turn - (-30.0)) < 5.0
    ratio = np.median(found.size[pairs[correct, 0]] / model.size[pairs[correct, 1]])
    assert 1.3 / 1.5 < ratio < 1.3 * 1.5


@pytest.mark.parametrize("feature_type", FEATURE_TYPES)
def test_detection_is_deterministic_and_masked(feature_type):
    scene, M = paste(background(3), textured_patch(4), (400, 300))
    a, b = detect(scene, feature_type), detect(scene.copy(), feature_type)
    for name in ("xy", "size", "angle", "response", "descriptors"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    mask = object_mask(scene.shape, textured_patch(4), M)
    inside = detect(scene, feature_type, mask=mask, max_features=100)
    assert 0 < len(inside) <= 100
    cols, rows = np.round(inside.xy).astype(int).T
    assert mask[rows.clip(0, 679), cols.clip(0, 1023)].mean() > 0.95
    assert inside.descriptors.shape[0] == len(inside)


def test_norms_and_descriptor_types():
    assert norm_of("sift") == norm_of("kaze") == cv2.NORM_L2
    assert norm_of("akaze") == norm_of("orb") == cv2.NORM_HAMMING
    patch = textured_patch(5)
    assert detect(patch, "sift").descriptors.dtype == np.float32
    assert detect(patch, "orb").descriptors.dtype == np.uint8


def test_bad_input_gets_clear_errors():
    with pytest.raises(ActiveVisionError, match="sift, kaze, akaze, orb"):
        detect(textured_patch(1), "surf")
    with pytest.raises(ActiveVisionError, match="uint8"):
        detect(np.zeros((10, 10), np.float32), "orb")
    with pytest.raises(ActiveVisionError, match="mask"):
        detect(textured_patch(1), "orb", mask=np.ones((3, 3)))
    a, b = detect(textured_patch(1), "orb"), detect(textured_patch(1), "sift")
    with pytest.raises(ActiveVisionError, match="same type"):
        match(a, b)
    with pytest.raises(ActiveVisionError, match="ratio"):
        match(a, a, ratio=1.5)


def test_ratio_test_needs_two_features_and_a_patch_matches_itself():
    a = detect(textured_patch(1), "sift")
    assert match(a, a.subset(np.array([0]))).shape == (0, 2)
    # a patch matched to itself: every feature finds itself (distance 0) unless a duplicate
    pairs = match(a, a)
    assert (pairs[:, 0] == pairs[:, 1]).mean() > 0.95


def _bf_reference(query, train, ratio=0.8):
    """Lowe's ratio test over cv2.BFMatcher.knnMatch (the original formulation of match)."""
    matcher = cv2.BFMatcher(norm_of(query.feature_type), crossCheck=False)
    pairs = matcher.knnMatch(query.descriptors, train.descriptors, k=2)
    rows = [(p[0].queryIdx, p[0].trainIdx) for p in pairs if len(p) == 2]
    rows = [r for r, p in zip(rows, pairs, strict=True) if p[0].distance < ratio * p[1].distance]
    return np.array(rows, np.int64).reshape(-1, 2)


@pytest.mark.parametrize("feature_type", FEATURE_TYPES)
def test_match_and_match_many_equal_the_brute_force_matcher(feature_type):
    scene, _ = paste(background(8), textured_patch(1), (300, 300), 20.0, 1.1)
    scene, _ = paste(scene, textured_patch(2), (700, 350), -10.0, 0.9)
    query = detect(scene, feature_type)
    trains = [detect(textured_patch(seed), feature_type) for seed in (1, 2, 3)]
    trains += [trains[0].subset(np.arange(1)), trains[1].subset(np.arange(0))]  # 1 and 0 kept
    many = match_many(query, trains)
    prepared = TrainSet(tuple(trains))
    assert prepared.exact_product == (feature_type == "sift")
    assert prepared.binary == (feature_type in ("akaze", "orb"))
    for a, b in zip(match_many(query, prepared), many, strict=True):
        np.testing.assert_array_equal(a, b)
    assert len(many) == len(trains) and len(many[0]) >= 30 and len(many[1]) >= 30
    for train, got in zip(trains, many, strict=True):
        expected = _bf_reference(query, train) if len(train) >= 2 else np.zeros((0, 2))
        np.testing.assert_array_equal(got, expected)
        np.testing.assert_array_equal(match(query, train), expected)
    with pytest.raises(ActiveVisionError, match="same type"):
        match_many(query, [detect(textured_patch(1), "orb" if feature_type != "orb" else "sift")])


def test_sift_descriptors_take_the_exact_matrix_product_path():
    # OpenCV's SIFT stores bytes as floats: the product path applies and is exact (test above);
    # KAZE's real-valued descriptors do not qualify and use the brute-force kernel
    from ipbench.perception.matching import _integer_valued

    assert _integer_valued(detect(textured_patch(1), "sift").descriptors)
    assert not _integer_valued(detect(textured_patch(1), "kaze").descriptors)
    assert not _integer_valued(np.array([[0.5, 1.0]], np.float32))
    assert not _integer_valued(np.full((1, 128), 2000.0, np.float32))  # sums beyond 2**22


def test_a_train_set_holds_one_feature_type():
    sets = [detect(textured_patch(1), "sift"), detect(textured_patch(1), "orb")]
    with pytest.raises(ActiveVisionError, match="one type"):
        TrainSet(tuple(sets))
    assert match_many(sets[0], TrainSet(())) == []
