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

each set gets its mean and interval, the gap between the sets and the union
(:func:`~ipbench.eval.replication.replicate`). Values are fractions (accuracy points / 100).
:func:`seed_set_lines` renders them as a section of the sorting results page, with a
generated sentence naming the rows where the sets disagree.
"""

from __future__ import annotations

from collections.abc import Sequence

from ipbench.eval.markdown import seeds_text
from ipbench.eval.replication import Replication, agreement, replicate, replication_table
from ipbench.eval.report.runs import Run
from ipbench.eval.sorting.curve import CONFIDENCE_FAMILIES, per_seed_scores
from ipbench.policies import split_policy_name

__all__ = ["replications", "seed_set_groups", "seed_set_lines"]


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
