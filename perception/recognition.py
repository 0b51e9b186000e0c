"""Recognition of multiple same-class object instances (MSCOI, thesis ch. 3 §3.3).

1. Match the scene's features to every view of the database (Lowe's ratio test, per view, so
   that the overlapping views of one object do not fail each other's ratio test).
2. Each match votes for the object's centre in the scene: ``centre = xy_scene + s R(theta)
   offset``, with the scale ``s`` = ratio of keypoint sizes, ``theta`` = difference of keypoint
   angles, ``offset`` = the model keypoint's offset to the object centre in its view.
3. Per class, Lowe's (2004, §7.3) Hough transform: bins of location (width
   :attr:`RecognitionConfig.hough_fraction` = 0.25 of the class' largest view outline
   diagonal times the scale), orientation (30°) and scale (factor 2), each vote entered in the
   2 nearest bins of each dimension. Greedily, the bin with most live votes becomes a cluster
   and its votes are retired; repeat while a bin has ``min_inliers`` votes. Instances side by
   side are more than a quarter of their size apart, so they fall in separate bins. Votes with
   a size ratio beyond ``1/max_zoom..max_zoom`` (3 octaves) are false matches and dropped.
4. Verify a cluster with a RANSAC homography (``cv2.findHomography``) from the view with most
   votes in it to the scene: reprojection threshold 5 px (OpenCV's feature-homography
   tutorial), at least ``min_inliers`` = 10 distinct scene keypoints as inliers, and a
   non-degenerate outline (convex, not mirrored, not collapsed).
5. A hypothesis whose centre lies inside a stronger hypothesis' outline (of any class) is
   dropped: the same instance found twice, or a weak look-alike of another class (shared
   print, e.g. a common font, can give ten-odd consistent matches) where an object already is.

Scene keypoints that are inliers of no hypothesis are returned as ``unmatched``: features of
nothing known, which :mod:`~ipbench.perception.saliency` turns into places to look at.
No value here was tuned on a result.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ipbench.perception.features2d import ActiveVisionError, Features
from ipbench.perception.matching import LOWE_RATIO, match_many
from ipbench.perception.object_database import ObjectDatabase

__all__ = ["Hypothesis", "Recognition", "RecognitionConfig", "recognise"]


@dataclass(frozen=True)
class RecognitionConfig:
    """MSCOI settings (module docstring): ratio test, Hough bin widths, RANSAC check."""

    ratio: float = LOWE_RATIO
    hough_fraction: float = 0.25  # centre bin / predicted object size (Lowe 2004, §7.3)
    max_angle_deg: float = 30.0  # orientation bin (Lowe 2004, §7.3)
    max_scale_factor: float = 2.0  # scale bin (Lowe 2004, §7.3)
    reproj_px: float = 5.0  # RANSAC reprojection threshold (OpenCV feature-homography tutorial)
    min_inliers: int = 10
    max_zoom: float = 8.0  # a vote whose size ratio is beyond 1/8..8 (3 octaves) is dropped
    ransac_iters: int = 2000
    ransac_confidence: float = 0.995

    def __post_init__(self) -> None:
        if not (0 < self.ratio <= 1 and self.hough_fraction > 0 and self.max_angle_deg > 0):
            raise ActiveVisionError(f"invalid {self}; valid: 0 < ratio <= 1, positive bins")
        if (
            self.max_scale_factor <= 1
            or self.max_zoom <= 1
            or self.reproj_px <= 0
            or self.min_inliers < 4
        ):
            raise ActiveVisionError(
                f"invalid {self}; valid: max_scale_factor > 1, max_zoom > 1, reproj_px > 0,"
                " min_inliers >= 4"
            )


@dataclass(frozen=True, eq=False)
class Hypothesis:
    """One recognised object instance in a scene image.

    Attributes
    ----------
    class_name : str
        The object's class.
    centre : (2,) float64 array
        The object's centre (the view's centre through the homography), px.
    outline : (4, 2) float64 array
        The view's outline through the homography, px.
    inliers : int
        Distinct scene keypoints consistent with the homography (>= ``min_inliers``).
    score : float
        ``inliers`` / keypoints of the matched view, in [0, 1]: the share of the model found.
    inlier_indices : (inliers,) int64 array
        Indices of the inlier keypoints in the scene's :class:`Features`, sorted.
    view : int
        Index of the matched view in the database.
    homography : (3, 3) float64 array
        View pixels -> scene pixels.
    """

    class_name: str
    centre: np.ndarray
    outline: np.ndarray
    inliers: int
    score: float
    inlier_indices: np.ndarray
    view: int
    homography: np.ndarray = field(repr=False)


@dataclass(frozen=True, eq=False)
class Recognition:
    """Hypotheses, strongest (most inliers) first, and the scene keypoints none explains.

    ``unmatched`` : (U,) int64 indices into the scene's features, sorted.
    """

    hypotheses: tuple[Hypothesis, ...]
    unmatched: np.ndarray


@dataclass(frozen=True)
class _Votes:
    view: np.ndarray  # (n,) database view index
    scene: np.ndarray  # (n,) scene keypoint index
    model: np.ndarray  # (n,) keypoint index in the view
    centre: np.ndarray  # (n, 2) predicted object centre, px
    log_scale: np.ndarray  # (n,) log2 of the size ratio
    angle: np.ndarray  # (n,) rotation, rad


def _votes(
    scene: Features,
    database: ObjectDatabase,
    views: list[int],
    matches: list[np.ndarray],
    config: RecognitionConfig,
) -> _Votes:
    # ``matches[k]``: the scene's matches to view ``views[k]`` (the ratio test is per view);
    # the vote geometry in one vectorised pass over all views' matches, in view order
    found = [(vi, pairs) for vi, pairs in zip(views, matches, strict=True) if len(pairs)]
    if not found:
        empty = np.zeros(0)
        return _Votes(empty.astype(int), empty.astype(int), empty.astype(int),
                      np.zeros((0, 2)), empty, empty)  # fmt: skip
    view = np.concatenate([np.full(len(pairs), vi) for vi, pairs in found])
    s = np.concatenate([pairs[:, 0] for _, pairs in found])
    m = np.concatenate([pairs[:, 1] for _, pairs in found])
    picked = [(database.views[vi], pairs[:, 1]) for vi, pairs in found]
    m_size = np.concatenate([v.features.size[k] for v, k in picked])
    m_angle = np.concatenate([v.features.angle[k] for v, k in picked])
    m_off = np.concatenate([v.offsets[k] for v, k in picked])
    scale = scene.size[s].astype(float) / np.maximum(m_size, 1e-6)
    ok = np.abs(np.log(scale)) <= np.log(config.max_zoom)
    view, s, m, scale, m_angle, m_off = view[ok], s[ok], m[ok], scale[ok], m_angle[ok], m_off[ok]
    theta = np.deg2rad(scene.angle[s].astype(float) - m_angle)
    off = m_off.astype(float)
    c, sn = np.cos(theta), np.sin(theta)
    rotated = np.stack([c * off[:, 0] - sn * off[:, 1], sn * off[:, 0] + c * off[:, 1]], 1)
    centre = scene.xy[s] + scale[:, None] * rotated
    return _Votes(view, s, m, centre, np.log2(scale), theta)


def _hough_bins(
    votes: _Votes, model_size: float, config: RecognitionConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lowe's Hough transform: each vote goes into the 2 nearest bins of each of location x, y
    (width ``hough_fraction * model_size * scale``, the scale of its scale bin), orientation and
    log-scale: 16 entries. Returns each entry's bin id (16 n,), bins numbered in increasing
    key (as ``np.unique`` numbers them), the entries ordered by bin (16 n,) and each bin's
    first position in that order (bins + 1,). Entry ``k n + i`` is vote ``i``'s ``k``-th."""
    fs = votes.log_scale / np.log2(config.max_scale_factor)
    fa = votes.angle / np.deg2rad(config.max_angle_deg)
    n_angle = int(round(360.0 / config.max_angle_deg))
    # the 16 entries of each vote by broadcasting over (scale, angle, x, y, vote): the order of
    # four nested loops over the two nearest bins of each dimension
    s_bin = np.stack(_two_nearest(fs))  # (2, n)
    a_bin = np.stack(_two_nearest(fa)) % n_angle  # (2, n)
    width = config.hough_fraction * model_size * config.max_scale_factor ** (s_bin + 0.5)
    x_bin, y_bin = (
        np.clip(np.stack(_two_nearest(votes.centre[:, k] / width), 1), -(2**20), 2**20 - 1) + 2**20
        for k in (0, 1)
    )  # (2 scale, 2 location, n)
    key = (
        (x_bin[:, None, :, None] << 29)
        | (y_bin[:, None, None, :] << 8)
        | (a_bin[None, :, None, None] << 4)
        | (s_bin[:, None, None, None] + 8)
    ).ravel()
    by_bin = np.argsort(key)  # one sort; the order inside a bin does not matter
    ordered = key[by_bin]
    first = np.flatnonzero(np.r_[True, ordered[1:] != ordered[:-1]])
    bin_of = np.empty(len(key), np.int64)
    bin_of[by_bin] = np.repeat(np.arange(len(first)), np.diff(np.r_[first, len(key)]))
    return bin_of, by_bin, np.r_[first, len(key)]


