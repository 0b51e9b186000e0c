"""The sorting report: ``sorting.md``, ``summary.json`` and figures from episode records.

Input is one JSON record per sorting episode (``episodes.jsonl``, see :func:`load_episodes`;
the fields :mod:`ipbench.eval.sorting.summary` reads). Output, per scene, is a table laid out
like the thesis' Table 5.1 (rows = policies, columns = categories as ``correct/total`` summed
over seeds, then the total), with the spread over seeds as a percentile bootstrap interval of
the per-seed mean accuracy and a paired sign-flip permutation test of ``gp-ipm`` against
``random`` (episodes paired by seed: same scene, same objects), and a table of where the
objects not sorted right were lost (to labels or to handling).

Statistics are pure numpy and deterministic for a given ``seed``; figures are drawn with
matplotlib's object API on an Agg canvas (no pyplot, no display, no global backend change).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ipbench.assets.objects.catalog import CATEGORIES
from ipbench.eval.episodes import load_episodes  # re-exported: the sorting log's reader
from ipbench.eval.sorting.summary import (  # re-exported: the report's figures
    LOSSES,
    POLICY_ORDER,
    SCENE_ORDER,
    THESIS_TABLE_5_1,
    ThesisResult,
    group_episodes,
    loss_decomposition,
    ordered,
    summarize,
    summarize_groups,
)
from ipbench.eval.stats import PairedTest, bootstrap_ci, paired_test  # re-exported

__all__ = [
    "LOSSES",
    "THESIS_TABLE_5_1",
    "PairedTest",
    "ReportPaths",
    "ThesisResult",
    "ThresholdSweep",
    "bootstrap_ci",
    "load_episodes",
    "loss_decomposition",
    "paired_test",
    "summarize",
    "write_report",
]

_DPI = 110


# --------------------------------------------------------------------------- figures


@dataclass(frozen=True, eq=False)
class ThresholdSweep:
    """Sorting accuracy and inspection rate as the inspection threshold varies.

    Attributes
    ----------
    thresholds : (k,) confidence thresholds below which the policy inspects.
    accuracy : (k,) accuracy at each threshold, fraction in ``[0, 1]``.
    inspected_fraction : (k,) fraction of decisions that inspected, in ``[0, 1]``.
    chosen : the threshold the policy uses.
    source : a sentence saying what data the sweep comes from.
    fitted : (k,) the accuracy the threshold rule reads (e.g. under a calibration fit), or
        None.
    """

    thresholds: np.ndarray
    accuracy: np.ndarray
    inspected_fraction: np.ndarray
    chosen: float
    source: str
    fitted: np.ndarray | None = None

    def __post_init__(self) -> None:
        arrays = {
            name: np.asarray(getattr(self, name), float)
            for name in ("thresholds", "accuracy", "inspected_fraction")
        }
        shapes = {a.shape for a in arrays.values()}
        k = arrays["thresholds"].shape
        if len(shapes) != 1 or len(k) != 1 or k[0] == 0:
            raise ValueError(
                "ThresholdSweep needs thresholds, accuracy and inspected_fraction of one "
                f"shape (k,) with k >= 1, got {[a.shape for a in arrays.values()]}"
            )
        if not all(np.isfinite(a).all() for a in arrays.values()) or not math.isfinite(self.chosen):
            raise ValueError("ThresholdSweep values must be finite")
        for name, a in arrays.items():
            object.__setattr__(self, name, a)
        object.__setattr__(self, "chosen", float(self.chosen))
        if self.fitted is not None:
            fitted = np.asarray(self.fitted, float)
            if fitted.shape != k:
                raise ValueError(f"ThresholdSweep.fitted needs shape {k}, got {fitted.shape}")
            object.__setattr__(self, "fitted", fitted)


@dataclass(frozen=True)
class ReportPaths:
    """The files :func:`write_report` wrote: ``markdown``, ``summary`` and the PNGs."""

    markdown: Path
    summary: Path
    plots: tuple[Path, ...]


def _label(name: str) -> str:
    return name.replace("_", " ")


def _accuracy_png(path: Path, summary: Mapping[str, Mapping[str, Mapping]]) -> None:
    """Grouped bars: per scene, each policy's mean accuracy (%) with its 95 % interval."""
    scenes = list(summary)
    policies = ordered({p for s in scenes for p in summary[s]}, POLICY_ORDER)
    width = 0.8 / len(policies)
    fig = Figure(figsize=(3.4 + 0.45 * len(scenes) * len(policies), 3.6), dpi=_DPI)
    ax = fig.subplots()
    thesis_style = {"marker": "D", "ms": 5, "ls": "none", "mfc": "white", "mec": "black"}
    for j, policy in enumerate(policies):
        xs, means, errs = [], [], [[], []]
        for i, scene in enumerate(scenes):
            s = summary[scene].get(policy)
            if s is None:
                continue
            xs.append(i - 0.4 + (j + 0.5) * width)
            means.append(100 * s["accuracy_mean"])
            errs[0].append(100 * (s["accuracy_mean"] - s["ci_low"]))
            errs[1].append(100 * (s["ci_high"] - s["accuracy_mean"]))
        ax.bar(xs, means, width, yerr=errs, capsize=3, label=policy, color=f"C{j}")
        for i, scene in enumerate(scenes):
            ref = THESIS_TABLE_5_1.get(scene, {}).get(policy)
            if ref is not None:
                x = i - 0.4 + (j + 0.5) * width
                ax.plot([x], [ref.percent], **thesis_style)
    if any(p in THESIS_TABLE_5_1.get(s, {}) for s in scenes for p in policies):
        ax.plot([], [], label="thesis (Table 5.1)", **thesis_style)
    ax.set_xticks(range(len(scenes)), scenes)
    ax.set_ylabel("objects in the right bin (%)\nmean over seeds, 95 % CI")
    ax.set_ylim(0, 105)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.set_title("Sorting accuracy by policy", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)


