"""The exploration report: ``summary.json``, ``exploration.md`` and ``recall.png`` from episodes.

Input is one JSON record per exploration episode (``episodes.jsonl``, read with
:func:`~ipbench.eval.episodes.load_episodes`; written by :mod:`ipbench.eval.exploration`)::

    {"scene": "simple"|"medium"|"complex", "policy": str, "feature": "sift"|"kaze"|"akaze"|"orb",
     "seed": int, "n_database": int, "true_positives": int, "false_positives": int,
     "not_found": int, "performance": float, "recovered": int,
     "fp_reasons": {"wrong_class": int, "already_reported": int, "nothing_there": int},
     "saccades": int, "sim_time_s": float, "wall_time_s": float, "steps": int,
     "recall_curve": [float, ...], "saccades_to_all": int | null, "sim_s_to_all": float | null,
     "refixation_rate": float, "localisation_mm": [float, ...], "halted": bool,
     "truncated": bool, "video": str | null, "cycle_s": float}

``n_database``: database instances in the scene; ``performance`` = TP / (TP + FP + not found)
(:mod:`ipbench.envs.exploration_scoring`), a fraction; ``recovered``: true positives of
instances an earlier report took for another class; ``recall_curve[k]``: fraction of the
database instances found after ``k`` saccades (``k = 0..saccades``); ``saccades_to_all``: the
first ``k`` with recall 1; ``refixation_rate``: share of fixations within 4 deg of an earlier
one; ``localisation_mm``: 3-D error of each true positive's report (mm); ``cycle_s``: mean wall
seconds per step.

Output (:func:`write_exploration_report`), per scene, policy and feature type: the thesis'
Tables 3.2/3.3 counts summed over seeds, the per-seed performance's mean with a 95 %
percentile bootstrap interval, search efficiency (recall AUC, saccades and simulated seconds
to find everything, re-fixation, localisation error, cycle time) and paired sign-flip tests
of ``active-vision`` against each baseline over the seeds (:mod:`ipbench.eval.stats`).
Figures use matplotlib's object API on an Agg canvas (no pyplot global state).
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ipbench.eval.exploration_records import (
    FEATURES,
    FP_REASONS,
    POLICY_ORDER,
    SCENES,
    ExplorationReportError,
    Groups,
    check_budget,
    group_records,
    ordered,
)
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

_PROPOSED = "active-vision"
_PAIRED_KEY = "vs_active_vision"
_COUNTS = ("n_database", "true_positives", "false_positives", "not_found", "recovered")
_DPI = 110


# --------------------------------------------------------------------------- thesis numbers


@dataclass(frozen=True)
class ThesisFigure:
    """One performance figure of the thesis' ch. 3 (TP / (TP + FP + not found)).

    Attributes
    ----------
    table : the thesis table, e.g. ``"3.3"``.
    head : the camera head it was measured on.
    feature : our feature type name it compares with (None: none of ours).
    method : the thesis' name of the feature type, or of the whole system.
    percent : performance, % (pooled over the thesis' own scenes, not ours).
    """

    table: str
    head: str
    feature: str | None
    method: str
    percent: float


THESIS_FIGURES: tuple[ThesisFigure, ...] = (
    ThesisFigure("3.2", "Prosilica stereo head", None, "the active-vision system", 93.5),
    ThesisFigure("3.3", "Nikon D5100 / PTU-D46 head", "sift", "SIFT", 77.0),
    ThesisFigure("3.3", "Nikon D5100 / PTU-D46 head", "kaze", "KAZE", 83.0),
    ThesisFigure("3.3", "Nikon D5100 / PTU-D46 head", None, "SURF", 60.0),
)
"""The thesis' exploration performance (Glasgow 2018 PhD thesis, ch. 3, Tables 3.2 and 3.3;
as recorded in /work/shared/facts/sensor_and_calibration_facts.md §3). SURF is patented and in
no pip wheel of OpenCV, so we cannot run it; AKAZE and ORB take its place and have no thesis
figure."""
_THESIS_SOURCE = "Glasgow 2018 PhD thesis, ch. 3"


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
    }


def _per_seed(runs: Sequence[Mapping]) -> dict[int, float]:
    return {int(ep["seed"]): float(ep["performance"]) for ep in runs}


def _paired(groups: Groups, scene: str, policy: str, feature: str) -> dict | None:
    """``active-vision`` - ``policy`` on per-seed performance (same scene and feature)."""
    proposed = groups[scene].get(_PROPOSED, {}).get(feature)
    if policy == _PROPOSED or proposed is None:
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
                    cell[_PAIRED_KEY] = paired
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
        ``halted`` and ``truncated`` (episodes), and, for a baseline when ``active-vision``
        ran the same scene and feature, ``vs_active_vision``: the paired test of
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


# --------------------------------------------------------------------------- markdown


def _pct(fraction: float | None, digits: int = 1) -> str:
    return "–" if fraction is None else f"{100 * fraction:.{digits}f}"


def _num(value: float | None, fmt: str) -> str:
    return "–" if value is None else format(value, fmt)


def _p(p: float | None) -> str:
    if p is None:
        return "n/a"
    return "< 0.0001" if p < 1e-4 else f"{p:.4f}"


def _row(cells: Iterable[object]) -> str:
    return "| " + " | ".join(str(c) for c in cells) + " |"


def _head(cells: Sequence[str]) -> list[str]:
    return [_row(cells), "|---" * len(cells) + "|"]


_HOW_TO_READ = (
    "How to read: one table per feature type and scene, laid out like the thesis' Tables "
    "3.2/3.3, one row per gaze policy. `true positives` counts reports of a database object "
    "at the place of an instance of that class not reported before; `false positives` every "
    "other report (a wrong class, an instance already reported, or nothing there); `not "
    "found` the database instances never reported; `recovered` the true positives of "
    "instances an earlier report had taken for another class (a failure put right). The "
    "three counts are totals over all seeds, as the thesis counts them over its trials. "
    "`performance` is TP / (TP + FP + not found) of each episode: its mean over the seeds "
    "and, in brackets, the 95 % percentile bootstrap interval of that mean (10,000 resamples "
    "of the seeds)."
)
_FEATURE_NOTE = (
    "Feature types: the thesis compared SIFT, KAZE and SURF. SURF is patented (non-free) and "
    "is in no pip wheel of OpenCV, so it cannot run here; AKAZE and ORB, the free "
    "binary-descriptor detectors of the `opencv-python-headless` wheel, take its place and "
    "have no thesis figure to compare with."
)
_EFFICIENCY_HOW_TO_READ = (
    "How to read: `recall AUC` is the area under the recall-vs-saccades curve (fraction of "
    "the database instances found after k saccades, k = 0 to the budget of {budget}, held at "
    "its last value after an episode stops), divided by the budget and averaged over seeds: "
    "1 means everything was found at once, 0 nothing ever. `found all` counts the seeds that "
    "found every instance; `saccades to all` and `sim s to all` are the mean saccades and "
    "simulated seconds they needed. `re-fixation` is the mean share of fixations within 4 deg "
    "of an earlier one (wasted looks). `3-D error` is the median distance (mm) between a true "
    "positive's reported point and the instance's centre, over all true positives. `cycle` "
    "is the mean wall-clock seconds per step."
)
_PAIRED_HOW_TO_READ = (
    "How to read: per scene and feature type, `active-vision` minus each baseline on the "
    "per-episode performance, paired by seed (the same scene layout for both): the mean "
    "difference in percentage points, the 95 % percentile bootstrap interval of the per-seed "
    "differences and the two-sided p of a sign-flip permutation test (exact up to 16 pairs, "
    "else 100,000 random sign patterns). A positive difference favours `active-vision`."
)


def _thesis_lines(feature: str) -> list[str]:
    mine = [f for f in THESIS_FIGURES if f.feature == feature]
    if mine:
        parts = [f"Table {f.table}, {f.head}, {f.method}: {f.percent:g} %" for f in mine]
        return [f"*Thesis ({_THESIS_SOURCE}):* " + "; ".join(parts) + "."]
    surf = next(f for f in THESIS_FIGURES if f.method == "SURF")
    return [
        f"*Thesis:* no figure for {feature.upper()}; it stands in for SURF (Table {surf.table}: "
        f"{surf.percent:g} %), which is in no pip wheel of OpenCV."
    ]


def _thesis_table() -> list[str]:
    lines = _head(["table", "head", "method", "performance", "our feature"])
    for f in THESIS_FIGURES:
        lines.append(_row([f.table, f.head, f.method, f"{f.percent:g} %", f.feature or "–"]))
    return lines


def _counts_table(cells: Mapping[str, Mapping]) -> list[str]:
    head = ["policy", "true positives", "false positives", "not found", "recovered"]
    lines = _head([*head, "performance % (mean [95 % CI])", "seeds"])
    for policy, s in cells.items():
        perf = f"{_pct(s['performance_mean'])} [{_pct(s['ci_low'])}, {_pct(s['ci_high'])}]"
        counts = [s[k] for k in ("true_positives", "false_positives", "not_found", "recovered")]
        lines.append(_row([policy, *counts, perf, s["n"]]))
    return lines


def _efficiency_table(by_policy: Mapping[str, Mapping[str, Mapping]]) -> list[str]:
    head = ["policy", "feature", "recall AUC", "found all", "saccades to all", "sim s to all"]
    lines = _head([*head, "re-fixation", "3-D error (mm)", "cycle (s)"])
    for policy, by_feature in by_policy.items():
        for feature, s in by_feature.items():
            lines.append(
                _row(
                    [
                        policy,
                        feature,
                        f"{s['recall_auc']:.3f}",
                        f"{s['found_all']}/{s['n']}",
                        _num(s["saccades_to_all_mean"], ".1f"),
                        _num(s["sim_s_to_all_mean"], ".1f"),
                        f"{_pct(s['refixation_rate'])} %",
                        _num(s["localisation_mm_median"], ".1f"),
                        f"{s['cycle_s']:.2f}",
                    ]
                )
            )
    return lines


def _paired_table(summary: Mapping) -> list[str]:
    rows = []
    for scene, by_policy in summary.items():
        for feature in FEATURES:
            for policy, by_feature in by_policy.items():
                t = by_feature.get(feature, {}).get(_PAIRED_KEY)
                if t is None:
                    continue
                if t["n"] == 0:
                    rows.append(_row([scene, feature, policy, 0, "–", "–", "no common seed"]))
                    continue
                pts = "{:+.1f}".format
                rows.append(
                    _row(
                        [
                            scene,
                            feature,
                            policy,
                            t["n"],
                            pts(100 * t["mean_diff"]),
                            f"[{pts(100 * t['ci_low'])}, {pts(100 * t['ci_high'])}]",
                            f"{_p(t['p_value'])} ({t['method']})",
                        ]
                    )
                )
    if not rows:
        return [f"No baseline ran a scene and feature type that `{_PROPOSED}` ran: no test."]
    head = ["scene", "feature", f"{_PROPOSED} vs", "seeds", "mean difference (points)"]
    return [*_head([*head, "95 % CI", "p"]), *rows]


@dataclass(frozen=True)
class ExplorationReportPaths:
    """The files :func:`write_exploration_report` wrote."""

    markdown: Path
    summary: Path
    recall_plot: Path


def write_exploration_report(
    episodes: Sequence[Mapping],
    out: Path,
    budget: int,
    title: str = "Active exploration: database objects found",
) -> ExplorationReportPaths:
    """Write ``summary.json``, ``exploration.md`` and ``recall.png`` into ``out``.

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

    lines = [f"# {title}", "", _HOW_TO_READ, "", _FEATURE_NOTE, ""]
    lines += ["Thesis figures (pooled over the thesis' own scenes, not ours):", ""]
    lines += [*_thesis_table(), ""]
    features = ordered({f for s in summary.values() for p in s.values() for f in p}, FEATURES)
    for feature in features:
        lines += [f"## {feature.upper()}: objects found (Tables 3.2/3.3 layout)", ""]
        for scene, by_policy in summary.items():
            cells = {p: c[feature] for p, c in by_policy.items() if feature in c}
            if not cells:
                continue
            lines += [f"### {scene} scene, {feature.upper()}", "", *_counts_table(cells), ""]
            stopped = sum(c["truncated"] for c in cells.values())
            if stopped:
                lines += [f"{stopped} episode(s) stopped at the saccade budget (truncated).", ""]
        lines += [*_thesis_lines(feature), ""]
    lines += ["## Search efficiency", "", _EFFICIENCY_HOW_TO_READ.format(budget=budget), ""]
    for scene, by_policy in summary.items():
        lines += [f"### {scene} scene", "", *_efficiency_table(by_policy), ""]
    lines += ["![recall vs saccades](recall.png)", ""]
    lines += ["## Paired comparisons over seeds", "", _PAIRED_HOW_TO_READ, ""]
    lines += [*_paired_table(summary), ""]
    markdown = out / "exploration.md"
    markdown.write_text("\n".join(lines).rstrip("\n") + "\n")
    return ExplorationReportPaths(markdown, summary_path, recall_path)
