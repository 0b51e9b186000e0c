"""The markdown of the exploration report: the thesis' figures, tables, how to read them.

Used by :func:`ipbench.eval.exploration.report.write_exploration_report`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from ipbench.eval.exploration.missed import MISSED_CAUSES
from ipbench.eval.exploration.records import FEATURES, PAIRED_KEY, PROPOSED, ordered

__all__ = ["THESIS_FIGURES", "ThesisFigure", "markdown_lines"]


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
"""The thesis' exploration performance (A. Khan, PhD thesis, University of Glasgow, 2018, ch. 3,
Tables 3.2 and 3.3). SURF is patented and in no pip wheel of OpenCV, so we cannot run it; AKAZE and
ORB take its place and have no thesis figure."""
_THESIS_SOURCE = "Glasgow 2018 PhD thesis, ch. 3"


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
                t = by_feature.get(feature, {}).get(PAIRED_KEY)
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
        return [f"No baseline ran a scene and feature type that `{PROPOSED}` ran: no test."]
    head = ["scene", "feature", f"{PROPOSED} vs", "seeds", "mean difference (points)"]
    return [*_head([*head, "95 % CI", "p"]), *rows]


def _cells_with(summary: Mapping, key: str) -> list[tuple[str, str, str, Mapping]]:
    """``(scene, policy, feature, cell[key])`` of every cell of ``summary`` that has ``key``,
    sorted by feature type (display order)."""
    rows = [
        (scene, policy, feature, cell[key])
        for scene, by_policy in summary.items()
        for policy, by_feature in by_policy.items()
        for feature, cell in by_feature.items()
        if key in cell
    ]
    return sorted(rows, key=lambda r: FEATURES.index(r[2]))


_ECCENTRICITY_HOW_TO_READ = (
    "How to read: at every look, each database instance visible in the left head image is a "
    "sighting; its eccentricity is the angle between the camera's optical axis and the ray "
    "to the instance's centre. A cell is the share of sightings in that band that the look "
    "recognised (triangulated a candidate of the instance's class on it), with the number "
    "of sightings. If recognition falls off away from the axis, where the head looks decides "
    "what it recognises; if it is flat, one glance recognises as much as many. `false / "
    "look`: candidates near no instance of their class, per look; `episodes`: those that "
    "recorded sightings (records written before they existed have none)."
)


def _eccentricity_lines(summary: Mapping) -> list[str]:
    rows = _cells_with(summary, "eccentricity")
    if not rows:
        return []
    bins = rows[0][3]["bins"]
    bands = [
        f"{b['low_deg']:g}–{b['high_deg']:g}°" if b["high_deg"] < 180 else f"≥ {b['low_deg']:g}°"
        for b in bins
    ]
    lines = ["## Recognition against eccentricity", "", _ECCENTRICITY_HOW_TO_READ, ""]
    lines += _head(["scene", "feature", "policy", *bands, "false / look", "looks", "episodes"])
    for scene, policy, feature, e in rows:
        cells = [
            "–" if b["n"] == 0 else f"{100 * b['recognised'] / b['n']:.0f} % ({b['n']})"
            for b in e["bins"]
        ]
        false = _num(e["false_candidates_per_look"], ".2f")
        lines.append(_row([scene, feature, policy, *cells, false, e["looks"], e["episodes"]]))
    return [*lines, ""]


_MISSED_HOW_TO_READ = (
    "How to read: every database instance an episode did not find is put down to the first "
    "stage of the exploration that lost it, followed look by look: {causes}. A cell is the "
    "share of the instances not found (their number in brackets); `episodes`: those that "
    "recorded it (records written before it existed have none)."
)


def _missed_lines(summary: Mapping) -> list[str]:
    rows = _cells_with(summary, "missed")
    if not rows:
        return []
    causes = ", ".join(f"*{c.replace('_', ' ')}* ({what})" for c, what in MISSED_CAUSES.items())
    lines = ["## Where the objects not found were lost", ""]
    lines += [_MISSED_HOW_TO_READ.format(causes=causes), ""]
    names = [c.replace("_", " ") for c in MISSED_CAUSES]
    lines += _head(["scene", "feature", "policy", "not found", *names, "episodes"])
    for scene, policy, feature, m in rows:
        total = sum(m["causes"].values())
        cells = [
            "–" if not total else f"{100 * m['causes'][c] / total:.0f} % ({m['causes'][c]})"
            for c in MISSED_CAUSES
        ]
        lines.append(_row([scene, feature, policy, total, *cells, m["episodes"]]))
    return [*lines, ""]


def markdown_lines(
    summary: Mapping, budget: int, title: str, recall_figure: str = "recall.png"
) -> list[str]:
    """The lines of ``exploration.md`` for a summary (:func:`~ipbench.eval.exploration.report.
    summarize_exploration`'s shape) of episodes run with a saccade ``budget``; the recall
    figure is linked as ``recall_figure`` (a path relative to the page)."""
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
    lines += [f"![recall vs saccades]({recall_figure})", ""]
    lines += ["## Paired comparisons over seeds", "", _PAIRED_HOW_TO_READ, ""]
    lines += [*_paired_table(summary), ""]
    return lines + _eccentricity_lines(summary) + _missed_lines(summary)
