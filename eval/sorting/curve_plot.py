"""The accuracy–inspection curve as a figure and as markdown (:mod:`ipbench.eval.sorting.curve`).

Both read the JSON-safe dict of :func:`ipbench.eval.sorting.curve.curve` (absent values are
None). The figure is drawn with matplotlib's object API on an Agg canvas (no pyplot, no
display, no global backend change).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

__all__ = ["curve_lines", "curve_png"]

_DPI = 110
_MARKERS = {"random-inspect": "s", "oracle-inspect": "^", "random": "X"}
_FIXED_STYLE = {
    "random-inspect": {"color": "0.45", "ls": "--"},
    "oracle-inspect": {"color": "black", "ls": "none", "ms": 7},
    "random": {"color": "tab:red", "ls": "none", "ms": 7},
}


def _errorbar(ax, points, **style) -> None:
    """Points at (inspections per object, accuracy %) with their 95 % interval as bars."""
    x = [p["inspections_per_object"] for p in points]
    y = np.array([100 * p["accuracy_mean"] for p in points])
    err = [y - [100 * p["ci_low"] for p in points], [100 * p["ci_high"] for p in points] - y]
    ax.errorbar(x, y, yerr=err, capsize=3, ms=style.pop("ms", 4), lw=1.2, **style)


def _with_anchor(points: list[Mapping], gp: Mapping | None) -> list[Mapping]:
    """The random-inspection points with ``gp-ipm@0`` and ``gp-ipm@1.0`` (the same loop
    inspecting nothing and everything: random inspection at P = 0 and 1) in place of its own
    ends where it has none, sorted by inspections per object."""
    own = {p["threshold"] for p in points}
    ends = [
        p
        for p in (gp or {}).get("points", [])
        if not p["validated"] and p["threshold"] in (0.0, 1.0) and p["threshold"] not in own
    ]
    return sorted([*points, *ends], key=lambda p: p["inspections_per_object"])


def curve_png(path: Path, curve: Mapping[str, Mapping[str, Mapping]]) -> None:
    """One panel per scene: accuracy (%) against inspections per object, 95 % CI bars.

    Each confidence family is a solid line over its ``@T`` runs with its validated run as a
    star; random inspection a dashed grey line (ended by ``gp-ipm@0`` and ``gp-ipm@1.0``
    where it has no point of its own there); oracle-inspect and random sorting markers.
    """
    scenes = list(curve) or ["no episodes"]
    fig = Figure(figsize=(1.2 + 4.0 * len(scenes), 3.8), dpi=_DPI)
    axes = np.atleast_1d(fig.subplots(1, len(scenes), sharey=True))
    for ax, scene in zip(axes, scenes, strict=True):
        colour = 0
        for family, entry in curve.get(scene, {}).items():
            points = entry["points"]
            if family == "random-inspect":
                points = _with_anchor(points, curve[scene].get("gp-ipm"))
            if family in _FIXED_STYLE:
                style = dict(_FIXED_STYLE[family], marker=_MARKERS[family], label=family)
                _errorbar(ax, points, **style)
                continue
            c = f"C{colour}"
            colour += 1
            sweep = [p for p in points if not p["validated"]]
            if sweep:
                _errorbar(ax, sweep, color=c, marker="o", ls="-", label=family)
            for p in (p for p in points if p["validated"]):
                t = p["threshold"]
                name = f"{family} (validated{'' if t is None else f' T={t:g}'})"
                _errorbar(ax, [p], color=c, marker="*", ls="none", ms=10, label=name)
        ax.set_xlabel("inspections per object (pooled over seeds)")
        ax.set_title(scene, fontsize=9)
        ax.set_ylim(0, 105)
        ax.set_xlim(left=-0.03)
        ax.grid(alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, loc="lower right")
    axes[0].set_ylabel("objects in the right bin (%)\nmean over seeds, 95 % CI")
    fig.tight_layout()
    fig.savefig(path)


def _pct(fraction: float | None, sign: str = "") -> str:
    return "–" if fraction is None else f"{100 * fraction:{sign}.1f}"


def _p(p: float | None) -> str:
    if p is None:
        return "n/a"
    return "< 0.0001" if p < 1e-4 else f"= {p:.4f}"


def _score_line(family: str, s: Mapping) -> str:
    head = f"**`{family}`, mean gain over random inspection:** "
    if s["mean"] is None:
        return head + f"not computed ({s['note']})."
    lo, hi = s["x_range"]
    text = (
        f"{_pct(s['mean'], '+')} points (95 % CI [{_pct(s['ci_low'], '+')}, "
        f"{_pct(s['ci_high'], '+')}]), p {_p(s['p_vs_random_inspect'])} (two-sided sign-flip "
        f"test against 0, n = {s['n']} paired seeds), over {lo:.3f}–{hi:.3f} inspections per "
        "object"
    )
    if s["normalized"] is not None:
        text += f"; {100 * s['normalized']:.0f} % of oracle-inspect's gain"
    return head + text + "."


def _decomposition_lines(parts: Mapping[str, Mapping]) -> list[str]:
    head = ["policy", "fixed", "broken", "truth unknown", "lost to handling", "vs", "seeds"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for policy, r in parts.items():
        lost = "–" if r["lost"] is None else f"{r['lost']:+.2f}"
        cells = [policy, f"{r['fixed']:.2f}", f"{r['broken']:.2f}", f"{r['unknown']:.2f}", lost]
        cells += [r["lost_baseline"] or "–", str(r["lost_n"]) if r["lost_baseline"] else "–"]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


_HOW_TO_READ = (
    "x: inspections per object, pooled over seeds (total inspections / total objects); "
    "accuracy: mean over seeds of the per-episode share of objects in their own bin, with "
    "its 95 % bootstrap interval. `threshold` is T of `<family>@T` (the validated T for the "
    "plain name) or P of `random-inspect@P`. The gain over random inspection is the area "
    "between the family's curve (its `@T` runs, linear between points) and the "
    "random-inspection line, divided by the x range both cover: the mean accuracy gain at "
    "equal inspection effort, in percentage points, one value per paired seed."
)
_DECOMPOSITION_HOW_TO_READ = (
    "Per episode, mean over seeds: `fixed` inspections whose first label was wrong and final "
    "label right, `broken` the reverse, `truth unknown` inspections without a known "
    "category; `lost to handling` objects dropped or left at the end minus those of the "
    "no-inspection run `vs` on the same seeds (negative: fewer)."
)


def curve_lines(
    curve: Mapping[str, Mapping[str, Mapping]],
    decomposition: Mapping[str, Mapping[str, Mapping]] | None = None,
    png: str = "curve.png",
) -> list[str]:
    """The report's markdown: per scene a table of the points (accuracy in %), each
    confidence family's gain over random inspection with its CI and p, and (when given)
    the decomposition of :func:`ipbench.eval.sorting.curve.decomposition`."""
    lines = ["## Accuracy against inspection effort", "", _HOW_TO_READ, ""]
    head = ["family", "policy", "threshold", "inspections / object", "accuracy", "95 % CI"]
    for scene, families in curve.items():
        lines += [f"### {scene}", "", "| " + " | ".join([*head, "seeds"]) + " |"]
        lines.append("|---" * (len(head) + 1) + "|")
        for family, entry in families.items():
            for p in entry["points"]:
                t = "–" if p["threshold"] is None else f"{p['threshold']:g}"
                cells = [family, f"`{p['policy']}`", t, f"{p['inspections_per_object']:.3f}"]
                cells += [f"{_pct(p['accuracy_mean'])} %"]
                cells += [f"[{_pct(p['ci_low'])}, {_pct(p['ci_high'])}] %", str(p["n"])]
                lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
        for family, entry in families.items():
            if entry["score"] is not None:
                lines += [_score_line(family, entry["score"]), ""]
        if decomposition and decomposition.get(scene):
            lines += ["#### What inspection did", "", *_decomposition_lines(decomposition[scene])]
            lines += ["", _DECOMPOSITION_HOW_TO_READ, ""]
    return [*lines, f"![accuracy against inspections per object]({png})", ""]