def _inspect_decisions(episodes: Sequence[Mapping]) -> list[tuple[str, float, float, bool | None]]:
    """``(scene, first_confidence, confidence, right)`` of every inspection decision.

    ``right`` is whether the fused label equals the true category, ``None`` when unknown.
    Decisions without both confidences finite are skipped.
    """
    out = []
    for ep in episodes:
        for d in ep.get("decisions") or []:
            if d.get("kind") != "inspect":
                continue
            before, after = d.get("first_confidence"), d.get("confidence")
            if before is None or after is None or not math.isfinite(before + after):
                continue  # e.g. an inspection cut short before the fused label
            truth = d.get("true_category")
            right = None if truth is None else d.get("label") == truth
            out.append((str(ep["scene"]), float(before), float(after), right))
    return out


def _confidence_png(path: Path, points: Sequence[tuple[str, float, float, bool | None]]) -> None:
    """Per scene: confidence before (scene view) vs after inspection, coloured by outcome."""
    scenes = ordered({p[0] for p in points}, SCENE_ORDER)
    fig = Figure(figsize=(3.6 * len(scenes), 3.6), dpi=_DPI)
    axes = np.atleast_1d(fig.subplots(1, len(scenes), sharey=True))
    styles = (
        (True, "tab:green", "o", "label right"),
        (False, "tab:red", "x", "label wrong"),
        (None, "0.5", ".", "truth unknown"),
    )
    for ax, scene in zip(axes, scenes, strict=True):
        ax.plot([0, 1], [0, 1], "k:", lw=1, label="no change")
        for outcome, colour, marker, name in styles:
            sel = [(b, a) for s, b, a, r in points if s == scene and r is outcome]
            if sel:
                b, a = np.array(sel).T
                ax.scatter(b, a, s=12, c=colour, marker=marker, label=f"{name} ({len(sel)})")
        ax.set_xlim(0, 1.02)
        ax.set_ylim(0, 1.02)
        ax.set_xlabel("confidence in the scene view")
        ax.set_title(f"{scene}: inspected objects", fontsize=9)
        ax.legend(fontsize=7, loc="lower right")
    axes[0].set_ylabel("confidence after inspection")
    fig.tight_layout()
    fig.savefig(path)


