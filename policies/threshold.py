"""Choosing a confidence-driven policy's threshold on validation data.

The evidence: labelled decisions taken on validation data disjoint from the test seeds, each
with its predicted label's confidence and whether the label was right (ground truth is allowed
here: this is training, as labelling the training views is). No policy's score enters: only
labels, confidences and the truth.

The rule (:data:`RULE`) reads the evidence through a two-parameter calibration fit instead of
its raw counts, so that the threshold does not jump when a few decisions change:

1. Fit ``P(right | c) = sigmoid(a + b logit(c))`` by maximum likelihood (logistic calibration,
   Platt 1999; a weak ridge keeps it finite when every label is right), each distinct
   ``(confidence, right)`` pair weighted by its share of the evidence — so permuting or
   duplicating the evidence gives the same fit, bit for bit.
2. The fitted precision of a threshold ``t`` is the mean fitted ``P(right | c)`` over the
   decisions with ``c >= t``: the expected fraction of right labels among those sorted without
   inspection. It rises with ``t`` whenever confidence is informative (``b > 0``).
3. The threshold is the lowest point of :data:`THRESHOLD_GRID` (steps of 0.05) whose fitted
   precision reaches ``target_precision``; 1.0 (inspect everything) when none does.

One decision more or less moves the fit by about 1/n, so the chosen grid point moves by at
most one step; last-bit differences of the confidences between platforms move nothing unless
the fitted precision sits on the target within rounding. The raw precision (as counted) is
kept beside the fit for the report.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ipbench.policies.base import PolicyError

__all__ = ["RULE", "THRESHOLD_GRID", "ThresholdChoice", "choose_threshold", "fit_correctness"]

RULE = "logistic-precision"
"""Name of the rule of :func:`choose_threshold` (recorded with every chosen threshold)."""
THRESHOLD_GRID: np.ndarray = np.round(np.linspace(0.0, 1.0, 21), 2)
"""The thresholds the rule chooses from (0, 0.05, ..., 1)."""
_RIDGE = 1e-3  # penalty on (a, b) of the weighted log-likelihood (weights sum to 1)
_EPS = 1e-6  # confidences are clipped to [eps, 1 - eps] before the logit


@dataclass(frozen=True)
class ThresholdChoice:
    """The chosen ``threshold`` and the sweep behind it.

    ``thresholds`` (k,): :data:`THRESHOLD_GRID`; ``precision`` (k,): fraction of right labels
    at or above each threshold, as counted (nan when none); ``fitted_precision`` (k,): the same
    under the calibration fit (what the rule reads; nan when none); ``inspected`` (k,): fraction
    of decisions below each threshold; ``fit``: ``(a, b)`` of ``sigmoid(a + b logit(c))``.
    """

    threshold: float
    target_precision: float
    n: int
    thresholds: np.ndarray
    precision: np.ndarray
    inspected: np.ndarray
    fitted_precision: np.ndarray
    fit: tuple[float, float]
    rule: str = RULE


def _evidence(confidence, correct) -> tuple[np.ndarray, np.ndarray]:
    c = np.asarray(confidence, dtype=float)
    ok = np.asarray(correct, dtype=bool)
    if c.ndim != 1 or c.shape != ok.shape or c.size == 0:
        raise PolicyError(
            f"need equal non-empty 1-D confidence and correct, got {c.shape}, {ok.shape}"
        )
    if not np.all(np.isfinite(c)) or c.min() < 0.0 or c.max() > 1.0:
        raise PolicyError("confidences must be finite and in [0, 1]")
    return c, ok


def _logit(c: np.ndarray) -> np.ndarray:
    c = np.clip(c, _EPS, 1.0 - _EPS)
    return np.log(c) - np.log1p(-c)


def _pairs(confidence, correct) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distinct ``(confidence, correct)`` pairs, sorted, and each one's share of the
    evidence: what the rule reads, the same for permuted or uniformly duplicated evidence."""
    c, ok = _evidence(confidence, correct)
    pairs, counts = np.unique(np.stack([c, ok.astype(float)], axis=1), axis=0, return_counts=True)
    return pairs[:, 0], pairs[:, 1] > 0.5, counts / counts.sum()


def _fit(c: np.ndarray, ok: np.ndarray, w: np.ndarray) -> np.ndarray:
    x = np.stack([np.ones(len(c)), _logit(c)], axis=1)
    y = ok.astype(float)
    theta = np.zeros(2)
    for _ in range(100):
        p = 1.0 / (1.0 + np.exp(-(x @ theta)))
        grad = x.T @ (w * (p - y)) + _RIDGE * theta
        hess = (x * (w * p * (1.0 - p))[:, None]).T @ x + _RIDGE * np.eye(2)
        step = np.linalg.solve(hess, grad)
        theta = theta - step
        if np.max(np.abs(step)) < 1e-10:
            break
    return theta


def fit_correctness(confidence, correct) -> tuple[float, float]:
    """``(a, b)`` of the logistic calibration ``P(right | c) = sigmoid(a + b logit(c))``.

    ``confidence`` (n,) in [0, 1], ``correct`` (n,) bool. Newton's method on the ridge-penalised
    mean log-likelihood over the distinct ``(confidence, correct)`` pairs weighted by their
    counts: invariant to the order of the evidence and to duplicating all of it.
    """
    a, b = _fit(*_pairs(confidence, correct))
    return float(a), float(b)


def choose_threshold(
    confidence: np.ndarray, correct: np.ndarray, target_precision: float = 0.95
) -> ThresholdChoice:
    """The lowest grid threshold whose fitted precision reaches ``target_precision`` (module
    docstring). ``confidence`` (n,) in [0, 1], ``correct`` (n,) bool."""
    c, ok, w = _pairs(confidence, correct)
    if not 0.0 < target_precision <= 1.0:
        raise PolicyError(f"target_precision must be in (0, 1], got {target_precision!r}")
    a, b = _fit(c, ok, w)
    p_hat = 1.0 / (1.0 + np.exp(-(a + b * _logit(c))))
    grid = THRESHOLD_GRID
    accepted = [c >= t for t in grid]

    def mean(values: np.ndarray, m: np.ndarray) -> float:
        return float(np.sum(w[m] * values[m]) / np.sum(w[m])) if m.any() else np.nan

    precision = np.array([mean(ok.astype(float), m) for m in accepted])
    fitted = np.array([mean(p_hat, m) for m in accepted])
    inspected = np.array([float(np.sum(w[~m])) for m in accepted])
    reach = np.flatnonzero(np.nan_to_num(fitted, nan=0.0) >= target_precision)
    threshold = float(grid[reach[0]]) if reach.size else 1.0
    return ThresholdChoice(
        threshold,
        float(target_precision),
        int(np.asarray(confidence).size),
        grid.copy(),
        precision,
        inspected,
        fitted,
        (float(a), float(b)),
    )
