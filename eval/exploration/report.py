"""The exploration report: ``summary.json``, ``exploration.md`` and ``recall.png`` from episodes.

Input is one JSON record per exploration episode (``episodes.jsonl``, read with
:func:`~ipbench.eval.episodes.load_episodes`; written by :mod:`ipbench.eval.exploration.evaluate`)::

    {"scene": "simple"|"medium"|"complex", "policy": str, "feature": "sift"|"kaze"|"akaze"|"orb",
     "seed": int, "n_database": int, "true_positives": int, "false_positives": int,
     "not_found": int, "performance": float, "recovered": int,
     "fp_reasons": {"wrong_class": int, "already_reported": int, "nothing_there": int},
     "saccades": int, "sim_time_s": float, "wall_time_s": float, "steps": int,
     "recall_curve": [float, ...], "saccades_to_all": int | null, "sim_s_to_all": float | null,
     "refixation_rate": float, "localisation_mm": [float, ...], "halted": bool,
     "truncated": bool, "video": str | null, "cycle_s": float,
     "sightings": [[float, bool, int], ...], "false_candidates": int, "looks": int,
     "missed": {cause: int, ...}}

``n_database``: database instances in the scene; ``performance`` = TP / (TP + FP + not found)
(:mod:`ipbench.envs.exploration_scoring`), a fraction; ``recovered``: true positives of
instances an earlier report took for another class; ``recall_curve[k]``: fraction of the
database instances found after ``k`` saccades (``k = 0..saccades``); ``saccades_to_all``: the
first ``k`` with recall 1; ``refixation_rate``: share of fixations within 4 deg of an earlier
one; ``localisation_mm``: 3-D error of each true positive's report (mm); ``cycle_s``: mean wall
seconds per step; ``sightings``, ``false_candidates``, ``looks``: recognition against
eccentricity (:mod:`ipbench.eval.exploration.sightings`; optional: records written before
they existed lack all three); ``missed``: the instances not found per cause
(:mod:`ipbench.eval.exploration.missed`; optional as well).

Output (:func:`write_exploration_report`), per scene, policy and feature type: the thesis'
Tables 3.2/3.3 counts summed over seeds, the per-seed performance's mean with a 95 %
percentile bootstrap interval, search efficiency (recall AUC, saccades and simulated seconds
to find everything, re-fixation, localisation error, cycle time) and paired sign-flip tests
of ``active-vision`` against each baseline over the seeds (:mod:`ipbench.eval.stats`), and
every comparison on disjoint seed sets (:mod:`ipbench.eval.exploration.seed_sets`).
Figures use matplotlib's object API on an Agg canvas (no pyplot global state).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ipbench.eval.exploration.markdown import THESIS_FIGURES, ThesisFigure, markdown_lines
from ipbench.eval.exploration.missed import MISSED_CAUSES
from ipbench.eval.exploration.records import (
    FEATURES,
    FP_REASONS,
    PAIRED_KEY,
    POLICY_ORDER,
    PROPOSED,
    SCENES,
    ExplorationReportError,
    Groups,
    check_budget,
    group_records,
    ordered,
)
from ipbench.eval.exploration.seed_sets import (
    seed_set_groups,
    seed_set_lines,
    seed_set_records,
)
from ipbench.eval.exploration.sightings import recognition_by_eccentricity
from ipbench.eval.stats import bootstrap_ci, paired_test

__all__ = [
    "FEATURES",
    "SCENES",
    "THESIS_FIGURES",
    "ExplorationReportError",
    "ExplorationReportPaths",
    "ThesisFigure",
    "recall_auc",
    "summarize_exploration",
    "write_exploration_report",
]

_COUNTS = ("n_database", "true_positives", "false_positives", "not_found", "recovered")
_DPI = 110


# --------------------------------------------------------------------------- summary


def _held_curve(curve: Sequence[float], budget: int) -> np.ndarray:
    """``curve[0..budget]``: cut after ``budget`` saccades, held at its last value up to it."""
    r = np.asarray(curve, float)[: budget + 1]
    return np.concatenate([r, np.full(budget + 1 - r.size, r[-1])])


def recall_auc(curve: Sequence[float], budget: int) -> float:
    """Area under recall vs saccades over ``0..budget`` saccades, normalised by ``budget``.

    The curve (``curve[k]``: recall after ``k`` saccades, fractions) is cut after ``budget``
    saccades or held at its last value up to ``budget``, then integrated with the trapezoid
    rule (unit spacing) and divided by ``budget``: 1.0 when everything was found before the
    first saccade, 0.0 when nothing was ever found; in ``[0, 1]``.

    Raises
    ------
    ExplorationReportError
        On ``budget < 1`` or an empty curve.
    """
    check_budget(budget)
    if len(curve) == 0:
        raise ExplorationReportError("recall_auc needs a non-empty recall curve")
    r = _held_curve(curve, budget)
    return float((r[:-1] + r[1:]).sum() / 2.0 / budget)


def _mean_or_none(values: Sequence[float]) -> float | None:
    return float(np.mean(values)) if len(values) else None


def _cell_summary(runs: Sequence[Mapping], budget: int) -> dict:
    mean, low, high = bootstrap_ci([float(ep["performance"]) for ep in runs])
    errors = [float(e) for ep in runs for e in ep["localisation_mm"]]
    found_all = [ep for ep in runs if ep["saccades_to_all"] is not None]
    return {
        "performance_mean": mean,
        "ci_low": low,
        "ci_high": high,
        "n": len(runs),
        "seeds": [int(ep["seed"]) for ep in runs],
        **{k: sum(int(ep[k]) for ep in runs) for k in _COUNTS},
        "fp_reasons": {r: sum(int(ep["fp_reasons"][r]) for ep in runs) for r in FP_REASONS},
        "recall_auc": float(np.mean([recall_auc(ep["recall_curve"], budget) for ep in runs])),
        "found_all": len(found_all),
        "saccades_to_all_mean": _mean_or_none([ep["saccades_to_all"] for ep in found_all]),
        "sim_s_to_all_mean": _mean_or_none(
            [ep["sim_s_to_all"] for ep in found_all if ep["sim_s_to_all"] is not None]
        ),
        "refixation_rate": float(np.mean([ep["refixation_rate"] for ep in runs])),
        "localisation_mm_median": float(np.median(errors)) if errors else None,
        "saccades_mean": float(np.mean([ep["saccades"] for ep in runs])),
        "sim_time_s_mean": float(np.mean([ep["sim_time_s"] for ep in runs])),
        "wall_time_s_mean": float(np.mean([ep["wall_time_s"] for ep in runs])),
        "cycle_s": float(np.mean([ep["cycle_s"] for ep in runs])),
        "halted": sum(bool(ep["halted"]) for ep in runs),
        "truncated": sum(bool(ep["truncated"]) for ep in runs),
        **_eccentricity(runs),
        **_missed(runs),
    }


def _missed(runs: Sequence[Mapping]) -> dict:
    """Where the instances not found were lost, over the episodes that carry it (none: {})."""
    carrying = [ep for ep in runs if "missed" in ep]
    if not carrying:
        return {}
    causes = {c: sum(int(ep["missed"][c]) for ep in carrying) for c in MISSED_CAUSES}
    return {"missed": {"episodes": len(carrying), "causes": causes}}


def _eccentricity(runs: Sequence[Mapping]) -> dict:
    """Recognition against eccentricity over the episodes that carry sightings (none: {})."""
    carrying = [ep for ep in runs if "sightings" in ep]
    if not carrying:
        return {}
    bins = recognition_by_eccentricity(s for ep in carrying for s in ep["sightings"])
    looks = sum(int(ep["looks"]) for ep in carrying)
    return {
        "eccentricity": {
            "episodes": len(carrying),
            "looks": looks,
            "bins": [
                {"low_deg": b.low_deg, "high_deg": b.high_deg, "n": b.n, "recognised": b.recognised}
                for b in bins
            ],
            "false_candidates_per_look": (
                sum(int(ep["false_candidates"]) for ep in carrying) / looks if looks else None
            ),
        }
    }


def _per_seed(runs: Sequence[Mapping]) -> dict[int, float]:
    return {int(ep["seed"]): float(ep["performance"]) for ep in runs}


def _paired(groups: Groups, scene: str, policy: str, feature: str) -> dict | None:
    """``active-vision`` - ``policy`` on per-seed performance (same scene and feature)."""
    proposed = groups[scene].get(PROPOSED, {}).get(feature)
    if policy == PROPOSED or proposed is None:
        return None
    t = paired_test(_per_seed(proposed), _per_seed(groups[scene][policy][feature]))
    finite = (lambda v: v if math.isfinite(v) else None) if t.n else (lambda v: None)
    return {
        "n": t.n,
        "mean_diff": finite(t.mean_diff),
        "ci_low": finite(t.ci_low),
        "ci_high": finite(t.ci_high),
        "p_value": finite(t.p_value),
        "method": t.method,
    }


def _summarize(groups: Groups, budget: int) -> dict:
    out: dict = {}
    for scene, by_policy in groups.items():
        out[scene] = {}
        for policy, by_feature in by_policy.items():
            out[scene][policy] = {}
            for feature, runs in by_feature.items():
                cell = _cell_summary(runs, budget)
                paired = _paired(groups, scene, policy, feature)
                if paired is not None:
                    cell[PAIRED_KEY] = paired
                out[scene][policy][feature] = cell
    return out


def summarize_exploration(episodes: Sequence[Mapping], budget: int) -> dict:
    """Per scene, policy and feature type: performance over seeds, totals, search efficiency.

    Parameters
    ----------
    episodes : records (module docstring), one per scene, policy, feature and seed.
    budget : the saccade budget the episodes ran with (normalises ``recall_auc``).

    Returns
    -------
    dict
        ``{scene: {policy: {feature: cell}}}`` in display order (scenes simple, medium,
        complex; policies active-vision, oracle-gaze, raster-scan, random-gaze, others
        alphabetically; features sift, kaze, akaze, orb). A cell has ``performance_mean,
        ci_low, ci_high`` (per-seed performance, fraction: mean and 95 % percentile bootstrap
        interval), ``n`` (seeds), ``seeds``, totals over seeds of ``n_database,
        true_positives, false_positives, not_found, recovered`` and ``fp_reasons``,
        ``recall_auc`` (mean over seeds of :func:`recall_auc`), ``found_all`` (seeds that
        found every instance), ``saccades_to_all_mean`` and ``sim_s_to_all_mean`` (over those
        seeds; None if none), ``refixation_rate`` (mean), ``localisation_mm_median`` (median
        over all true positives, mm; None without any), ``saccades_mean``,
        ``sim_time_s_mean``, ``wall_time_s_mean``, ``cycle_s`` (means per episode),
        ``halted`` and ``truncated`` (episodes); when episodes carry sightings,
        ``eccentricity``: ``episodes, looks``, ``bins`` (``low_deg, high_deg, n,
        recognised`` per bin of ``sightings.ECCENTRICITY_BINS_DEG``) and
        ``false_candidates_per_look``; when episodes carry ``missed``, ``missed``:
        ``episodes`` and ``causes`` (instances not found per cause of
        ``missed.MISSED_CAUSES``, summed over those episodes); and, for a baseline when
        ``active-vision`` ran the same scene and feature, ``vs_active_vision``: the paired test of
        ``active-vision`` minus this policy on per-seed performance (``n, mean_diff, ci_low,
        ci_high, p_value, method``, fractions; None for undefined values).

    Raises
    ------
    ExplorationReportError
        On no records, a bad record (naming it and the field), a duplicate (scene, policy,
        feature, seed) or ``budget < 1``.
    """
    if not episodes:
        raise ExplorationReportError("the exploration report needs at least one record, got none")
    check_budget(budget)
    return _summarize(group_records(episodes), budget)


# --------------------------------------------------------------------------- figure


def _recall_png(path: Path, groups: Groups, budget: int) -> None:
    """Mean recall over seeds vs saccades, a panel per scene, a line per (policy, feature)."""
    scenes = list(groups)
    policies = ordered({p for s in scenes for p in groups[s]}, POLICY_ORDER)
    colour = {p: f"C{i % 10}" for i, p in enumerate(policies)}
    style = dict(zip(FEATURES, ("-", "--", "-.", ":"), strict=True))
    fig = Figure(figsize=(3.6 * len(scenes) + 1.6, 3.4), dpi=_DPI)
    axes = np.atleast_1d(fig.subplots(1, len(scenes), sharey=True, squeeze=False)[0])
    k = np.arange(budget + 1)
    for ax, scene in zip(axes, scenes, strict=True):
        for policy, by_feature in groups[scene].items():
            for feature, runs in by_feature.items():
                mean = np.mean([_held_curve(ep["recall_curve"], budget) for ep in runs], axis=0)
                ax.plot(
                    k, 100 * mean, style[feature], color=colour[policy], lw=1.3,
                    label=f"{policy} / {feature}",
                )  # fmt: skip
        ax.set_xlim(0, budget)
        ax.set_ylim(0, 102)
        ax.set_xlabel("saccades")
        ax.set_title(f"{scene} scene", fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("database instances found (%)\nmean over seeds")
    handles, labels = axes[0].get_legend_handles_labels()
    for ax in axes[1:]:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, fontsize=6, loc="upper left", bbox_to_anchor=(0.80, 0.95))
    fig.tight_layout(rect=(0, 0, 0.80, 1))
    fig.savefig(path)


@dataclass(frozen=True)
class ExplorationReportPaths:
    """The files :func:`write_exploration_report` wrote."""

    markdown: Path
    summary: Path
    recall_plot: Path
    seed_sets: Path


def write_exploration_report(
    episodes: Sequence[Mapping],
    out: Path,
    budget: int,
    title: str = "Active exploration: database objects found",
) -> ExplorationReportPaths:
    """Write ``summary.json``, ``seed_sets.json``, ``exploration.md`` and ``recall.png`` into
    ``out``.

    Parameters
    ----------
    episodes : episode records in any order (module docstring; :func:`summarize_exploration`).
    out : report folder (created if needed).
    budget : the saccade budget the episodes ran with (x range of the recall curves).
    title : the markdown's first heading.

    Raises
    ------
    ExplorationReportError
        As :func:`summarize_exploration`.
    """
    if not episodes:
        raise ExplorationReportError("the exploration report needs at least one record, got none")
    check_budget(budget)
    groups = group_records(episodes)
    summary = _summarize(groups, budget)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    summary_path = out / "summary.json"
    summary_path.write_text(json.dumps(summary, indent=2, allow_nan=False) + "\n")
    recall_path = out / "recall.png"
    _recall_png(recall_path, groups, budget)

    found = seed_set_groups(groups)
    seed_sets_path = out / "seed_sets.json"
    seed_sets_path.write_text(json.dumps(seed_set_records(found), indent=2, allow_nan=False) + "\n")
    lines = markdown_lines(summary, budget, title) + seed_set_lines(found)
    markdown = out / "exploration.md"
    markdown.write_text("\n".join(lines).rstrip("\n") + "\n")
    return ExplorationReportPaths(markdown, summary_path, recall_path, seed_sets_path)
