"""One quantity measured on two or more disjoint seed sets: each set's estimate, how far apart
the sets land, and the seeds a stable answer needs.

Chaotic contact and the scenes' layouts make one seed set one draw of the benchmark: a
verdict that holds on seeds 0–29 may not on seeds 30–59. :func:`replicate` takes a quantity's
per-seed values on each set (fractions: accuracies, performances, or differences of them)
and gives each set its mean and 95 % bootstrap interval, the gap between the last set and the
first (:func:`~ipbench.eval.stats.two_sample_test`: bootstrap interval and permutation p),
the union's mean, interval and per-seed standard deviation, and the seeds a ±2 and ±1 point
interval needs (:func:`~ipbench.eval.stats.seeds_for_half_width`).
:func:`replication_table` and :func:`agreement` render rows of them as markdown. Used by the
sorting report (runs as seed sets) and the exploration report (a run's seeds split in sets).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ipbench.eval.markdown import p_value, points, points_interval, table
from ipbench.eval.stats import (
    TwoSampleTest,
    bootstrap_ci,
    paired_test,
    seeds_for_half_width,
    two_sample_test,
)

__all__ = [
    "HALF_WIDTHS",
    "Estimate",
    "Replication",
    "agreement",
    "replicate",
    "replication_table",
]

HALF_WIDTHS: tuple[float, ...] = (0.02, 0.01)
"""Interval half-widths (fractions: ±2 and ±1 accuracy points) whose seed counts are reported."""


@dataclass(frozen=True)
class Estimate:
    """A quantity's per-seed values on a set of seeds.

    Attributes
    ----------
    name : the run (its path under the results folder), or ``"all"`` for the union.
    seeds : (n,) the seeds, sorted.
    mean, ci_low, ci_high : mean over seeds and its 95 % percentile bootstrap interval.
    sd : per-seed standard deviation (``ddof=1``; 0 for one seed).
    """

    name: str
    seeds: tuple[int, ...]
    mean: float
    ci_low: float
    ci_high: float
    sd: float


@dataclass(frozen=True)
class Replication:
    """One scene's quantity on two or more disjoint seed sets.

    Attributes
    ----------
    scene, quantity : e.g. ``"cluttered"``, ``"gp-ipm score"``.
    sets : one :class:`Estimate` per seed set, in the order given.
    gap : the last set minus the first (:class:`~ipbench.eval.stats.TwoSampleTest`).
    pooled : the union of the sets.
    pooled_p : two-sided sign-flip p of ``pooled.mean`` against 0 (a score or a difference;
        None for an accuracy, ``random``).
    seeds_needed : ``{half_width: seeds}`` for :data:`HALF_WIDTHS`, from ``pooled.sd``.
    """

    scene: str
    quantity: str
    sets: tuple[Estimate, ...]
    gap: TwoSampleTest
    pooled: Estimate
    pooled_p: float | None
    seeds_needed: Mapping[float, int]


def _estimate(name: str, values: Mapping[int, float]) -> Estimate:
    seeds = tuple(sorted(values))
    x = np.array([values[s] for s in seeds])
    mean, low, high = bootstrap_ci(x)
    sd = float(np.std(x, ddof=1)) if x.size > 1 else 0.0
    return Estimate(name, seeds, mean, low, high, sd)


def replicate(
    scene: str, quantity: str, sets: Sequence[tuple[str, Mapping[int, float]]], level: bool
) -> Replication | None:
    """One quantity on disjoint seed sets: each set's estimate, the gap, the union; None when
    a set has fewer than two seeds (no interval, no gap).

    Parameters
    ----------
    scene, quantity : the row's names.
    sets : ``(name, {seed: value})`` per set, in order (values are fractions).
    level : True for a level (an accuracy, a performance): no p against 0; False for a
        difference or a score, tested against 0 over the union (sign flip).
    """
    if len(sets) < 2 or any(len(v) < 2 for _, v in sets):
        return None
    estimates = tuple(_estimate(name, v) for name, v in sets)
    union = {s: x for _, v in sets for s, x in v.items()}
    pooled = _estimate("all", union)
    gap = two_sample_test(list(sets[0][1].values()), list(sets[-1][1].values()))
    needed = {h: seeds_for_half_width(pooled.sd, h) for h in HALF_WIDTHS}
    p = None if level else paired_test(union, dict.fromkeys(union, 0.0)).p_value
    return Replication(scene, quantity, estimates, gap, pooled, p, needed)


def _value(level: bool, mean: float, low: float, high: float) -> str:
    if level:
        return f"{100 * mean:.1f} [{100 * low:.1f}, {100 * high:.1f}]"
    return f"{points(mean)} {points_interval(low, high)}"


def agreement(rows: Sequence[Replication]) -> str:
    """One sentence: whether every gap's interval holds 0 (the sets agree), else which rows'
    gaps exclude it."""
    apart = [r for r in rows if not r.gap.ci_low <= 0.0 <= r.gap.ci_high]
    if not apart:
        return (
            "The seed sets agree: every gap's 95 % interval holds 0 "
            f"(largest gap {max(abs(100 * r.gap.mean_diff) for r in rows):.1f} points)."
        )
    listed = "; ".join(
        f"{r.scene} {r.quantity}: {points(r.gap.mean_diff)} "
        f"{points_interval(r.gap.ci_low, r.gap.ci_high)}, p {p_value(r.gap.p_value)}"
        for r in apart
    )
    return f"The seed sets land apart beyond their intervals in {len(apart)} row(s): {listed}."


def replication_table(rows: Sequence[Replication], set_names: Sequence[str]) -> list[str]:
    """The markdown table of ``rows`` (one :func:`replicate` each, sets named ``set_names``):
    each set, the gap and its p, the union with its p, the seeds ±2 and ±1 points need.
    Levels in percent, differences and scores in percentage points."""
    head = ["scene", "quantity", *set_names, "gap", "p", "all seeds"]
    head += ["p (all)", "seeds for " + " / ".join(f"±{100 * h:g}" for h in HALF_WIDTHS)]
    cells = []
    for r in rows:
        level = r.pooled_p is None
        cells.append(
            [
                r.scene,
                f"`{r.quantity}`",
                *(_value(level, s.mean, s.ci_low, s.ci_high) for s in r.sets),
                f"{points(r.gap.mean_diff)} {points_interval(r.gap.ci_low, r.gap.ci_high)}",
                p_value(r.gap.p_value),
                _value(level, r.pooled.mean, r.pooled.ci_low, r.pooled.ci_high)
                + f" (n = {len(r.pooled.seeds)})",
                p_value(r.pooled_p),
                " / ".join(str(r.seeds_needed[h]) for h in HALF_WIDTHS),
            ]
        )
    return table(head, cells)
