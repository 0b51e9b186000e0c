"""Classification and calibration metrics (pure numpy).

Conventions: ``probs`` is an ``(m, C)`` array of predicted class probabilities (rows sum to
one), ``labels`` and ``preds`` are ``(m,)`` integer arrays in ``0 .. C - 1``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "accuracy",
    "confusion_matrix",
    "expected_calibration_error",
    "log_loss",
    "per_class_precision_recall",
    "reliability_curve",
]


def _check(probs: np.ndarray, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    p = np.asarray(probs, dtype=float)
    y = np.asarray(labels)
    if p.ndim != 2 or y.ndim != 1 or p.shape[0] != y.shape[0] or p.shape[0] == 0:
        raise ValueError(
            f"need probs (m, C) and labels (m,) with m > 0, got {p.shape} and {y.shape}"
        )
    y = y.astype(np.int64)
    if y.min() < 0 or y.max() >= p.shape[1]:
        raise ValueError(f"labels must lie in 0..{p.shape[1] - 1}, got {y.min()}..{y.max()}")
    return p, y


def accuracy(labels: np.ndarray, preds: np.ndarray) -> float:
    """Fraction of ``preds`` equal to ``labels`` (both ``(m,)``)."""
    labels, preds = np.asarray(labels), np.asarray(preds)
    if labels.shape != preds.shape or labels.ndim != 1 or labels.size == 0:
        raise ValueError(f"need equal non-empty 1-D shapes, got {labels.shape}, {preds.shape}")
    return float(np.mean(labels == preds))


def log_loss(probs: np.ndarray, labels: np.ndarray, eps: float = 1e-15) -> float:
    """Mean negative log probability of the true class, in nats.

    Probabilities are clipped to ``[eps, 1]`` so a confident mistake costs at most
    ``-log(eps)`` (34.5 nats for the default).
    """
    p, y = _check(probs, labels)
    return float(-np.mean(np.log(np.clip(p[np.arange(y.size), y], eps, 1.0))))


def reliability_curve(
    probs: np.ndarray, labels: np.ndarray, n_bins: int = 15
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-bin mean confidence, accuracy and count on equal-width confidence bins.

    Confidence is the maximum class probability; bin ``b`` holds confidences in
    ``(b / n_bins, (b + 1) / n_bins]`` (bin 0 also holds 0).

    Returns
    -------
    bin_conf, bin_acc : (n_bins,) arrays, NaN for empty bins.
    bin_count : (n_bins,) int array.
    """
    p, y = _check(probs, labels)
    if n_bins < 1:
        raise ValueError(f"n_bins must be >= 1, got {n_bins}")
    conf = p.max(axis=1)
    correct = (p.argmax(axis=1) == y).astype(float)
    idx = np.clip(np.ceil(conf * n_bins).astype(np.int64) - 1, 0, n_bins - 1)
    count = np.bincount(idx, minlength=n_bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        bin_conf = np.bincount(idx, weights=conf, minlength=n_bins) / count
        bin_acc = np.bincount(idx, weights=correct, minlength=n_bins) / count
    return bin_conf, bin_acc, count


def expected_calibration_error(probs: np.ndarray, labels: np.ndarray, n_bins: int = 15) -> float:
    """ECE: ``sum_b (n_b / m) |acc_b - conf_b|`` over equal-width confidence bins."""
    bin_conf, bin_acc, count = reliability_curve(probs, labels, n_bins)
    nz = count > 0
    return float(np.sum(count[nz] * np.abs(bin_acc[nz] - bin_conf[nz])) / count.sum())


def confusion_matrix(labels: np.ndarray, preds: np.ndarray, n_classes: int) -> np.ndarray:
    """``(C, C)`` int counts; entry ``[i, j]`` = samples of true class ``i`` predicted ``j``."""
    labels = np.asarray(labels, dtype=np.int64)
    preds = np.asarray(preds, dtype=np.int64)
    if labels.shape != preds.shape or labels.ndim != 1:
        raise ValueError(f"need equal 1-D shapes, got {labels.shape}, {preds.shape}")
    for name, v in (("labels", labels), ("preds", preds)):
        if v.size and (v.min() < 0 or v.max() >= n_classes):
            raise ValueError(f"{name} must lie in 0..{n_classes - 1}")
    return np.bincount(labels * n_classes + preds, minlength=n_classes**2).reshape(
        n_classes, n_classes
    )


def per_class_precision_recall(
    labels: np.ndarray, preds: np.ndarray, n_classes: int
) -> tuple[np.ndarray, np.ndarray]:
    """Per-class precision and recall, each ``(C,)``; NaN where undefined (0 / 0)."""
    cm = confusion_matrix(labels, preds, n_classes).astype(float)
    tp = np.diag(cm)
    with np.errstate(invalid="ignore", divide="ignore"):
        return tp / cm.sum(axis=0), tp / cm.sum(axis=1)