def _sweep_png(path: Path, sweep: ThresholdSweep) -> None:
    """Accuracy and inspected fraction (%) against the threshold, the chosen one marked."""
    order = np.argsort(sweep.thresholds)
    t = sweep.thresholds[order]
    fig = Figure(figsize=(4.6, 3.4), dpi=_DPI)
    ax = fig.subplots()
    ax.plot(t, 100 * sweep.accuracy[order], "o-", ms=3, label="accuracy")
    if sweep.fitted is not None:
        ax.plot(t, 100 * sweep.fitted[order], "-", lw=1, label="accuracy, fitted")
    ax.plot(t, 100 * sweep.inspected_fraction[order], "s--", ms=3, label="inspected")
    ax.axvline(sweep.chosen, color="k", lw=1, ls=":", label=f"chosen {sweep.chosen:.2f}")
    ax.set_xlabel("inspection threshold (confidence)")
    ax.set_ylabel("%")
    ax.set_ylim(0, 105)
    ax.legend(fontsize=8)
    ax.set_title("Inspection threshold sweep", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)


# --------------------------------------------------------------------------- markdown


def _pct(fraction: float, digits: int = 1) -> str:
    return f"{100 * fraction:.{digits}f}"


def _p(p: float) -> str:
    if math.isnan(p):
        return "n/a"
    return "< 0.0001" if p < 1e-4 else f"= {p:.4f}"


