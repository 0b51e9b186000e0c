"""A set of rendered views, each stored as its FPFH descriptors with its label and origin."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

__all__ = ["SOURCES", "ViewSet"]

SOURCES: tuple[str, ...] = ("isolated", "cluttered", "in_hand")
"""Where a view comes from: an object alone on the table, a segment of a cluttered scene, or
an object held up to the wrist camera by the gripper."""


@dataclass(frozen=True)
class ViewSet:
    """Views with their FPFH descriptors.

    Attributes
    ----------
    descriptors : (total, 33) float32 FPFH descriptors of all views, concatenated.
    offsets : (n + 1,) int64: view i owns ``descriptors[offsets[i]:offsets[i+1]]``.
    labels : (n,) category index (bin order).
    instance : (n,) instance name.
    known : (n,) bool, known (training) instance.
    source : (n,) one of :data:`SOURCES`.
    """

    descriptors: np.ndarray
    offsets: np.ndarray
    labels: np.ndarray
    instance: np.ndarray
    known: np.ndarray
    source: np.ndarray

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
    ) -> ViewSet:
        """A set of ``len(descriptors)`` views from one ``source``; view i has the (n_i, 33)
        FPFH descriptors ``descriptors[i]``."""
        if source not in SOURCES:
            raise ValueError(f"unknown view source {source!r}; valid: {', '.join(SOURCES)}")
        n = len(descriptors)
        if not len(labels) == len(instance) == len(known) == n:
            raise ValueError("descriptors, labels, instance and known must have one entry per view")
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
)
