"""The dynamic update's consistency check: which stereo pair the matched pixels support.

Synthetic: two cameras 0.288 m apart (the CloPeMa head's calibrated baseline) at f = 1519 px
(the head's 35 mm lens on the D5100's 23.6 mm sensor at 1024 px) look at points 1.2-1.8 m
away. Exact projections agree with the true pair to round-off; turning the right camera by
0.1 deg (two PTU steps) moves epipolar lines by about 2.6 px, beyond INLIER_PX.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from ipbench.perception.calibration.consistency import (
    INLIER_PX,
    MIN_MATCHES,
    choose_pair,
    consensus,
)
from ipbench.perception.calibration.errors import CalibrationError

F_PX = 35.0 / 23.6 * 1024
K = np.array([[F_PX, 0.0, 511.5], [0.0, F_PX, 339.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.08, 0.05, 0.0005, -0.0003, 0.0])  # a mild lens, to exercise undistortion


def pose(x: float, yaw_deg: float = 0.0, pitch_deg: float = 0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(np.radians([pitch_deg, yaw_deg, 0.0]))[0]
    T[:3, 3] = [x, 0.0, 0.0]
    return T


def project(points: np.ndarray, T: np.ndarray) -> np.ndarray:
    inv = np.linalg.inv(T)
    rvec = cv2.Rodrigues(inv[:3, :3])[0]
    xy, _ = cv2.projectPoints(points, rvec, inv[:3, 3], K, DIST)
    return xy.reshape(-1, 2)


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(0)
    points = np.column_stack([rng.uniform(-0.3, 0.3, 200), rng.uniform(-0.2, 0.2, 200),
                              rng.uniform(1.2, 1.8, 200)])  # fmt: skip
    left, right = pose(0.0), pose(0.288)
    return points, left, right, project(points, left), project(points, right)


def test_the_true_pair_agrees_with_every_exact_match_and_a_turned_one_does_not(scene):
    _, left, right, xl, xr = scene
    turned = right @ pose(0.0, pitch_deg=0.1)  # two PTU steps about the right camera's x
    scores = consensus(xl, xr, K, K, DIST, DIST, {"true": (left, right), "turned": (left, turned)})
    assert scores["true"] == 1.0
    assert scores["turned"] < 0.1
    assert choose_pair(scores, prefer="turned") == "true"


def test_mismatches_cost_every_candidate_alike_so_the_right_matches_decide(scene):
    points, left, right, xl, xr = scene
    rng = np.random.default_rng(1)
    wrong = rng.permutation(len(xr))[:150]  # three matches in four wrong: as on a checkerboard
    shuffled = xr.copy()
    shuffled[wrong] = xr[np.roll(wrong, 1)]
    turned = right @ pose(0.0, pitch_deg=0.1)
    scores = consensus(xl, shuffled, K, K, DIST, DIST,
                       {"true": (left, right), "turned": (left, turned)})  # fmt: skip
    right_share = 1.0 - len(wrong) / len(xr)
    assert scores["true"] >= right_share  # every right match, and a few chance agreements
    assert scores["true"] > 2 * scores["turned"]
    assert choose_pair(scores, prefer="turned") == "true"


def test_the_preferred_candidate_wins_ties_and_bad_input_is_refused(scene):
    _, left, right, xl, xr = scene
    same = consensus(xl, xr, K, K, DIST, DIST, {"a": (left, right), "b": (left, right)})
    assert choose_pair(same, prefer="b") == "b" and choose_pair(same, prefer="a") == "a"
    with pytest.raises(CalibrationError, match="valid: one of"):
        choose_pair(same, prefer="c")
    with pytest.raises(CalibrationError, match="no candidate pairs"):
        consensus(xl, xr, K, K, DIST, DIST, {})
    with pytest.raises(CalibrationError, match=f"at least {MIN_MATCHES}"):
        consensus(xl[:5], xr[:5], K, K, DIST, DIST, {"a": (left, right)})
    assert INLIER_PX < 2.6  # the turned pair's line shift is outside the consensus band
