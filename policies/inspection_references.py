"""The two reference policies that bound every confidence-driven inspection policy.

Both run the GP-IPM loop (:class:`~ipbench.policies.interactive.InteractiveSorter`: the most
confident object first, inspection in hand, the fused label decides the bin) and differ only in
*whether* an object is inspected:

* ``oracle-inspect`` (:class:`OracleInspectSorter`) inspects exactly the objects whose first
  label is wrong, asking the ground truth (``info``) — the best any confidence can do with this
  inspection. The label after looking still comes from perception.
* ``random-inspect@P`` (:class:`RandomInspectSorter`) inspects each object with probability
  ``P``, from a generator seeded by the episode seed — what a confidence without information
  gives at an inspection rate of ``P``.
"""

from __future__ import annotations

import numpy as np

from ipbench.policies.base import PolicyError
from ipbench.policies.interactive import InteractiveConfig, InteractiveSorter
from ipbench.policies.oracle import true_category
from ipbench.policies.perceiver import Detection, Perceiver

__all__ = ["OracleInspectSorter", "RandomInspectSorter"]

_CONFIG = InteractiveConfig(threshold=1.0)  # the threshold is never read


class OracleInspectSorter(InteractiveSorter):
    """Inspects an object exactly when its first label is not its true category (an object
    the ground truth cannot name, e.g. a segment of the table, is sorted as labelled)."""

    def __init__(
        self,
        perceiver: Perceiver,
        config: InteractiveConfig = _CONFIG,
        name: str = "oracle-inspect",
    ) -> None:
        super().__init__(perceiver, config, name)

    def inspects(self, detection: Detection, info: dict | None) -> bool:
        if info is None:
            raise PolicyError(f"{self.name} reads the ground truth: call act(observation, info)")
        truth = true_category(detection.segment.pixels, info)
        return truth is not None and detection.label != truth


class RandomInspectSorter(InteractiveSorter):
    """Inspects each object with probability ``fraction`` (in [0, 1]); ``reset(seed)`` seeds
    the draws, one per object chosen."""

    def __init__(
        self,
        perceiver: Perceiver,
        fraction: float,
        config: InteractiveConfig = _CONFIG,
        name: str = "random-inspect",
    ) -> None:
        if not 0.0 <= fraction <= 1.0:
            raise PolicyError(f"random-inspect fraction must be in [0, 1], got {fraction!r}")
        super().__init__(perceiver, config, name)
        self.fraction = float(fraction)
        self._rng = np.random.default_rng()

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self._rng = np.random.default_rng(seed)

    def inspects(self, detection: Detection, info: dict | None) -> bool:
        return bool(self._rng.random() < self.fraction)
