"""Splitting a segment that holds several touching objects.

Euclidean clustering (:mod:`~ipbench.perception.segmentation`) joins objects that touch: in
the cluttered scene every object stands against a neighbour, and a quarter of the segments
of a view hold two to seven objects. Such a segment is recognisable by its size: its box
fits no object the robot sorts (:class:`ObjectEnvelope`, the boxes an object of the task
fills in its resting poses — a size prior, not a label). A segment that fits no envelope is
split by a marker-controlled watershed of its top-down height map (the classical remedy for
touching objects seen from above): each object's top is a plateau at a local maximum of the
height map (markers: cells within ``peak_tolerance`` of the highest cell within
``peak_window``), and the cells flood down from the markers until the fronts meet in the
valleys between objects. Points go with their cell; parts with fewer than ``min_points``
points join the part of their nearest point. A segment that fits an envelope, or whose map
has one marker, is returned as it was.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from .cloud import PerceptionError
from .segmentation import Segment, make_segment, plane_basis

__all__ = ["ObjectEnvelope", "SplitConfig", "fits_one_object", "split_merged", "split_segment"]


@dataclass(frozen=True)
class ObjectEnvelope:
    """The box an object fills in one resting pose on the table: footprint sides ``long`` >=
    ``short`` and ``height`` (m)."""

    long: float
    short: float
    height: float

    def __post_init__(self) -> None:
        if not (self.long >= self.short > 0 and self.height > 0):
            raise PerceptionError(
                f"ObjectEnvelope({self.long}, {self.short}, {self.height}); valid: "
                "long >= short > 0 and height > 0 (m)"
            )


@dataclass(frozen=True)
class SplitConfig:
    """Settings of the split (m unless said otherwise).

    ``margin``: a segment fits an envelope when each of its box sides is at most the
    envelope's plus this (depth noise widens a segment's box by up to a centimetre);
    ``cell``: height-map cell; ``peak_window``, ``peak_tolerance``: a marker cell is within
    ``peak_tolerance`` of the highest cell in the ``peak_window`` square around it (an
    object's top, flat to within the tolerance, is narrower than two windows only when the
    object is); ``min_peak_height``: markers stand at least this high above the table;
    ``min_points``: a part keeps at least this many points (as the segmentation's size rule).
    """

    margin: float = 0.015
    cell: float = 0.005
    peak_window: float = 0.05
    peak_tolerance: float = 0.01
    min_peak_height: float = 0.02
    min_points: int = 100

    def __post_init__(self) -> None:
        for name in ("margin", "cell", "peak_window", "peak_tolerance", "min_peak_height"):
            if not getattr(self, name) >= 0:
                raise PerceptionError(f"SplitConfig.{name}={getattr(self, name)!r}; valid: >= 0")
        if not (self.cell > 0 and self.peak_window >= self.cell and self.min_points >= 1):
            raise PerceptionError(
                f"SplitConfig(cell={self.cell}, peak_window={self.peak_window}, "
                f"min_points={self.min_points}); valid: cell > 0, peak_window >= cell, "
                "min_points >= 1"
            )


DEFAULT_SPLIT = SplitConfig()


def _as_array(envelopes: Sequence[ObjectEnvelope]) -> np.ndarray:
    if len(envelopes) == 0:
        raise PerceptionError("no object envelopes; valid: at least one ObjectEnvelope")
    return np.array([(e.long, e.short, e.height) for e in envelopes], dtype=float)


def fits_one_object(
    segment: Segment, envelopes: Sequence[ObjectEnvelope], margin: float = DEFAULT_SPLIT.margin
) -> bool:
    """Whether ``segment``'s box (longer and shorter footprint side, height) fits in at least
    one of ``envelopes`` grown by ``margin`` (m)."""
    long, short = sorted(np.asarray(segment.box_extent[:2], dtype=float))[::-1]
    size = np.array([long, short, float(segment.height)])
    return bool(np.any(np.all(size <= _as_array(envelopes) + margin, axis=1)))


def split_segment(
    segment: Segment,
    plane: tuple[np.ndarray, float],
    envelopes: Sequence[ObjectEnvelope],
    config: SplitConfig = DEFAULT_SPLIT,
) -> tuple[Segment, ...]:
    """``segment`` cut into one part per object top by the watershed of the module
    docstring (largest part first); ``plane`` = ``(normal, offset)`` of the table, as in
    :class:`~ipbench.perception.segmentation.SceneSegmentation`. A map with one marker gives
    ``(segment,)``."""
    normal, offset = np.asarray(plane[0], dtype=float), float(plane[1])
    points = np.asarray(segment.points, dtype=float)
    e1, e2 = plane_basis(normal)
    flat = np.column_stack([points @ e1, points @ e2])
    height = points @ normal + offset
    ij = np.floor((flat - flat.min(axis=0)) / config.cell).astype(np.int64) + 1
    shape = tuple(ij.max(axis=0) + 2)
    top = np.zeros(shape)
    np.maximum.at(top, (ij[:, 0], ij[:, 1]), np.maximum(height, 1e-6))
    seen = top > 0
    # close one-cell holes (depth drop-outs) so that an object's top stays one plateau
    filled = np.where(seen, top, ndimage.grey_closing(top, size=3))
    occupied = filled > 0
    k = max(3, int(round(config.peak_window / config.cell)) | 1)
    peaks = (
        (filled >= ndimage.maximum_filter(filled, size=k) - config.peak_tolerance)
        & occupied
        & (filled > config.min_peak_height)
    )
    markers, n = ndimage.label(peaks)
    if n <= 1:
        return (segment,)
    depth = np.round((filled.max() - filled) / max(filled.max(), 1e-9) * 65535).astype(np.uint16)
    seeds = np.where(occupied, markers, -1).astype(np.int32)
    seeds[occupied & (markers == 0)] = 0
    grid = ndimage.watershed_ift(depth, seeds)
    grid[~occupied] = 0
    labels = _merge_parts(grid, filled, ij, points, normal, offset, envelopes, config)
    return _parts(segment, labels, normal, offset, config)


def _saddles(grid: np.ndarray, filled: np.ndarray) -> dict[tuple[int, int], float]:
    """Highest pass (m) between each pair of 4-adjacent labelled regions of ``grid``."""
    out: dict[tuple[int, int], float] = {}
    for a, b, ha, hb in (
        (grid[1:], grid[:-1], filled[1:], filled[:-1]),
        (grid[:, 1:], grid[:, :-1], filled[:, 1:], filled[:, :-1]),
    ):
        edge = (a != b) & (a > 0) & (b > 0)
        lo, hi = np.minimum(a[edge], b[edge]), np.maximum(a[edge], b[edge])
        for x, y, h in zip(
            lo.tolist(), hi.tolist(), np.minimum(ha[edge], hb[edge]).tolist(), strict=True
        ):
            if h > out.get((x, y), -1.0):
                out[(x, y)] = h
    return out


def _merge_parts(grid, filled, ij, points, normal, offset, envelopes, config) -> np.ndarray:
    """Point labels (N,) after merging adjacent watershed regions, shallowest valley first,
    while the merged region still fits one object (fragments of one object's top: a bowl's
    rim and floor, a lying bottle's crown and shoulder)."""
    labels = grid[ij[:, 0], ij[:, 1]].copy()
    peak = {int(k): float(filled[grid == k].max()) for k in np.unique(grid) if k > 0}
    saddle = _saddles(grid, filled)
    while saddle:
        order = sorted(saddle, key=lambda e: min(peak[e[0]], peak[e[1]]) - saddle[e])
        for a, b in order:
            both = (labels == a) | (labels == b)
            union = make_segment(points[both], np.zeros(int(both.sum()), np.int64), normal, offset)
            if fits_one_object(union, envelopes, config.margin):
                break
        else:
            break
        labels[labels == b] = a
        peak[a] = max(peak[a], peak.pop(b))
        merged: dict[tuple[int, int], float] = {}
        for (x, y), h in saddle.items():
            x, y = (a if x == b else x), (a if y == b else y)
            if x != y:
                key = (min(x, y), max(x, y))
                merged[key] = max(h, merged.get(key, -1.0))
        saddle = merged
    return labels


def _parts(segment: Segment, labels: np.ndarray, normal, offset, config) -> tuple[Segment, ...]:
    """One segment per label with at least ``min_points`` points (the others' points join
    the part of their nearest point), largest first; ``(segment,)`` if that is one part."""
    points = np.asarray(segment.points, dtype=float)
    ids, counts = np.unique(labels, return_counts=True)
    big = [int(k) for k, c in zip(ids, counts, strict=True) if k > 0 and c >= config.min_points]
    if len(big) <= 1:
        return (segment,)
    keep = np.isin(labels, big)
    if not keep.all():
        _, nearest = cKDTree(points[keep]).query(points[~keep])
        labels = labels.copy()
        labels[~keep] = labels[keep][nearest]
    parts = [
        make_segment(points[labels == k], segment.pixels[labels == k], normal, offset) for k in big
    ]
    return tuple(sorted(parts, key=lambda s: -len(s.points)))


def split_merged(
    segments: Sequence[Segment],
    plane: tuple[np.ndarray, float],
    envelopes: Sequence[ObjectEnvelope],
    config: SplitConfig = DEFAULT_SPLIT,
) -> tuple[Segment, ...]:
    """``segments`` with each one that fits no envelope replaced by its parts
    (:func:`split_segment`), largest first."""
    out: list[Segment] = []
    for segment in segments:
        if fits_one_object(segment, envelopes, config.margin):
            out.append(segment)
        else:
            out.extend(split_segment(segment, plane, envelopes, config))
    return tuple(sorted(out, key=lambda s: -len(s.points)))
