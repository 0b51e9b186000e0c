"""Choosing GP-IPM's confidence threshold on validation data.

The evidence: the decisions taken through validation episodes (seeds disjoint from the test
seeds), each with its predicted label's confidence and whether the label was right (ground
truth is allowed here: this is training, as labelling the training views is). The evaluation
gathers them from random sorting, which uses no threshold, so the evidence does not depend on
the threshold it chooses. The threshold is the lowest confidence at which the objects sorted
without inspection are still right at least ``target_precision`` of the time — everything
less sure is inspected. No policy's score enters: only labels, confidences and the truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ipbench.policies.base import PolicyError

__all__ = ["ThresholdChoice", "choose_threshold"]


@dataclass(frozen=True)
class ThresholdChoice:
    """The chosen ``threshold`` and the sweep behind it.

    ``thresholds`` (k,), ``precision`` (k,): accuracy of the labels at or above each
    threshold (nan when none), ``inspected`` (k,): fraction of objects below it.
    """

    threshold: float
    target_precision: float
    n: int
    thresholds: np.ndarray
    precision: np.ndarray
    inspected: np.ndarray


def choose_threshold(
    confidence: np.ndarray, correct: np.ndarray, target_precision: float = 0.95
) -> ThresholdChoice:
    """The lowest threshold whose accepted labels reach ``target_precision``.

    ``confidence`` (n,) in [0, 1], ``correct`` (n,) bool. When no threshold reaches the target,
    1.0 (inspect everything).
    """
    c = np.asarray(confidence, dtype=float)
    ok = np.asarray(correct, dtype=bool)
    if c.ndim != 1 or c.shape != ok.shape or c.size == 0:
        raise PolicyError(
            f"need equal non-empty 1-D confidence and correct, got {c.shape}, {ok.shape}"
        )
    if not 0.0 < target_precision <= 1.0:
        raise PolicyError(f"target_precision must be in (0, 1], got {target_precision!r}")
    grid = np.round(np.linspace(0.0, 1.0, 101), 2)
    precision = np.array([ok[c >= t].mean() if np.any(c >= t) else np.nan for t in grid])
    inspected = np.array([np.mean(c < t) for t in grid])
    reach = np.flatnonzero(np.nan_to_num(precision, nan=0.0) >= target_precision)
    threshold = float(grid[reach[0]]) if reach.size else 1.0
    return ThresholdChoice(threshold, target_precision, int(c.size), grid, precision, inspected)
