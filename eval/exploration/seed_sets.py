"""Every exploration comparison on disjoint seed sets, and how far apart the sets land.

Where a gaze policy looks changes what it finds, and which objects lie where changes with the
seed: a verdict measured on seeds 0–9 is one draw of the benchmark's scenes and need not hold
on seeds 10–19. So the exploration report measures every comparison on two or more disjoint
seed sets of one run. Per scene and feature type, the seeds that every policy ran are split in
order into sets of :data:`SEED_SET_SIZE` (the last set takes the remainder; fewer than two
sets' worth of seeds: no split); on each set, each quantity gets its mean and 95 % bootstrap
interval, and the sets' gap its interval and permutation p
(:func:`~ipbench.eval.replication.replicate`, shared with the sorting report). The
quantities, in percent or percentage points of the per-episode performance TP / (TP + FP +
not found):

* ``<policy>``: each policy's performance (a level);
* ``active-vision − <baseline>``: the proposed policy against each baseline, paired by seed;
* ``oracle-gaze − random-gaze``: what looking at the objects is worth against looking
  anywhere, whatever the policy that decides where — the measure of whether gaze matters.

:func:`seed_set_lines` renders them as a section of ``exploration.md`` and
:func:`seed_set_records` as the rows of ``seed_sets.json``; :func:`seed_set_groups_from_records`
reads those rows back, so pages rendered from ``seed_sets.json`` alone (the documentation's
results pages) show the same section.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from ipbench.eval.exploration.records import FEATURES, POLICY_ORDER, PROPOSED, Groups, ordered
from ipbench.eval.markdown import seeds_text
from ipbench.eval.replication import (
    HALF_WIDTHS,
    Estimate,
    Replication,
    agreement,
    replicate,
    replication_table,
)
from ipbench.eval.stats import TwoSampleTest, seeds_for_half_width

__all__ = [
    "GAZE_BASELINE",
    "ORACLE",
    "SEED_SET_SIZE",
    "SeedSetGroup",
    "seed_set_groups",
    "seed_set_groups_from_records",
    "seed_set_lines",
    "seed_set_records",
    "split_seeds",
]

SEED_SET_SIZE = 10
"""Seeds per set: the smallest set on which the exploration comparisons are reported."""
ORACLE = "oracle-gaze"
GAZE_BASELINE = "random-gaze"


def split_seeds(seeds: Sequence[int], size: int = SEED_SET_SIZE) -> list[tuple[int, ...]]:
    """``seeds`` (sorted, duplicates dropped) in consecutive sets of ``size``, the last set
    taking the remainder; an empty list when there are fewer than ``2 * size`` seeds.

    Raises ValueError when ``size < 2`` (a set needs two seeds for an interval).
    """
    if size < 2:
        raise ValueError(f"seed sets need size >= 2 (an interval needs two seeds), got {size}")
    values = sorted({int(s) for s in seeds})
    n = len(values) // size
    if n < 2:
        return []
    sets = [tuple(values[i * size : (i + 1) * size]) for i in range(n)]
    sets[-1] += tuple(values[n * size :])
    return sets


@dataclass(frozen=True)
class SeedSetGroup:
    """One scene and feature type on disjoint seed sets.

    Attributes
    ----------
    scene, feature : e.g. ``"simple"``, ``"sift"``.
    sets : the seed sets, in order (:func:`split_seeds`).
    rows : one :class:`~ipbench.eval.replication.Replication` per quantity (module
        docstring), policies first.
    """

    scene: str
    feature: str
    sets: tuple[tuple[int, ...], ...]
    rows: tuple[Replication, ...]


def _performance(runs: Sequence[Mapping]) -> dict[int, float]:
    return {int(ep["seed"]): float(ep["performance"]) for ep in runs}


def _quantities(by_policy: Mapping[str, Mapping[int, float]]) -> list[tuple[str, dict, bool]]:
    """``(quantity, {seed: value}, level)`` for one scene and feature type (module docstring)."""
    out = [(policy, dict(values), True) for policy, values in by_policy.items()]
    pairs = [(PROPOSED, p) for p in by_policy if p != PROPOSED] + [(ORACLE, GAZE_BASELINE)]
    for a, b in pairs:
        if a in by_policy and b in by_policy:
            diff = {s: by_policy[a][s] - by_policy[b][s] for s in by_policy[a]}
            out.append((f"{a} − {b}", diff, False))
    return out


def seed_set_groups(groups: Groups, size: int = SEED_SET_SIZE) -> list[SeedSetGroup]:
    """Per scene and feature type whose policies share ``2 * size`` seeds or more: the seed
    sets (:func:`split_seeds` of the shared seeds) and every quantity on them."""
    out = []
    for scene, by_policy in groups.items():
        features = ordered({f for cells in by_policy.values() for f in cells}, FEATURES)
        for feature in features:
            policies = ordered([p for p in by_policy if feature in by_policy[p]], POLICY_ORDER)
            values = {p: _performance(by_policy[p][feature]) for p in policies}
            shared = set.intersection(*(set(v) for v in values.values()))
            sets = split_seeds(sorted(shared), size)
            if not sets:
                continue
            rows = []
            for quantity, per_seed, level in _quantities(
                {p: {s: v[s] for s in shared} for p, v in values.items()}
            ):
                named = [(seeds_text(s)[1], {k: per_seed[k] for k in s}) for s in sets]
                row = replicate(scene, quantity, named, level)
                if row is not None:
                    rows.append(row)
            out.append(SeedSetGroup(scene, feature, tuple(sets), tuple(rows)))
    return out


_HOW_TO_READ = (
    "How to read: per scene and feature type, the seeds every policy ran are split in order "
    "into sets of {size} (the last takes the remainder). Each quantity on each set: its mean "
    "over the set's seeds with the 95 % bootstrap interval; `gap`: the last set minus the "
    "first, with the bootstrap interval of that difference (each set resampled on its own) "
    "and the permutation p; `all seeds`: the union, with the sign-flip p against 0 for a "
    "difference; `seeds for ±2 / ±1`: the seeds a 95 % interval that narrow needs, from the "
    "union's per-seed standard deviation (normal approximation). A policy's row is its "
    "performance in percent; `a − b` is paired per seed, in percentage points. `{oracle} − "
    "{baseline}` is what looking at the objects is worth against looking anywhere: whether "
    "gaze matters at all in this setting."
)


def seed_set_lines(found: Sequence[SeedSetGroup], size: int = SEED_SET_SIZE) -> list[str]:
    """The section's markdown lines for :func:`seed_set_groups`' result; when there is none,
    one sentence saying how many seeds a split needs."""
    head = ["## Seed sets: does each comparison hold on disjoint seeds?", ""]
    if not found:
        return [
            *head,
            f"Not measured: a split needs {2 * size} or more seeds that every policy of a scene "
            f"ran (e.g. `--seeds 0:{2 * size}`).",
            "",
        ]
    how = _HOW_TO_READ.format(size=size, oracle=ORACLE, baseline=GAZE_BASELINE)
    lines = [*head, how, ""]
    for g in found:
        names = [f"seeds {seeds_text(s)[1]}" for s in g.sets]
        lines += [f"### {g.scene} scene, {g.feature.upper()}", ""]
        lines += [*replication_table(g.rows, names), "", agreement(g.rows), ""]
    return lines


def _finite(value: float | None) -> float | None:
    return None if value is None or not math.isfinite(value) else float(value)


def seed_set_records(found: Sequence[SeedSetGroup]) -> list[dict]:
    """The rows of ``seed_sets.json``: ``scene, feature, quantity, level`` (True for a
    policy's performance, False for a difference), ``sets`` (``seeds, mean, ci_low,
    ci_high``), ``gap`` (last set minus first: ``mean_diff, ci_low, ci_high, p_value``) and
    ``all`` (``seeds, mean, ci_low, ci_high, sd, p_value``); fractions, None for undefined."""
    out = []
    for g in found:
        for r in g.rows:
            out.append(
                {
                    "scene": g.scene,
                    "feature": g.feature,
                    "quantity": r.quantity,
                    "level": r.pooled_p is None,
                    "sets": [
                        {
                            "seeds": list(s.seeds),
                            "mean": _finite(s.mean),
                            "ci_low": _finite(s.ci_low),
                            "ci_high": _finite(s.ci_high),
                        }
                        for s in r.sets
                    ],
                    "gap": {
                        "mean_diff": _finite(r.gap.mean_diff),
                        "ci_low": _finite(r.gap.ci_low),
                        "ci_high": _finite(r.gap.ci_high),
                        "p_value": _finite(r.gap.p_value),
                    },
                    "all": {
                        "seeds": list(r.pooled.seeds),
                        "mean": _finite(r.pooled.mean),
                        "ci_low": _finite(r.pooled.ci_low),
                        "ci_high": _finite(r.pooled.ci_high),
                        "sd": _finite(r.pooled.sd),
                        "p_value": _finite(r.pooled_p),
                    },
                }
            )
    return out


def _number(value: float | None) -> float:
    return math.nan if value is None else float(value)


def seed_set_groups_from_records(records: Sequence[Mapping]) -> list[SeedSetGroup]:
    """The groups whose :func:`seed_set_records` are ``records`` (rows of ``seed_sets.json``),
    in their order. What the records do not keep (each set's per-seed standard deviation) is
    NaN; :func:`seed_set_lines` of the result equals that of the original groups."""
    found: dict[tuple[str, str], list[Replication]] = {}
    sets: dict[tuple[str, str], tuple[tuple[int, ...], ...]] = {}
    for r in records:
        key = (str(r["scene"]), str(r["feature"]))
        seed_sets = tuple(tuple(int(x) for x in s["seeds"]) for s in r["sets"])
        estimates = tuple(
            Estimate(
                seeds_text(seeds)[1],
                seeds,
                _number(s["mean"]),
                _number(s["ci_low"]),
                _number(s["ci_high"]),
                math.nan,
            )
            for seeds, s in zip(seed_sets, r["sets"], strict=True)
        )
        g, a = r["gap"], r["all"]
        gap = TwoSampleTest(
            len(seed_sets[0]),
            len(seed_sets[-1]),
            _number(g["mean_diff"]),
            _number(g["ci_low"]),
            _number(g["ci_high"]),
            _number(g["p_value"]),
        )
        pooled_seeds = tuple(int(x) for x in a["seeds"])
        sd = _number(a["sd"])
        pooled = Estimate(
            "all", pooled_seeds, _number(a["mean"]), _number(a["ci_low"]), _number(a["ci_high"]), sd
        )
        needed = {h: seeds_for_half_width(sd, h) for h in HALF_WIDTHS}
        p = None if r["level"] else _number(a["p_value"])
        found.setdefault(key, []).append(
            Replication(key[0], str(r["quantity"]), estimates, gap, pooled, p, needed)
        )
        sets.setdefault(key, seed_sets)
    return [SeedSetGroup(s, f, sets[s, f], tuple(rows)) for (s, f), rows in found.items()]