def _two_nearest(value: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The bin of ``value`` (bins of width 1) and its neighbour nearest to ``value``."""
    low = np.floor(value).astype(np.int64)
    return low, np.where(value - low >= 0.5, low + 1, low - 1)


def _good_outline(outline: np.ndarray) -> bool:
    quad = outline.astype(np.float32)
    if not np.all(np.isfinite(quad)) or not cv2.isContourConvex(quad):
        return False
    x, y = quad[:, 0], quad[:, 1]
    signed = 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    return signed > 1.0  # clockwise on screen (y down) as the view's outline: not mirrored


def _verify(
    scene: Features,
    database: ObjectDatabase,
    votes: _Votes,
    members: np.ndarray,
    config: RecognitionConfig,
) -> Hypothesis | None:
    if len(members) < config.min_inliers:
        return None
    vi = int(np.argmax(np.bincount(votes.view[members])))  # most votes; ties: the lowest view
    chosen = members[votes.view[members] == vi]
    if len(np.unique(votes.scene[chosen])) < config.min_inliers:
        return None
    view = database.views[vi]
    src = view.features.xy[votes.model[chosen]].astype(np.float64)
    dst = scene.xy[votes.scene[chosen]].astype(np.float64)
    H, mask = cv2.findHomography(
        src, dst, cv2.RANSAC, config.reproj_px,
        maxIters=config.ransac_iters, confidence=config.ransac_confidence,
    )  # fmt: skip
    if H is None or mask is None:
        return None
    inlier_scene = np.unique(votes.scene[chosen][mask.ravel() != 0])
    if len(inlier_scene) < config.min_inliers:
        return None
    outline = cv2.perspectiveTransform(view.outline[None].astype(np.float64), H)[0]
    if not _good_outline(outline):
        return None
    centre = cv2.perspectiveTransform(view.centre[None, None].astype(np.float64), H)[0, 0]
    return Hypothesis(
        view.class_name, centre, outline, len(inlier_scene),
        len(inlier_scene) / max(len(view.features), 1), inlier_scene.astype(np.int64), vi, H,
    )  # fmt: skip


def _cluster(
    scene: Features,
    database: ObjectDatabase,
    votes: _Votes,
    model_size: float,
    config: RecognitionConfig,
) -> list[Hypothesis]:
    found: list[Hypothesis] = []
    if len(votes.scene) < config.min_inliers:
        return found
    bin_of, by_bin, start = _hough_bins(votes, model_size, config)
    n = len(votes.scene)
    entries = bin_of.reshape(-1, n)  # entries[k, i]: the k-th of vote i's 16 bins
    # live entries per bin, kept up to date as votes retire (equal to a fresh bincount of the
    # live entries every round, without the O(16 n) pass per round)
    counts = np.diff(start)
    owner = by_bin % n  # the vote of each entry, in bin order
    alive = np.ones(n, bool)

    def retire(index: np.ndarray) -> None:
        alive[index] = False
        np.subtract.at(counts, entries[:, index].ravel(), 1)

    while alive.sum() >= config.min_inliers:
        best = int(np.argmax(counts))  # ties: the lowest bin id (deterministic)
        if counts[best] < config.min_inliers:
            break
        in_bin = owner[start[best] : start[best + 1]]
        members = np.unique(in_bin[alive[in_bin]])
        retire(members)
        hypothesis = _verify(scene, database, votes, members, config)
        if hypothesis is not None:
            found.append(hypothesis)
            retire(np.flatnonzero(alive & np.isin(votes.scene, hypothesis.inlier_indices)))
    return found


def recognise(
    scene: Features, database: ObjectDatabase, config: RecognitionConfig | None = None
) -> Recognition:
    """All instances of the database's classes in a scene's features (module docstring)."""
    config = config or RecognitionConfig()
    if scene.feature_type != database.feature_type:
        raise ActiveVisionError(
            f"scene has {scene.feature_type} features, the database {database.feature_type};"
            " valid: detect the scene with the database's feature type"
        )
    candidates: list[Hypothesis] = []
    matches = match_many(scene, database.train_set, config.ratio)
    for name in database.classes:
        views = [i for i, v in enumerate(database.views) if v.class_name == name]
        model_size = 2.0 * max(database.views[i].radius for i in views)
        votes = _votes(scene, database, views, [matches[i] for i in views], config)
        candidates += _cluster(scene, database, votes, model_size, config)
    candidates.sort(key=lambda h: (-h.inliers, -h.score, h.class_name, h.centre[0], h.centre[1]))
    kept: list[Hypothesis] = []
    for h in candidates:  # one place, two hypotheses: keep the stronger
        if not any(
            cv2.pointPolygonTest(k.outline.astype(np.float32), tuple(map(float, h.centre)), False)
            >= 0
            for k in kept
        ):
            kept.append(h)
    explained = np.zeros(len(scene), bool)
    for h in kept:
        explained[h.inlier_indices] = True
    return Recognition(tuple(kept), np.flatnonzero(~explained).astype(np.int64))
