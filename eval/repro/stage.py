"""What a stage of :mod:`ipbench.eval.repro.digests` is: its fixed inputs, the digest of its
output arrays, its result and its tolerances."""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "EPISODE_STEPS",
    "IMAGE_SIZE",
    "LAYOUT_SEEDS",
    "PHYSICS_STEPS",
    "SCENE",
    "SEED",
    "Stage",
    "StageResult",
    "digest_arrays",
]

SEED = 0
"""The episode seed of every stage that resets an environment."""
SCENE = "cluttered"
"""The scene of every stage that resets an environment (the harder one: contacts, occlusion)."""
LAYOUT_SEEDS = range(20)
"""Seeds whose layouts the ``layout`` stage samples, for every scene and catalogue."""
PHYSICS_STEPS = 250
"""``mj_step`` calls of the ``physics_settle`` stage after the reset (0.5 s at 2 ms)."""
EPISODE_STEPS = 6
"""Step limit of the ``episode_*`` stages (about 5 s each on one core)."""
IMAGE_SIZE = (480, 640)
"""(height, width) px of every rendered and synthetic image."""
_F = 570.0  # px; focal length of the synthetic depth images (the Xtion's at 640x480)
_NOISE_SEED = 12345  # seed of the depth-noise streams (that of the digests in tests/data)


def digest_arrays(*values) -> str:
    """SHA-256 hex digest of ``values``: arrays (dtype, shape and bytes), numbers or strings.

    Two calls agree iff every value has the same type, shape and bits.
    """
    h = hashlib.sha256()
    for value in values:
        if isinstance(value, str | bytes):
            raw = value.encode() if isinstance(value, str) else value
            h.update(f"s{len(raw)}:".encode())
            h.update(raw)
            continue
        arr = np.ascontiguousarray(value)
        if arr.dtype.hasobject:
            raise TypeError(f"cannot digest an object array ({arr.dtype}); pass numbers or str")
        h.update(f"a{arr.dtype.str}{arr.shape}:".encode())
        h.update(arr.tobytes())
    return h.hexdigest()


@dataclass(frozen=True)
class StageResult:
    """What a stage produced: part digests, summary numbers and its wall time (s)."""

    parts: dict[str, str]
    summary: dict[str, float]
    seconds: float = 0.0

    @property
    def digest(self) -> str:
        """SHA-256 of every part's name and digest: equal iff every part is."""
        return digest_arrays(*(f"{k}={v}" for k, v in sorted(self.parts.items())))

    def to_json(self) -> dict:
        """JSON-ready ``{"digest", "parts", "summary", "seconds"}``."""
        return {
            "digest": self.digest,
            "parts": dict(sorted(self.parts.items())),
            "summary": dict(self.summary),
            "seconds": round(self.seconds, 3),
        }


@dataclass(frozen=True)
class Stage:
    """One stage: what it runs and how its summaries may differ on another platform.

    ``tolerances``: summary name -> ``(abs, rel)``; two values ``a`` (here) and ``b`` (the
    reference) are close when ``|a - b| <= abs + rel * |b|``. A summary not listed (a count)
    must be equal. ``cheap``: no rendering and no physics (seconds; the cross-process test
    runs these).
    """

    name: str
    run: Callable[[], tuple[dict[str, str], dict[str, float]]]
    description: str
    tolerances: dict[str, tuple[float, float]] = field(default_factory=dict)
    depends_on: tuple[str, ...] = ()
    cheap: bool = False
