"""A set of rendered views, each stored as its FPFH descriptors and a fixed-size sample of its
segment's points, with its label and origin."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

__all__ = ["POINTS_PER_VIEW", "SOURCES", "ViewSet", "sample_points"]

SOURCES: tuple[str, ...] = ("isolated", "cluttered", "in_hand")
"""Where a view comes from: an object alone on the table, a segment of a cluttered scene, or
an object held up to the wrist camera by the gripper."""

POINTS_PER_VIEW = 512
"""Points stored per view (:attr:`ViewSet.points`): enough for a PointNet's shape cue at a
6 kB (float32) cost per view; segments with fewer points are sampled with replacement."""


def sample_points(points: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) float32 rows drawn from the (m, 3) ``points`` by ``rng``: without replacement
    when ``m >= n``, else every point once plus ``n - m`` drawn with replacement (so a small
    segment keeps all its points). The order is random; the frame and units are the input's."""
    points = np.asarray(points)
    if points.ndim != 2 or points.shape[1] != 3 or len(points) == 0:
        raise ValueError(f"points must be a non-empty (m, 3) array, got shape {points.shape}")
    m = len(points)
    if m >= n:
        idx = rng.choice(m, n, replace=False)
    else:
        idx = rng.permutation(np.concatenate([np.arange(m), rng.choice(m, n - m)]))
    return points[idx].astype(np.float32)


@dataclass(frozen=True)
class ViewSet:
    """Views with their FPFH descriptors and point samples.

    Attributes
    ----------
    descriptors : (total, 33) float32 FPFH descriptors of all views, concatenated.
    offsets : (n + 1,) int64: view i owns ``descriptors[offsets[i]:offsets[i+1]]``.
    labels : (n,) category index (bin order).
    instance : (n,) instance name.
    known : (n,) bool, known (training) instance.
    source : (n,) one of :data:`SOURCES`.
    points : (n, P, 3) float32 (P = :data:`POINTS_PER_VIEW`): a sample of each view's segment
        (:func:`sample_points`, seeded per view by the capture) in the world frame (m, z up;
        the frame the FPFH are computed in); NaN for views stored without points (synthetic
        sets).
    """

    descriptors: np.ndarray
    offsets: np.ndarray
    labels: np.ndarray
    instance: np.ndarray
    known: np.ndarray
    source: np.ndarray
    points: np.ndarray

    def __len__(self) -> int:
        return len(self.labels)

    def view(self, i: int) -> np.ndarray:
        return self.descriptors[self.offsets[i] : self.offsets[i + 1]]

    def subset(self, mask: np.ndarray) -> ViewSet:
        idx = np.flatnonzero(mask)
        parts = [self.view(i) for i in idx]
        lengths = np.array([len(p) for p in parts], np.int64)
        return ViewSet(
            descriptors=np.concatenate(parts) if parts else np.zeros((0, 33), np.float32),
            offsets=np.concatenate([[0], np.cumsum(lengths)]),
            labels=self.labels[idx],
            instance=self.instance[idx],
            known=self.known[idx],
            source=self.source[idx],
            points=self.points[idx],
        )

    @staticmethod
    def concat(sets: list[ViewSet]) -> ViewSet:
        sets = [s for s in sets if len(s)]
        if not sets:
            return _EMPTY
        lengths = np.concatenate([np.diff(s.offsets) for s in sets])
        return ViewSet(
            descriptors=np.concatenate([s.descriptors for s in sets]),
            offsets=np.concatenate([[0], np.cumsum(lengths)]),
            labels=np.concatenate([s.labels for s in sets]),
            instance=np.concatenate([s.instance for s in sets]),
            known=np.concatenate([s.known for s in sets]),
            source=np.concatenate([s.source for s in sets]),
            points=np.concatenate([s.points for s in sets]),
        )

    def save(self, path: Path) -> None:
        np.savez_compressed(path, **asdict(self))

    @classmethod
    def from_views(
        cls,
        descriptors: Sequence[np.ndarray],
        labels: Sequence[int],
        instance: Sequence[str],
        known: Sequence[bool],
        source: str,
        points: Sequence[np.ndarray] | None = None,
    ) -> ViewSet:
        """A set of ``len(descriptors)`` views from one ``source``; view i has the (n_i, 33)
        FPFH descriptors ``descriptors[i]`` and the (P, 3) point sample ``points[i]`` (None:
        no points, stored as NaN)."""
        if source not in SOURCES:
            raise ValueError(f"unknown view source {source!r}; valid: {', '.join(SOURCES)}")
        n = len(descriptors)
        if not len(labels) == len(instance) == len(known) == n:
            raise ValueError("descriptors, labels, instance and known must have one entry per view")
        shape = (n, POINTS_PER_VIEW, 3)
        if points is None:
            cloud = np.full(shape, np.nan, np.float32)
        else:
            cloud = np.asarray(points, np.float32) if n else np.zeros(shape, np.float32)
            if cloud.shape != shape:
                raise ValueError(
                    f"points must hold one ({POINTS_PER_VIEW}, 3) sample per view "
                    f"(sample_points): got shape {cloud.shape} for {n} views"
                )
        lengths = np.array([len(d) for d in descriptors], np.int64)
        return cls(
            descriptors=(
                np.concatenate(descriptors).astype(np.float32)
                if n
                else np.zeros((0, 33), np.float32)
            ),
            offsets=np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
            labels=np.array(labels, np.int64).reshape(n),
            instance=np.array(instance, "U32").reshape(n),
            known=np.array(known, bool).reshape(n),
            source=np.full(n, source, "U16"),
            points=cloud,
        )

    @classmethod
    def load(cls, path: Path) -> ViewSet:
        with np.load(path, allow_pickle=False) as data:
            return cls(**{k: data[k] for k in cls.__dataclass_fields__})


_EMPTY = ViewSet(
    np.zeros((0, 33), np.float32),
    np.zeros(1, np.int64),
    np.zeros(0, np.int64),
    np.zeros(0, "U32"),
    np.zeros(0, bool),
    np.zeros(0, "U16"),
    np.zeros((0, POINTS_PER_VIEW, 3), np.float32),
)
