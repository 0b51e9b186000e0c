"""The label part of the accuracy–inspection curve, read off one inspect-everything run.

In a run of ``<family>@1.0`` every object chosen is inspected, and its decision keeps both
labels: the first view's (``first_label``, with its confidence) and the one after inspection
(``label``). The loop picks the most confident object first whatever the threshold, so the
label a run at threshold ``T`` would give an object is, as far as labels go, the first one when
its confidence reaches ``T`` and the inspected one otherwise. :func:`label_curve` computes
that for every ``T`` of the threshold grid: the fraction of decisions (with a known true
category) whose label is right, and the fraction inspected. It leaves out what the extra
handling changes (grasps, drops, the scene after a different removal) — which is why every
number of the report comes from episodes, and the measured runs at their thresholds
(``measured``: the same fraction over their own decisions) say how close the shortcut is.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from ipbench.policies import split_policy_name
from ipbench.policies.threshold import THRESHOLD_GRID

__all__ = ["label_curve", "label_curve_lines"]


def _right(decisions: Sequence[Mapping], threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """Per decision with a known truth: the label at ``threshold`` is right; it is inspected."""
    right, inspected = [], []
    for d in decisions:
        if d.get("true_category") is None:
            continue
        look = threshold >= 1.0 or d["first_confidence"] < threshold
        label = d["label"] if look and d.get("views", 0) > 0 else d["first_label"]
        right.append(label == d["true_category"])
        inspected.append(look)
    return np.array(right, bool), np.array(inspected, bool)


def _measured(records: Sequence[Mapping]) -> float:
    """Fraction of the decisions (known truth) whose final label is right."""
    pairs = [
        d["label"] == d["true_category"]
        for r in records
        for d in r["decisions"]
        if d.get("true_category") is not None
    ]
    return float(np.mean(pairs)) if pairs else float("nan")


def label_curve(episodes: Sequence[Mapping], family: str = "gp-ipm") -> dict:
    """``{scene: {"thresholds", "label_accuracy", "inspected_fraction", "decisions",
    "measured": [{"threshold", "label_accuracy", "decisions"}]}}`` for each scene with
    ``<family>@1.0`` records and decisions of known truth (others are left out). Fractions
    in [0, 1]; ``thresholds`` is :data:`~ipbench.policies.threshold.THRESHOLD_GRID`;
    ``measured`` lists every ``<family>@T`` run of the scene."""
    out: dict[str, dict] = {}
    for scene in dict.fromkeys(r["scene"] for r in episodes):
        runs: dict[float, list[Mapping]] = {}
        for r in episodes:
            base, value = split_policy_name(r["policy"])
            if r["scene"] == scene and base == family and value is not None:
                runs.setdefault(value, []).append(r)
        if 1.0 not in runs:
            continue
        decisions = [d for r in runs[1.0] for d in r["decisions"]]
        rows = [_right(decisions, float(t)) for t in THRESHOLD_GRID]
        if rows[0][0].size == 0:
            continue  # no decision with a known truth: nothing to read off
        out[scene] = {
            "thresholds": THRESHOLD_GRID.tolist(),
            "label_accuracy": [float(r.mean()) if r.size else None for r, _ in rows],
            "inspected_fraction": [float(i.mean()) if i.size else None for _, i in rows],
            "decisions": int(rows[0][0].size),
            "measured": [
                {
                    "threshold": t,
                    "label_accuracy": _measured(runs[t]),
                    "decisions": sum(len(r["decisions"]) for r in runs[t]),
                }
                for t in sorted(runs)
            ],
        }
    return out


def label_curve_lines(curve: Mapping[str, Mapping], family: str = "gp-ipm") -> list[str]:
    """Markdown: per scene, the labels read off ``<family>@1.0`` beside each measured run's."""
    if not curve:
        return []
    lines = [
        f"### Labels read off `{family}@1.0`",
        "",
        "The label each object would get at threshold T, read off the run that inspects "
        "everything (first label at or above T, inspected label below; "
        ":mod:`ipbench.eval.sorting.label_curve`), beside the labels the runs at T gave. "
        "The shortcut "
        "leaves out what the extra handling changes; the measured points are the result.",
        "",
        "| scene | T | inspected (read off) | labels right (read off) | labels right (measured) |",
        "|---|---|---|---|---|",
    ]
    for scene, entry in curve.items():
        at = dict(zip(entry["thresholds"], entry["label_accuracy"], strict=True))
        inspected = dict(zip(entry["thresholds"], entry["inspected_fraction"], strict=True))
        for m in entry["measured"]:
            if not m["decisions"]:
                continue
            t = min(at, key=lambda g: abs(g - m["threshold"]))
            lines.append(
                f"| {scene} | {m['threshold']:g} | {100 * inspected[t]:.1f} % | "
                f"{100 * at[t]:.1f} % | {100 * m['label_accuracy']:.1f} % |"
            )
    return [*lines, ""]
