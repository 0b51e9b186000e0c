"""The threshold rule: a logistic calibration fit read on a 0.05 grid, the same for permuted or
duplicated evidence, and not steep (one flipped decision moves it by at most one grid step)."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.linear_model import LogisticRegression

from ipbench.policies import PolicyError
from ipbench.policies.threshold import (
    RULE,
    THRESHOLD_GRID,
    choose_threshold,
    fit_correctness,
)


def _evidence(n: int = 400, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Confidences of a 5-class classifier that is right about as often as it says, a little
    less: the shape of a GP's validation decisions."""
    rng = np.random.default_rng(seed)
    conf = 0.2 + 0.8 * rng.beta(4.0, 2.0, n)
    right = rng.random(n) < conf**1.4
    return conf, right


def test_fit_is_the_maximum_likelihood_logistic_calibration() -> None:
    conf, right = _evidence()
    a, b = fit_correctness(conf, right)
    x = np.log(conf / (1 - conf))[:, None]
    ref = LogisticRegression(C=1e6, tol=1e-10, max_iter=1000).fit(x, right)
    assert a == pytest.approx(ref.intercept_[0], abs=0.02)
    assert b == pytest.approx(ref.coef_[0, 0], abs=0.02)
    assert b > 0  # confidence is informative


def test_threshold_is_the_lowest_grid_point_whose_fitted_precision_reaches_the_target() -> None:
    conf, right = _evidence()
    choice = choose_threshold(conf, right, 0.9)
    assert choice.rule == RULE and choice.n == len(conf)
    np.testing.assert_array_equal(choice.thresholds, THRESHOLD_GRID)
    i = int(np.flatnonzero(choice.thresholds == choice.threshold)[0])
    assert choice.fitted_precision[i] >= 0.9 > np.nan_to_num(choice.fitted_precision[i - 1])
    # the fitted precision is the mean fitted P(right | c) over the labels kept
    a, b = choice.fit
    p = 1 / (1 + np.exp(-(a + b * np.log(conf / (1 - conf)))))
    kept = conf >= choice.threshold
    assert choice.fitted_precision[i] == pytest.approx(p[kept].mean())
    assert choice.precision[i] == pytest.approx(right[kept].mean())
    assert choice.inspected[i] == pytest.approx(np.mean(~kept))


def test_permuted_or_duplicated_evidence_gives_the_same_choice() -> None:
    conf, right = _evidence()
    choice = choose_threshold(conf, right)
    order = np.random.default_rng(1).permutation(len(conf))
    for c, r in ((conf[order], right[order]), (np.tile(conf, 3), np.tile(right, 3))):
        other = choose_threshold(c, r)
        assert other.threshold == choice.threshold and other.fit == choice.fit
        np.testing.assert_array_equal(other.fitted_precision, choice.fitted_precision)


@pytest.mark.parametrize("target", [0.85, 0.9, 0.95])
def test_one_flipped_decision_moves_the_threshold_by_at_most_one_grid_step(target) -> None:
    conf, right = _evidence(300, seed=2)
    chosen = choose_threshold(conf, right, target).threshold
    moves = set()
    for i in range(len(conf)):
        flipped = right.copy()
        flipped[i] = not flipped[i]
        moves.add(round(abs(choose_threshold(conf, flipped, target).threshold - chosen), 2))
    assert moves <= {0.0, 0.05}


def test_extremes_and_bad_input() -> None:
    conf = np.linspace(0.3, 0.99, 50)
    assert choose_threshold(conf, np.ones(50, bool)).threshold == 0.0  # never wrong: no look
    assert choose_threshold(conf, np.zeros(50, bool)).threshold == 1.0  # never right: all
    with pytest.raises(PolicyError, match="equal non-empty"):
        choose_threshold(conf, np.ones(3, bool))
    with pytest.raises(PolicyError, match=r"in \[0, 1\]"):
        choose_threshold(conf + 0.5, np.ones(50, bool))
    with pytest.raises(PolicyError, match="target_precision"):
        choose_threshold(conf, np.ones(50, bool), 1.5)
