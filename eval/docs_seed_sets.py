"""The seed-set section of the sorting results page: one measurement on disjoint seed sets.

For every group of sorting runs that are seed sets of one measurement
(:func:`ipbench.eval.seed_sets.seed_set_groups`): a table per group with, per scene and
quantity, each set's mean and interval, how far apart the sets land (the later minus the
first, with its interval and p), the union's mean and interval, and the seeds a ±2 and ±1
point interval needs; and a generated sentence naming the rows where the sets disagree.
"""

from __future__ import annotations

from collections.abc import Sequence

from ipbench.eval.docs_markdown import p_value, points, points_interval, seeds_text, table
from ipbench.eval.docs_runs import Run
from ipbench.eval.seed_sets import HALF_WIDTHS, Replication, replications, seed_set_groups

__all__ = ["agreement", "seed_set_lines"]

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


def _value(quantity: str, mean: float, low: float, high: float) -> str:
    if quantity == "random":
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
        f"{points_interval(r.gap.ci_low, r.gap.ci_high)}"
        for r in apart
    )
    return f"The seed sets land apart beyond their intervals in {len(apart)} row(s): {listed}."


def _group_lines(group: tuple[Run, ...]) -> list[str]:
    rows = replications(group)
    if not rows:
        return []
    names = ", ".join(
        f"`{r.name}` on seeds {seeds_text(s.seeds)[1]}"
        for r, s in zip(group, rows[0].sets, strict=True)
    )
    head = ["scene", "quantity", *(f"`{r.name}`" for r in group), "gap", "p", "all seeds"]
    head += ["p (all)", "seeds for " + " / ".join(f"±{100 * h:g}" for h in HALF_WIDTHS)]
    cells = []
    for r in rows:
        cells.append(
            [
                r.scene,
                f"`{r.quantity}`",
                *(_value(r.quantity, s.mean, s.ci_low, s.ci_high) for s in r.sets),
                f"{points(r.gap.mean_diff)} {points_interval(r.gap.ci_low, r.gap.ci_high)}",
                p_value(r.gap.p_value),
                _value(r.quantity, r.pooled.mean, r.pooled.ci_low, r.pooled.ci_high)
                + f" (n = {len(r.pooled.seeds)})",
                p_value(r.pooled_p),
                " / ".join(str(r.seeds_needed[h]) for h in HALF_WIDTHS),
            ]
        )
    return [f"### Seed sets: {names}", "", *table(head, cells), "", agreement(rows), ""]


def seed_set_lines(runs: Sequence[Run]) -> list[str]:
    """The section's markdown lines; none when no runs are seed sets of one measurement."""
    body = [line for group in seed_set_groups(runs) for line in _group_lines(group)]
    return ["## One measurement on disjoint seed sets", "", _HOW_TO_READ, "", *body] if body else []
