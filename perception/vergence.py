"""Vergence from feature disparities (thesis ch. 3 §3.3): where the two eyes' views agree.

The left and right images' features are matched (Lowe's ratio test); every match has a
horizontal disparity ``d = x_right - x_left`` (px). The disparities are histogrammed in bins
of :data:`DISPARITY_BIN_PX` = 4 px, and the peak bin (with its two neighbours, so a peak that
straddles a bin edge is not split) gives the disparity as the median of its matches' ``d``:

- global (non-selective) vergence: all matches — the dominant surface;
- selective vergence: only matches whose left keypoint lies in a region of interest of the
  left image (the attended object's box).

Verging turns the right camera so that this disparity goes to zero. A feature at column ``x``
of a camera with intrinsics ``K`` lies ``atan((x - cx) / fx)`` to the right of the optical
axis, so the turn that brings the peak's right-image column ``x_r`` onto its left-image column
``x_l`` is ``atan((x_r - cx) / fx) - atan((x_l - cx) / fx)``. Angles are in the camera's frame:
positive turns the optical axis towards image +x (right), a rotation about the camera's +y
(down) axis; the environment maps this to its pan-tilt unit's pan sign.

The 4 px bin is twice the 2 px vergence goal and is not tuned on any result; matches whose rows
differ by more than ``max_row_px`` (default 40 px, about 6 % of a 680-row image) are taken for
false matches of an epipolar-roughly-horizontal head (the two PTUs tilt together).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ipbench.perception.features2d import ActiveVisionError, Features
from ipbench.perception.matching import LOWE_RATIO, match

__all__ = [
    "DISPARITY_BIN_PX",
    "Vergence",
    "fixations_agree",
    "pan_angle",
    "pan_correction",
    "peak_disparity",
]

DISPARITY_BIN_PX = 4.0
MAX_ROW_PX = 40.0
FIXATION_TOLERANCE_PX = 20.0


@dataclass(frozen=True, eq=False)
class Vergence:
    """The peak disparity of a stereo pair.

    Attributes
    ----------
    disparity : float
        Median ``x_right - x_left`` of the peak's matches, px.
    x_left, x_right : float
        Median columns of the peak's matches in the left and right image, px.
    row_offset : float
        Median ``y_right - y_left`` of the peak's matches, px.
    support : int
        Matches in the peak (bin and neighbours).
    matches : (M, 2) int64 array
        All ``(left, right)`` feature index pairs considered (after the ROI and row filters).
    peak : (support,) int64 array
        Rows of ``matches`` in the peak.
    """

    disparity: float
    x_left: float
    x_right: float
    row_offset: float
    support: int
    matches: np.ndarray
    peak: np.ndarray


def peak_disparity(
    left: Features,
    right: Features,
    roi: tuple[float, float, float, float] | None = None,
    bin_px: float = DISPARITY_BIN_PX,
    max_row_px: float | None = MAX_ROW_PX,
    ratio: float = LOWE_RATIO,
    pairs: np.ndarray | None = None,
) -> Vergence | None:
    """Peak horizontal disparity of the matches; ``roi = (x0, y0, x1, y1)`` in the left image
    makes it selective. ``pairs`` reuses ``(left, right)`` matches computed already. ``None``
    when no match is left."""
    if bin_px <= 0:
        raise ActiveVisionError(f"bin_px is {bin_px}; valid: > 0 px")
    pairs = match(left, right, ratio) if pairs is None else np.asarray(pairs, np.int64)
    if pairs.ndim != 2 or pairs.shape[1] != 2:
        raise ActiveVisionError(f"pairs have shape {pairs.shape}; valid: (M, 2) index pairs")
    xl, xr = left.xy[pairs[:, 0]].astype(float), right.xy[pairs[:, 1]].astype(float)
    keep = np.ones(len(pairs), bool)
    if roi is not None:
        x0, y0, x1, y1 = map(float, roi)
        if not (x1 > x0 and y1 > y0):
            raise ActiveVisionError(f"roi is {roi}; valid: (x0, y0, x1, y1) with x1 > x0, y1 > y0")
        keep &= (xl[:, 0] >= x0) & (xl[:, 0] <= x1) & (xl[:, 1] >= y0) & (xl[:, 1] <= y1)
    if max_row_px is not None:
        keep &= np.abs(xr[:, 1] - xl[:, 1]) <= max_row_px
    pairs, xl, xr = pairs[keep], xl[keep], xr[keep]
    if len(pairs) == 0:
        return None
    d = xr[:, 0] - xl[:, 0]
    bins = np.floor(d / bin_px).astype(np.int64)
    labels, counts = np.unique(bins, return_counts=True)
    best = labels[np.argmax(counts)]  # ties: the smallest disparity bin
    peak = np.flatnonzero(np.abs(bins - best) <= 1)
    return Vergence(
        float(np.median(d[peak])),
        float(np.median(xl[peak, 0])),
        float(np.median(xr[peak, 0])),
        float(np.median(xr[peak, 1] - xl[peak, 1])),
        len(peak),
        pairs,
        peak.astype(np.int64),
    )


def _check_K(K: np.ndarray) -> np.ndarray:
    K = np.asarray(K, float)
    if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0:
        raise ActiveVisionError(f"K has shape {K.shape}; valid: finite 3x3 intrinsics, fx > 0")
    return K


def pan_angle(x: float, K: np.ndarray) -> float:
    """Angle (rad) of image column ``x`` right of the optical axis: ``atan((x - cx) / fx)``."""
    K = _check_K(K)
    return float(np.arctan((x - K[0, 2]) / K[0, 0]))


def pan_correction(vergence: Vergence, K: np.ndarray) -> float:
    """Turn (rad, + towards image +x) of the right camera (intrinsics ``K``) that moves the
    peak's right-image column onto its left-image column, i.e. the disparity to zero."""
    return pan_angle(vergence.x_right, K) - pan_angle(vergence.x_left, K)


def fixations_agree(
    left_xy: np.ndarray,
    right_xy: np.ndarray,
    disparity: float = 0.0,
    tolerance_px: float = FIXATION_TOLERANCE_PX,
) -> bool:
    """Whether a right-image point is where a left-image point is expected on a verged pair:
    within ``tolerance_px`` of ``left_xy + (disparity, 0)``. The default 20 px is ten times the
    2 px vergence goal (not tuned)."""
    left_xy, right_xy = np.asarray(left_xy, float), np.asarray(right_xy, float)
    if left_xy.shape != (2,) or right_xy.shape != (2,) or tolerance_px <= 0:
        raise ActiveVisionError("valid: left_xy and right_xy of shape (2,), tolerance_px > 0")
    return bool(np.linalg.norm(right_xy - left_xy - (disparity, 0.0)) <= tolerance_px)