def _scene_table(summary: Mapping[str, Mapping]) -> list[str]:
    cats = ordered({c for s in summary.values() for c in s["per_category"]}, CATEGORIES)
    head = ["policy", *map(_label, cats), "Total", "mean", "95 % CI", "seeds"]
    head += ["inspections", "grasp failures", "dropped / wrong bin / left", "wall time"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for policy, s in summary.items():
        cells = [policy]
        for cat in cats:
            c = s["per_category"].get(cat)
            cells.append(f"{c['correct']}/{c['total']}" if c and c["total"] else "–")
        total = f"{s['correct']}/{s['objects']}"
        if s["objects"]:
            total += f" ({100 * s['correct'] / s['objects']:.0f} %)"
        cells += [
            total,
            f"{_pct(s['accuracy_mean'])} %",
            f"[{_pct(s['ci_low'])}, {_pct(s['ci_high'])}] %",
            str(s["n"]),
            f"{s['inspections_mean']:.1f}",
            f"{s['grasp_failures_mean']:.1f}",
            f"{s.get('dropped', 0)} / {s.get('wrong_bin', 0)} / {s.get('left', 0)}",
            f"{s['wall_time_s_mean']:.1f} s",
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


_LOSSES_HOW_TO_READ = (
    "Where the objects not sorted into their own bin were lost, per policy: mean objects per "
    "episode, and in brackets % of all the cell's objects; `label`: the grasp took the object "
    "it aimed at and its label sent it to a wrong bin (perception), `wrong object`: another "
    "object than the aimed one (a neighbour, part of a merged segment) ended in a wrong bin, "
    "`misplaced`: the aimed object fell into another bin than it was sent to, "
    "`dropped`: off the table, `left`: still on the table, in the inspection area or in hand "
    "at the end (the last four are handling); the five add up to the objects not sorted "
    "right."
)


def _losses_lines(summary: Mapping[str, Mapping]) -> list[str]:
    """The "where the objects were lost" table of one scene and its explanation; cells whose
    records predate the decomposition are named instead of shown."""
    shown = {p: s for p, s in summary.items() if s.get("losses_mean") is not None}
    missing = [p for p in summary if p not in shown]
    lines = ["### Where the objects were lost", ""]
    if shown:
        head = ["policy", *map(_label, LOSSES)]
        lines += ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
        for policy, s in shown.items():
            cells = [policy]
            for k in LOSSES:
                mean = s["losses_mean"][k]
                share = mean * s["n"] / s["objects"] if s["objects"] else 0.0
                cells.append(f"{mean:.1f} ({_pct(share)} %)")
            lines.append("| " + " | ".join(cells) + " |")
        lines += ["", _LOSSES_HOW_TO_READ, ""]
    if missing:
        names = ", ".join(
            f"`{p}` ({summary[p].get('losses_missing', summary[p]['n'])} of {summary[p]['n']} "
            "episodes without one)"
            for p in missing
        )
        lines += [
            f"No loss decomposition for {names}: those records predate it; run them again "
            "into a new --out to get it.",
            "",
        ]
    return lines


def _thesis_line(scene: str) -> str:
    refs = THESIS_TABLE_5_1.get(scene)
    if not refs:
        return f"*Thesis:* no Table 5.1 figure for the {scene} scene."
    parts = [
        f"{r.label} (`{p}`) {r.correct}/{r.total} ({r.percent:.0f} %)" for p, r in refs.items()
    ]
    return f"*Thesis, Table 5.1, {scene} (totals only):* " + "; ".join(parts) + "."


def _overlap(a: Mapping, b: Mapping) -> bool:
    return max(a["ci_low"], b["ci_low"]) <= min(a["ci_high"], b["ci_high"])


def _paired_line(
    scene: str,
    runs: Mapping[str, Sequence[Mapping]],
    summary: Mapping,
    policy: str = "gp-ipm",
    baseline: str = "random",
) -> str:
    per_seed = {
        p: {int(ep["seed"]): float(ep["accuracy"]) for ep in runs[p]} for p in (policy, baseline)
    }
    t = paired_test(per_seed[policy], per_seed[baseline])
    head = f"**Paired test, {scene}, `{policy}` − `{baseline}`:** "
    if t.n == 0:
        return head + "no seed in common, no test."
    method = "exact" if t.method == "exact" else "100,000 random sign flips"
    overlap = "overlap" if _overlap(summary[policy], summary[baseline]) else "do not overlap"
    return (
        head + f"mean difference {100 * t.mean_diff:+.1f} points "
        f"(95 % CI [{100 * t.ci_low:+.1f}, {100 * t.ci_high:+.1f}]), "
        f"p {_p(t.p_value)} (two-sided sign-flip permutation test, {method}; "
        f"n = {t.n} paired seeds); the two policies' 95 % intervals {overlap}."
    )


def _paired_lines(scene: str, runs: Mapping[str, Sequence[Mapping]], summary: Mapping) -> list[str]:
    """The paired test of every policy against random sorting (GP-IPM's first), and of
    GP-IPM against SVM-IPM (does the GP's confidence matter?), where both ran."""
    if "random" not in summary:
        return []
    others = ordered((p for p in summary if p != "random"), ("gp-ipm",))
    pairs = [(p, "random") for p in others]
    for other in ("svm-ipm", "deep-ipm"):
        if "gp-ipm" in summary and other in summary:
            pairs.append(("gp-ipm", other))
    return [line for p, b in pairs for line in (_paired_line(scene, runs, summary, p, b), "")]


def _confidence_lines(points: Sequence[tuple[str, float, float, bool | None]]) -> list[str]:
    known = [p for p in points if p[3] is not None]
    raised = sum(after > before for _, before, after, _ in points)
    text = f"{len(points)} inspections (all policies); the confidence rose in {raised} of them" + (
        f"; the fused label was right in {sum(p[3] for p in known)} of the {len(known)} "
        "with known ground truth."
        if known
        else "."
    )
    return [text, "", "![confidence before and after inspection](confidence_inspection.png)"]


def _sweep_lines(sweep: ThresholdSweep) -> list[str]:
    i = int(np.argmin(np.abs(sweep.thresholds - sweep.chosen)))
    return [
        f"{sweep.source} Chosen threshold: {sweep.chosen:.2f}; at the nearest sweep point "
        f"({sweep.thresholds[i]:.2f}) accuracy {_pct(sweep.accuracy[i])} % with "
        f"{_pct(sweep.inspected_fraction[i])} % of the decisions inspected.",
        "",
        "![threshold sweep](threshold_sweep.png)",
    ]


_HOW_TO_READ = (
    "How to read: one table per scene, laid out like the thesis' Table 5.1. Each category "
    "column counts objects sorted into their own bin as `correct/total`, summed over all "
    "seeds; `Total` pools every object of every seed. `mean` is the mean over seeds of the "
    "per-episode accuracy and `95 % CI` its percentile bootstrap interval (10,000 resamples "
    "of the seeds), so `mean` can differ from the pooled `Total` when scenes hold different "
    "numbers of objects. `inspections` and `grasp failures` are means per episode, `wall "
    "time` the mean wall-clock seconds per episode. The paired test compares `gp-ipm` with "
    "`random` on the seeds both ran (the same scenes): the difference is in percentage "
    "points, its interval is a bootstrap of the per-seed differences."
)


def write_report(
    episodes: Sequence[Mapping],
    out: Path,
    threshold_sweep: ThresholdSweep | None = None,
    title: str = "Interactive sorting: objects in the right bin",
    sections: Sequence[str] = (),
) -> ReportPaths:
    """Write ``summary.json``, ``sorting.md`` and the PNGs into ``out`` (created if needed).

    Parameters
    ----------
    episodes : episode records in any order (see :func:`summarize`).
    out : report folder.
    threshold_sweep : if given, ``threshold_sweep.png`` and its paragraph are added.
    title : the markdown's first heading.
    sections : markdown lines added after the scenes' tables (e.g. the accuracy-inspection
        curve, :mod:`ipbench.eval.sorting.curve`).

    Returns
    -------
    ReportPaths
        ``plots`` holds ``accuracy_by_policy.png``, ``confidence_inspection.png`` (only when
        some decision inspected) and ``threshold_sweep.png`` (only with a sweep).

    Raises
    ------
    ValueError
        On no episodes, or on records :func:`summarize` rejects.
    """
    if not episodes:
        raise ValueError("write_report needs at least one episode record, got none")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    runs = group_episodes(episodes)
    summary = summarize_groups(runs)
    summary_path = out / "summary.json"
    summary_path.write_text(json.dumps(summary, indent=2, allow_nan=False) + "\n")

    plots = [out / "accuracy_by_policy.png"]
    _accuracy_png(plots[0], summary)
    lines = [f"# {title}", "", _HOW_TO_READ, ""]
    for scene, by_policy in summary.items():
        lines += [f"## {scene}", "", *_scene_table(by_policy), "", _thesis_line(scene), ""]
        truncated = sum(s["truncated"] for s in by_policy.values())
        if truncated:
            lines += [f"{truncated} episode(s) stopped at the step limit (truncated).", ""]
        lines += _paired_lines(scene, runs[scene], by_policy)
        lines += _losses_lines(by_policy)
    lines += [*sections]
    lines += ["## Plots", "", "![accuracy by policy](accuracy_by_policy.png)", ""]
    points = _inspect_decisions(episodes)
    if points:
        plots.append(out / "confidence_inspection.png")
        _confidence_png(plots[-1], points)
        lines += ["### Confidence before and after inspection", "", *_confidence_lines(points)]
        lines.append("")
    if threshold_sweep is not None:
        plots.append(out / "threshold_sweep.png")
        _sweep_png(plots[-1], threshold_sweep)
        lines += ["### Inspection threshold", "", *_sweep_lines(threshold_sweep), ""]
    markdown = out / "sorting.md"
    markdown.write_text("\n".join(lines).rstrip("\n") + "\n")
    return ReportPaths(markdown, summary_path, tuple(plots))
