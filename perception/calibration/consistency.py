"""Which of several estimates of the head's stereo pair agrees with what the cameras see.

The dynamic update (:mod:`~ipbench.perception.calibration.dynamic`) re-estimates each head
camera's pose from tracked features after a PTU move. It can be wrong (a PnP fit on few or
clustered features), and the robot has no ground truth to tell. It has the images: a stereo
pair whose relative pose is right maps every left feature onto the epipolar line of its right
match. :func:`epipolar_consistency` scores candidate pairs (say the encoders' and the
update's) by their consensus: the fraction of one set of left/right matches, in the images
both candidates are meant to explain, whose right feature lies within :data:`INLIER_PX` of its
left feature's epipolar line (RANSAC's consensus set, Fischler & Bolles, CACM 1981).
:func:`choose_pair` keeps the candidate with the largest consensus.

The matches are Lowe ratio-test matches (:func:`~ipbench.perception.matching.match`), the same
for every candidate. Most of them can be wrong (a checkerboard's repeated squares pass the
ratio test across squares): a mismatch is outside every candidate's consensus, so only the
right matches decide. Neither a mean nor a median distance would do: with three matches in
four wrong, both measure the mismatches. Nor a RANSAC fundamental matrix as a filter: with most
matches on one plane (the board) its estimate is degenerate.

What the score sees: the pair's relative tilt and roll and the direction of its baseline (a
rotation error of 0.05 deg moves an epipolar line by 1.3 px at f = 1519 px, against a SIFT
keypoint noise of a few tenths of a pixel). It does not see the baseline's length, nor where
the pair is in the world, nor a vergence error (a relative turn about the cameras' vertical
axes moves features along their epipolar lines): that one scales the triangulated depth, so a
pair can pass the check and still reconstruct a board worse than another.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ipbench.perception.calibration.errors import CalibrationError
from ipbench.perception.features2d import DEFAULT_MAX_FEATURES, ActiveVisionError, detect
from ipbench.perception.matching import LOWE_RATIO, match
from ipbench.perception.stereo import StereoRig

__all__ = ["INLIER_PX", "MIN_MATCHES", "choose_pair", "consensus", "epipolar_consistency"]

INLIER_PX = 1.0
"""A match agrees with a candidate within this distance to its epipolar line, px: a few times
SIFT's keypoint noise (a few tenths of a pixel), under the 1.3 px a 0.05 deg rotation error
moves a line by at f = 1519 px."""
MIN_MATCHES = 12
"""Fewest filtered matches a score is computed from (as the dynamic update's stages)."""


def epipolar_consistency(
    left_img: np.ndarray,
    right_img: np.ndarray,
    K_l: np.ndarray,
    K_r: np.ndarray,
    dist_l: np.ndarray | None,
    dist_r: np.ndarray | None,
    pairs: Mapping[str, tuple[np.ndarray, np.ndarray]],
    feature_type: str = "sift",
    *,
    max_features: int = DEFAULT_MAX_FEATURES,
    ratio: float = LOWE_RATIO,
) -> dict[str, float]:
    """Consensus of one image pair's matches with each candidate pose pair (a fraction).

    ``left_img`` and ``right_img`` are the two head images taken at one moment (uint8, as
    captured: distorted); ``K_*`` (3, 3) px and ``dist_*`` (5,) or None the calibrated
    intrinsics; ``pairs`` maps a candidate's name to its ``(T_world_left, T_world_right)``
    (4, 4) m. Returns ``{name: fraction}``: the fraction of the matches whose epipolar
    distance under the candidate is within :data:`INLIER_PX` (:func:`consensus`; larger is
    more consistent). Raises
    :class:`CalibrationError` when there are fewer than :data:`MIN_MATCHES` matches, or when
    ``pairs`` is empty.
    """
    if not pairs:
        raise CalibrationError("no candidate pairs; valid: a mapping name -> (T_wl, T_wr)")
    try:
        left = detect(left_img, feature_type, max_features=max_features)
        right = detect(right_img, feature_type, max_features=max_features)
    except ActiveVisionError as error:
        raise CalibrationError(f"epipolar consistency: {error}") from error
    index = match(left, right, ratio) if len(left) and len(right) else np.zeros((0, 2), int)
    if len(index) < MIN_MATCHES:
        raise CalibrationError(
            f"only {len(index)} left/right {feature_type} matches; need at least {MIN_MATCHES}:"
            " point the head at a textured scene both cameras see"
        )
    xl = left.xy[index[:, 0]].astype(np.float64)
    xr = right.xy[index[:, 1]].astype(np.float64)
    return consensus(xl, xr, K_l, K_r, dist_l, dist_r, pairs)


def consensus(
    xy_left: np.ndarray,
    xy_right: np.ndarray,
    K_l: np.ndarray,
    K_r: np.ndarray,
    dist_l: np.ndarray | None,
    dist_r: np.ndarray | None,
    pairs: Mapping[str, tuple[np.ndarray, np.ndarray]],
) -> dict[str, float]:
    """Per candidate of ``pairs``, the fraction of the matched pixels ``xy_left``/``xy_right``
    ((N, 2) each, observed: distorted) within :data:`INLIER_PX` of their epipolar lines."""
    if not pairs:
        raise CalibrationError("no candidate pairs; valid: a mapping name -> (T_wl, T_wr)")
    if len(xy_left) != len(xy_right) or len(xy_left) < MIN_MATCHES:
        raise CalibrationError(
            f"{len(xy_left)} left and {len(xy_right)} right pixels; valid: as many of each, at"
            f" least {MIN_MATCHES}"
        )
    scores = {}
    for name, (T_l, T_r) in pairs.items():
        d = StereoRig(K_l, T_l, K_r, T_r, dist_l, dist_r).epipolar_distance(xy_left, xy_right)
        scores[name] = float(np.mean(d <= INLIER_PX))
    return scores


def choose_pair(scores: Mapping[str, float], prefer: str) -> str:
    """The candidate of ``scores`` with the largest consensus; ``prefer`` wins ties."""
    if prefer not in scores:
        raise CalibrationError(f"prefer is {prefer!r}; valid: one of {sorted(scores)}")
    best = max(scores.values())
    return prefer if scores[prefer] >= best else max(scores, key=scores.__getitem__)
