"""The in-hand sections of ``perception.md``: the in-hand ablation and fused accuracy against
the number of views (:mod:`ipbench.eval.perception.in_hand_ablation`,
:mod:`ipbench.eval.perception.view_fusion`)."""

from __future__ import annotations

__all__ = ["fusion_table", "in_hand_ablation_table"]

_ROW_TITLES = {
    "baseline": "baseline (every factor as captured)",
    "true_mask": "true_mask: the simulator's mask instead of the in-hand segmentation",
    "no_jaws": "no_jaws: the gripper's points dropped from the cloud",
    "ideal_depth": "ideal_depth: depth without sensor noise",
    "table_distance": "table_distance: the camera at the table-top views' distance",
}


def _acc(entry: dict, key: str = "accuracy") -> str:
    value = entry.get(key)
    return "—" if value is None else f"{value:.3f}"


def in_hand_ablation_table(metrics: dict) -> list[str]:
    """Markdown lines: accuracy with each in-hand factor removed (nothing without the
    ablation)."""
    ablation = metrics.get("in_hand_ablation", {})
    if not ablation:
        return []
    names = list(next(iter(ablation.values())))
    base = ablation.get("baseline", {})
    lines = [
        "## In-hand ablation",
        "",
        "5-class accuracy on in-hand views of the similar and novel instances with one factor "
        "removed from the capture (light protocol: 3 instances per category and split, 3 views "
        "per grasp, 2 grasps per resting pose; every row from the same grasps and turns). The "
        "in-hand model is retrained per row on that row's views of the train instances (the "
        "codebook stays the one of the table-top views): a row measures what the factor costs "
        "when training sees it too. Nothing removes the physics (the jaws hide the object). "
        "Accuracy all / similar / novel (change from the baseline, all).",
        "",
        "| factor removed | " + " | ".join(names) + " | views (train / test) |",
        "|---|" + "---|" * (len(names) + 1),
    ]
    for row, by_name in ablation.items():
        cells = []
        for n in names:
            m = by_name[n]
            delta = ""
            if row != "baseline" and m.get("accuracy") is not None and n in base:
                delta = f" ({m['accuracy'] - base[n]['accuracy']:+.3f})"
            cells.append(
                f"{_acc(m)} / {_acc(m, 'similar_accuracy')} / {_acc(m, 'novel_accuracy')}{delta}"
            )
        first = by_name[names[0]]
        counts = f"{first.get('train_n', 0)} / {first.get('n', 0)}"
        lines.append(f"| {_ROW_TITLES.get(row, row)} | " + " | ".join(cells) + f" | {counts} |")
    return lines + [""]


def fusion_table(metrics: dict) -> list[str]:
    """Markdown lines: fused accuracy for 1..6 views, in hand and on the table (nothing
    without fusion results)."""
    fusion = metrics.get("fusion", {})
    if not fusion:
        return []
    k = max(len(m["accuracy_by_views"]) for c in fusion.values() for m in c.values())
    lines = [
        "## Fused accuracy against the number of views",
        "",
        "Every run of k consecutive views of one test instance (similar and novel), fused by "
        "majority vote (the thesis' rule; ties: the highest single-view probability) and by "
        "the product of the predictive distributions (`bayes`). In hand: the turns of a grasp, "
        "30 deg apart, classified by the in-hand model; table top: yaw steps of 20 deg, by "
        "the table-top model.",
        "",
        "| views | rule | " + " | ".join(str(i + 1) for i in range(k)) + " |",
        "|---|---|" + "---|" * k,
    ]
    for condition, by_name in fusion.items():
        for name, m in by_name.items():
            for rule, key in (
                ("majority", "accuracy_by_views"),
                ("bayes", "bayes_accuracy_by_views"),
            ):
                if key not in m:
                    continue
                cells = ["—" if a is None else f"{a:.3f}" for a in m[key]]
                lines.append(f"| {condition}, {name} | {rule} | " + " | ".join(cells) + " |")
    return lines + [""]
