"""Saliency of unexplained keypoints and inhibition of return over gaze directions."""

from __future__ import annotations

import numpy as np
import pytest

from ipbench.perception.features2d import ActiveVisionError
from ipbench.perception.saliency import (
    INHIBITION_RADIUS_RAD,
    InhibitionMap,
    most_salient,
    pixel_direction,
    salient_locations,
)

W, H = 1024, 680
K = np.array([[781.0, 0, 511.5], [0, 781.0, 339.5], [0, 0, 1.0]])
POSE = np.eye(4)
POSE[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]  # looking along world +y, image down = -z


def blob(centre, n: int, spread: float, rng) -> np.ndarray:
    return np.asarray(centre, float) + rng.normal(0, spread, (n, 2))


def test_the_densest_unexplained_texture_is_most_salient():
    rng = np.random.default_rng(0)
    xy = np.vstack([
        blob((300, 250), 60, 15, rng),
        blob((800, 450), 20, 15, rng),
        rng.uniform((0, 0), (W, H), (80, 2)),
    ])  # fmt: skip
    locations = salient_locations(xy, (W, H), principal_point=(K[0, 2], K[1, 2]))
    assert np.linalg.norm(locations[0].xy - (300, 250)) < 32
    assert any(np.linalg.norm(loc.xy - (800, 450)) < 32 for loc in locations[1:])
    scores = [loc.score for loc in locations]
    assert scores == sorted(scores, reverse=True) and locations[0].support >= 30
    # candidates are at least 2 sigma apart
    centres = np.array([loc.xy for loc in locations])
    gaps = np.linalg.norm(centres[:, None] - centres[None], axis=2) + 1e9 * np.eye(len(centres))
    assert gaps.min() > 64
    assert salient_locations(np.zeros((0, 2)), (W, H)) == []


def test_of_two_equal_blobs_the_less_eccentric_wins():
    rng = np.random.default_rng(1)
    base = blob((0, 0), 40, 12, rng)
    near, far = base + (611.5, 339.5), base + (911.5, 339.5)  # 100 and 400 px from the centre
    best = salient_locations(np.vstack([far, near]), (W, H))[0]
    assert np.linalg.norm(best.xy - (611.5, 339.5)) < 32


def test_inhibition_of_return_never_attends_a_location_twice():
    rng = np.random.default_rng(2)
    xy = np.vstack([blob(c, 30, 10, rng) for c in rng.uniform((50, 50), (W - 50, H - 50), (8, 2))])
    locations = salient_locations(xy, (W, H))
    inhibition = InhibitionMap()
    attended = []
    for _ in range(len(locations) + 1):
        pick = most_salient(locations, K, POSE, inhibition)
        if pick is None:
            break
        direction = pixel_direction(pick.xy, K, POSE)
        for previous in attended:  # never within the inhibition radius of an earlier fixation
            assert np.arccos(np.clip(previous @ direction, -1, 1)) > INHIBITION_RADIUS_RAD
        assert not inhibition.is_inhibited(direction)
        inhibition.add(direction)
        assert inhibition.is_inhibited(direction)
        attended.append(direction)
    assert most_salient(locations, K, POSE, inhibition) is None
    assert len(attended) == len(inhibition) >= 5


def test_directions_and_radius():
    straight = pixel_direction((K[0, 2], K[1, 2]), K, POSE)
    np.testing.assert_allclose(straight, (0, 1, 0), atol=1e-12)
    # a pixel right of the centre looks to world +x, one below to world -z
    assert pixel_direction((700, K[1, 2]), K, POSE)[0] > 0
    assert pixel_direction((K[0, 2], 600), K, POSE)[2] < 0
    inhibition = InhibitionMap(radius_rad=np.deg2rad(4.0))
    inhibition.add(straight * 3.0)  # any length; normalised
    tilt = np.deg2rad
    assert inhibition.is_inhibited((np.sin(tilt(3.9)), np.cos(tilt(3.9)), 0))
    assert not inhibition.is_inhibited((np.sin(tilt(4.1)), np.cos(tilt(4.1)), 0))
    with pytest.raises(ActiveVisionError, match="non-zero"):
        inhibition.add((0.0, 0.0, 0.0))
    with pytest.raises(ActiveVisionError, match="radius"):
        InhibitionMap(radius_rad=0.0)
