"""Fusing the class probabilities of several views of one object.

* :func:`majority_vote` — the thesis' rule: the label most views predict; a tie goes to the
  tied label with the highest single-view probability.
* :func:`bayes_fusion` — the documented alternative: treat the views as independent
  observations of the class, ``p(c | v_1..v_n) ∝ p(c)^(1-n) prod_i p(c | v_i)`` with a
  uniform prior ``p(c)``, i.e. the normalised product of the predictive distributions
  (computed in log space).
"""

from __future__ import annotations

import numpy as np

__all__ = ["FUSIONS", "FusionError", "bayes_fusion", "fuse", "majority_vote"]

FUSIONS: tuple[str, ...] = ("majority", "bayes")


class FusionError(ValueError):
    """Bad input to a fusion rule (no views, ragged shapes, unknown rule)."""


def _views(probs) -> np.ndarray:
    p = np.asarray(probs, dtype=float)
    if p.ndim != 2 or p.shape[0] == 0 or p.shape[1] < 2:
        raise FusionError(f"need (n_views >= 1, n_classes >= 2) probabilities, got {p.shape}")
    return p


def majority_vote(probs) -> tuple[int, float]:
    """``(label, confidence)`` of views ``probs`` (n, C): the most voted label, ties broken by
    the highest single-view probability; confidence = the mean probability of that label."""
    p = _views(probs)
    votes = np.bincount(p.argmax(axis=1), minlength=p.shape[1])
    tied = np.flatnonzero(votes == votes.max())
    label = int(tied[np.argmax(p[:, tied].max(axis=0))])
    return label, float(p[:, label].mean())


def bayes_fusion(probs, eps: float = 1e-12) -> np.ndarray:
    """(C,) posterior of independent views ``probs`` (n, C) under a uniform class prior."""
    log_p = np.log(np.clip(_views(probs), eps, 1.0)).sum(axis=0)
    log_p -= log_p.max()
    out = np.exp(log_p)
    return out / out.sum()


def fuse(probs, rule: str = "majority") -> tuple[int, float]:
    """``(label, confidence)`` by ``rule`` (one of :data:`FUSIONS`)."""
    if rule == "majority":
        return majority_vote(probs)
    if rule == "bayes":
        post = bayes_fusion(probs)
        return int(post.argmax()), float(post.max())
    raise FusionError(f"unknown fusion rule {rule!r}; valid: {', '.join(FUSIONS)}")
