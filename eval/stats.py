"""Statistics over seeds shared by the reports: a percentile bootstrap interval of a mean, a
paired sign-flip permutation test (two policies on the same seeds), a two-sample test (one
quantity on two disjoint seed sets) and the seeds a target interval width needs.

Deterministic for a given ``seed``; :mod:`ipbench.eval.sorting.report` re-exports the first two.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

__all__ = [
    "PairedTest",
    "TwoSampleTest",
    "bootstrap_ci",
    "paired_test",
    "seeds_for_half_width",
    "two_sample_test",
]

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


@dataclass(frozen=True)
class TwoSampleTest:
    """One quantity measured on two disjoint seed sets (``b - a``).

    Attributes
    ----------
    n_a, n_b : values (seeds) in each set.
    mean_diff : ``mean(b) - mean(a)`` (units of the inputs).
    ci_low, ci_high : 95 % percentile bootstrap interval of ``mean_diff`` (each set resampled
        on its own).
    p_value : two-sided permutation p of ``mean_diff`` (the values reassigned to the sets).
    """

    n_a: int
    n_b: int
    mean_diff: float
    ci_low: float
    ci_high: float
    p_value: float


def two_sample_test(
    a: Iterable[float],
    b: Iterable[float],
    n_resamples: int = 10_000,
    seed: int = 0,
) -> TwoSampleTest:
    """Difference of the means of two independent samples: bootstrap interval and permutation p.

    Parameters
    ----------
    a, b : (n_a,), (n_b,) finite values, e.g. one score per seed of two disjoint seed sets;
        each needs two or more.
    n_resamples : bootstrap resamples and random permutations
        (:func:`scipy.stats.bootstrap`, :func:`scipy.stats.permutation_test`).
    seed : seeds both.

    Raises
    ------
    ValueError
        When a sample has fewer than two values or a non-finite one.
    """
    from scipy import stats

    x, y = (np.asarray(list(v), dtype=float) for v in (a, b))
    for name, v in (("a", x), ("b", y)):
        if v.ndim != 1 or v.size < 2 or not np.isfinite(v).all():
            raise ValueError(
                f"two_sample_test needs two or more finite values in {name}, got {v.tolist()}"
            )

    def diff(u, v, axis=-1):
        return np.mean(v, axis=axis) - np.mean(u, axis=axis)

    mean = float(diff(x, y))
    if np.ptp(np.concatenate([x, y])) == 0.0:
        return TwoSampleTest(x.size, y.size, mean, mean, mean, 1.0)
    boot = stats.bootstrap(
        (x, y), diff, n_resamples=n_resamples, method="percentile", rng=seed, vectorized=True
    )
    perm = stats.permutation_test((x, y), diff, n_resamples=n_resamples, rng=seed, vectorized=True)
    low, high = boot.confidence_interval
    return TwoSampleTest(x.size, y.size, mean, float(low), float(high), float(perm.pvalue))


def seeds_for_half_width(sd: float, half_width: float, level: float = 0.95) -> int:
    """Seeds a mean needs for its ``level`` interval to be ``±half_width`` wide.

    The normal approximation ``n = (z * sd / half_width) ** 2`` rounded up, with ``z`` the
    two-sided ``level`` quantile (1.96 at 95 %) and ``sd`` the per-seed standard deviation
    (units of ``half_width``). Raises ValueError on ``half_width <= 0``, a negative or
    non-finite ``sd`` or ``level`` outside ``(0, 1)``.
    """
    from scipy import stats

    if not (half_width > 0 and np.isfinite(sd) and sd >= 0 and 0.0 < level < 1.0):
        raise ValueError(
            f"need sd >= 0, half_width > 0 and 0 < level < 1, got {sd}, {half_width}, {level}"
        )
    z = float(stats.norm.ppf(0.5 + level / 2.0))
    return max(1, int(np.ceil((z * sd / half_width) ** 2 - 1e-9)))
