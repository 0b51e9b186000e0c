"""Statistics over seeds shared by the reports: a percentile bootstrap interval of a mean and
a paired sign-flip permutation test.

Moved here from :mod:`ipbench.eval.sorting_report` (which imports them back, so its public names
are unchanged) when the exploration report (:mod:`ipbench.eval.exploration_report`) came to
need them too. Pure numpy and deterministic for a given ``seed``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

__all__ = ["PairedTest", "bootstrap_ci", "paired_test"]

_EXACT_MAX_N = 16
"""Up to this many pairs the permutation test enumerates all ``2**n`` sign patterns."""


def bootstrap_ci(
    values: Iterable[float], n_boot: int = 10_000, level: float = 0.95, seed: int = 0
) -> tuple[float, float, float]:
    """Mean of ``values`` and its percentile bootstrap interval.

    Parameters
    ----------
    values : (n,) finite numbers, typically one per seed (e.g. accuracies in ``[0, 1]``).
    n_boot : number of resamples (with replacement, size ``n`` each).
    level : coverage of the interval, in ``(0, 1)``.
    seed : seeds the resampling; equal inputs give equal outputs.

    Returns
    -------
    mean, low, high : floats in the units of ``values``. A single value, or ``n`` equal
        values, give ``(v, v, v)``.

    Raises
    ------
    ValueError
        On empty or non-finite ``values``, ``n_boot < 1`` or ``level`` outside ``(0, 1)``.
    """
    x = np.asarray(list(values), dtype=float)
    if x.ndim != 1 or x.size == 0:
        raise ValueError(
            f"bootstrap_ci needs a non-empty 1-D sequence of values, got shape {x.shape}"
        )
    if not np.isfinite(x).all():
        raise ValueError(f"bootstrap_ci needs finite values, got {x.tolist()}")
    if n_boot < 1 or not 0.0 < level < 1.0:
        raise ValueError(f"need n_boot >= 1 and 0 < level < 1, got {n_boot}, {level}")
    if np.ptp(x) == 0.0:
        v = float(x[0])
        return v, v, v
    rng = np.random.default_rng(seed)
    rows = max(1, 2_000_000 // x.size)  # bounds the (rows, n) index block's memory
    means = np.concatenate(
        [
            x[rng.integers(0, x.size, size=(min(rows, n_boot - start), x.size))].mean(axis=1)
            for start in range(0, n_boot, rows)
        ]
    )
    alpha = (1.0 - level) / 2.0
    low, high = np.quantile(means, [alpha, 1.0 - alpha])
    return float(x.mean()), float(low), float(high)


@dataclass(frozen=True)
class PairedTest:
    """Paired comparison of two policies over the seeds both ran (``a - b``).

    Attributes
    ----------
    n : number of paired seeds (0 when the two share none).
    mean_diff : mean of the per-seed differences ``a[s] - b[s]`` (units of the inputs).
    ci_low, ci_high : 95 % percentile bootstrap interval of ``mean_diff``.
    p_value : two-sided sign-flip permutation p of ``mean_diff`` (NaN when ``n == 0``).
    method : how ``p_value`` was obtained: ``"exact"`` (all ``2**n`` sign patterns),
        ``"monte-carlo"`` (random sign patterns, ``(hits + 1) / (draws + 1)``) or
        ``"none"`` (no common seeds).
    """

    n: int
    mean_diff: float
    ci_low: float
    ci_high: float
    p_value: float
    method: str


def _sign_flip_p(diffs: np.ndarray, n_flips: int, seed: int) -> tuple[float, str]:
    """Two-sided p of ``|sum(diffs)|`` under random signs, and the method used."""
    n = diffs.size
    observed = abs(float(diffs.sum()))
    tol = 1e-9 * max(float(np.abs(diffs).sum()), 1e-300)  # summation-order rounding
    if n <= _EXACT_MAX_N:
        patterns = np.arange(2**n)[:, None] >> np.arange(n) & 1
        stats = np.abs((2.0 * patterns - 1.0) @ diffs)
        return float(np.mean(stats >= observed - tol)), "exact"
    rng = np.random.default_rng(seed)
    hits, chunk = 0, max(1, 1_000_000 // n)
    for start in range(0, n_flips, chunk):
        signs = 2.0 * rng.integers(0, 2, size=(min(chunk, n_flips - start), n)) - 1.0
        hits += int(np.count_nonzero(np.abs(signs @ diffs) >= observed - tol))
    return (hits + 1) / (n_flips + 1), "monte-carlo"


def paired_test(
    a: Mapping[int, float],
    b: Mapping[int, float],
    n_flips: int = 100_000,
    n_boot: int = 10_000,
    seed: int = 0,
) -> PairedTest:
    """Paired sign-flip permutation test of ``mean(a[s] - b[s])`` over common seeds ``s``.

    Parameters
    ----------
    a, b : per-seed values (e.g. accuracy in ``[0, 1]``) of two policies, keyed by seed;
        seeds present in only one of them are ignored.
    n_flips : random sign patterns when there are more than 16 pairs (up to 16 pairs the
        test is exact).
    n_boot : bootstrap resamples for the interval of the mean difference.
    seed : seeds the random sign patterns and the bootstrap.

    Returns
    -------
    PairedTest
        With ``n == 0`` (no common seed): NaN difference, interval and p, method ``"none"``.
    """
    seeds = sorted(set(a) & set(b))
    if not seeds:
        nan = float("nan")
        return PairedTest(0, nan, nan, nan, nan, "none")
    diffs = np.array([float(a[s]) - float(b[s]) for s in seeds])
    mean, low, high = bootstrap_ci(diffs, n_boot=n_boot, seed=seed)
    p, method = _sign_flip_p(diffs, n_flips, seed)
    return PairedTest(len(seeds), mean, low, high, p, method)
