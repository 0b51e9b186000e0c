"""One sorting measurement on disjoint seed sets: how far apart the sets land, and the seeds a
stable answer needs.

Chaotic contact makes one seed set one draw of the benchmark's scenes: a verdict that holds
on seeds 0–29 may not on seeds 30–59. Runs of ``ipbench eval sorting`` that differ only in
their seeds — the same ``run.json`` fingerprint (env, models, thresholds, code version: every
setting but seeds, scenes, policies and workers) and pairwise disjoint seeds — are *seed sets*
of one measurement. For each scene and each quantity every set has:

* ``<family> score``: a confidence family's gain over random inspection
  (:mod:`ipbench.eval.sorting.curve`), one value per seed, from the set's ``curve.json`` and
  per-seed accuracies (:func:`~ipbench.eval.sorting.curve.per_seed_scores`);
* ``<policy> − random``: a validated confidence policy's accuracy minus random sorting's on
  the same seed;
* ``random``: random sorting's accuracy, the floor the others are read against;

each set gets its mean and 95 % bootstrap interval; the sets' difference (the later minus the
first) its bootstrap interval and permutation p (:func:`~ipbench.eval.stats.two_sample_test`);
the union of the sets its mean, interval and per-seed standard deviation, and the seeds a
±1 and ±2 point interval needs (:func:`~ipbench.eval.stats.seeds_for_half_width`). Values are
fractions (accuracy points / 100). :func:`seed_set_lines` renders them as a section of the
sorting results page, with a generated sentence naming the rows where the sets disagree.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ipbench.eval.report.markdown import p_value, points, points_interval, seeds_text, table
from ipbench.eval.report.runs import Run
from ipbench.eval.sorting.curve import CONFIDENCE_FAMILIES, per_seed_scores
from ipbench.eval.stats import (
    TwoSampleTest,
    bootstrap_ci,
    paired_test,
    seeds_for_half_width,
    two_sample_test,
)
from ipbench.policies import split_policy_name

__all__ = [
    "HALF_WIDTHS",
    "Estimate",
    "Replication",
    "agreement",
    "replicate",
    "replication_table",
    "replications",
    "seed_set_groups",
    "seed_set_lines",
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


def _seeds(run: Run) -> set[int]:
    return {int(s) for s in ((run.json("run.json") or {}).get("config") or {}).get("seeds", [])}


def seed_set_groups(runs: Sequence[Run]) -> list[tuple[Run, ...]]:
    """Groups of two or more sorting runs with one fingerprint and pairwise disjoint seeds, in
    the order of ``runs``; a run whose seeds overlap an earlier run of its group is left out."""
    groups: dict[str, list[Run]] = {}
    for run in runs:
        info = run.json("run.json") or {}
        if run.kind != "sorting" or not info.get("fingerprint") or not _seeds(run):
            continue
        group = groups.setdefault(info["fingerprint"], [])
        if all(not (_seeds(run) & _seeds(other)) for other in group):
            group.append(run)
    return [tuple(g) for g in groups.values() if len(g) > 1]


def _quantities(run: Run) -> dict[tuple[str, str], dict[int, float]]:
    """``{(scene, quantity): {seed: value}}`` of one run (see the module docstring)."""
    accuracy = run.json("accuracy_per_seed.json") or {}
    out: dict[tuple[str, str], dict[int, float]] = {}
    scores = per_seed_scores(run.json("curve.json") or {}, accuracy)
    for scene, by_policy in accuracy.items():
        for family, values in scores.get(scene, {}).items():
            out[(scene, f"{family} score")] = values
        if "random" not in by_policy:
            continue
        base = {int(s): float(a) for s, a in by_policy["random"].items()}
        for policy, values in by_policy.items():
            family, value = split_policy_name(policy)
            if family in CONFIDENCE_FAMILIES and value is None:
                diffs = {int(s): float(a) - base[int(s)] for s, a in values.items()}
                out[(scene, f"{policy} − random")] = {s: d for s, d in diffs.items() if s in base}
        out[(scene, "random")] = base
    return out


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


def replications(group: Sequence[Run]) -> list[Replication]:
    """Every scene and quantity that each run of ``group`` (:func:`seed_set_groups`) measured
    on two or more seeds, in the first run's order."""
    per_run = [_quantities(run) for run in group]
    out = []
    for key in per_run[0]:
        values = [q.get(key) for q in per_run]
        if any(v is None for v in values):
            continue
        sets = [(run.name, v) for run, v in zip(group, values, strict=True)]
        row = replicate(key[0], key[1], sets, level=key[1] == "random")
        if row is not None:
            out.append(row)
    return out


_HOW_TO_READ = (
    "Runs with one fingerprint (the same environment, models, thresholds and code) on disjoint "
    "seeds are seed sets of one measurement. Per scene and quantity: each set's mean over its "
    "seeds with the 95 % bootstrap interval; `gap`: the last set minus the first, with the "
    "bootstrap interval of that difference (each set resampled on its own) and the "
    "permutation p; `all seeds`: the union, with the sign-flip p against 0 for a score or a "
    "difference; `seeds for ±2 / ±1`: the seeds a 95 % interval that narrow needs, from the "
    "union's per-seed standard deviation (normal approximation). A score is a confidence "
    "family's gain over random inspection; `<policy> − random` is paired per seed; `random` "
    "is random sorting's accuracy. Accuracy in percent, the others in percentage points."
)


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


def _group_lines(group: tuple[Run, ...]) -> list[str]:
    rows = replications(group)
    if not rows:
        return []
    names = ", ".join(
        f"`{r.name}` on seeds {seeds_text(s.seeds)[1]}"
        for r, s in zip(group, rows[0].sets, strict=True)
    )
    body = replication_table(rows, [f"`{r.name}`" for r in group])
    return [f"### Seed sets: {names}", "", *body, "", agreement(rows), ""]


def seed_set_lines(runs: Sequence[Run]) -> list[str]:
    """The section's markdown lines; none when no runs are seed sets of one measurement."""
    body = [line for group in seed_set_groups(runs) for line in _group_lines(group)]
    return ["## One measurement on disjoint seed sets", "", _HOW_TO_READ, "", *body] if body else []
