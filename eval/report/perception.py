"""The perception results page (``docs/results/perception.md``) of ``ipbench report docs``.

Per perception run (:mod:`ipbench.eval.report.runs`), from its ``metrics.json``: accuracy, log
loss and ECE per test split and classifier, the unknown instances per class subset, the
segmentation scores (``segmentation.json``), and, when the run has them, the sensor and
in-hand ablations and the fused accuracy against the number of views (the run report's own
tables, :mod:`ipbench.eval.perception.in_hand_report`).
"""

from __future__ import annotations

from collections.abc import Mapping

from ipbench.eval.markdown import demote, generated_header, number, table
from ipbench.eval.perception.in_hand_report import fusion_table, in_hand_ablation_table
from ipbench.eval.report.runs import Run

__all__ = ["perception_command", "perception_page"]

_SPLITS_HOW_TO_READ = (
    "5-class accuracy, log loss and expected calibration error (ECE, 15 bins) of each "
    "classifier, and the number of test views. `similar`: new instances of the trained "
    "families on the table top; `novel`: instances of held-out families on the table top; "
    "`in_hand`: instances not trained on, held up to the wrist camera (the in-hand model); "
    "`clutter`: segments cut out of cluttered scenes (labelled by overlap with the ground "
    "truth)."
)
_SUBSETS_HOW_TO_READ = (
    "The unknown instances (isolated, table top) per class subset: accuracy, log loss and ECE; "
    "`cluttered`: accuracy on the segments of cluttered scenes; `in hand`: accuracy of the "
    "in-hand model on in-hand views, and of the table-top model on the same views."
)
_SEGMENTATION_HOW_TO_READ = (
    "Mean per-scene precision and recall of the segments of each scene's first wrist view "
    "against the ground-truth masks (IoU >= 0.5), and the merged and split segments counted."
)


def perception_command(run: Run) -> str:
    """The ``ipbench eval perception`` command line of ``run`` (its classifiers; the env is
    not recorded in ``metrics.json``)."""
    metrics = run.json("metrics.json") or {}
    names = list(metrics.get("5class", {})) or list(
        next(iter(metrics.get("splits", {}).values()), {})
    )
    return "ipbench eval perception" + (f" --classifiers {','.join(names)}" if names else "")


def _split_lines(metrics: Mapping) -> list[str]:
    splits = metrics.get("splits") or {}
    rows = [
        [
            split,
            f"`{name}`",
            number(m.get("accuracy")),
            number(m.get("log_loss")),
            number(m.get("ece")),
            str(m.get("n", 0)),
        ]
        for split, by_name in splits.items()
        for name, m in by_name.items()
    ]
    if not rows:
        return []
    head = ["split", "classifier", "accuracy", "log loss", "ECE", "views"]
    return ["### Every test split, 5 classes", "", _SPLITS_HOW_TO_READ, "", *table(head, rows), ""]


def _subset_lines(metrics: Mapping) -> list[str]:
    rows = []
    for subset in (k for k in ("5class", "3class") if k in metrics):
        for name, m in metrics[subset].items():
            rows.append(
                [
                    subset.replace("class", " classes"),
                    f"`{name}`",
                    number(m.get("accuracy")),
                    number(m.get("log_loss")),
                    number(m.get("ece")),
                    str(m.get("n", 0)),
                    number(m.get("cluttered", {}).get("accuracy")),
                    number(m.get("in_hand", {}).get("accuracy")),
                    number(m.get("in_hand_scene_model", {}).get("accuracy")),
                ]
            )
    if not rows:
        return []
    head = ["classes", "classifier", "accuracy", "log loss", "ECE", "views", "cluttered"]
    head += ["in hand (in-hand model)", "in hand (table-top model)"]
    return ["### Unknown instances", "", _SUBSETS_HOW_TO_READ, "", *table(head, rows), ""]


def _segmentation_lines(segmentation: Mapping | None) -> list[str]:
    if not segmentation:
        return []
    rows = [
        [
            scene,
            str(m.get("scenes", "–")),
            number(m.get("precision")),
            number(m.get("recall")),
            str(m.get("merged", "–")),
            str(m.get("split", "–")),
        ]
        for scene, m in segmentation.items()
    ]
    head = ["scene", "scenes", "precision", "recall", "merged", "split"]
    return ["### Segmentation", "", _SEGMENTATION_HOW_TO_READ, "", *table(head, rows), ""]


def _sensor_ablation_lines(metrics: Mapping) -> list[str]:
    ablation = metrics.get("ablation") or {}
    if not ablation:
        return []
    names = list(next(iter(ablation.values())))
    rows = [
        [effect, *(number(by_name.get(n, {}).get("accuracy")) for n in names)]
        for effect, by_name in ablation.items()
    ]
    return [
        "### Sensor ablation",
        "",
        "5-class accuracy on the similar and novel table-top views with one sensor effect "
        "switched off (train and test views captured again); `none` switches nothing off.",
        "",
        *table(["effect switched off", *(f"`{n}`" for n in names)], rows),
        "",
    ]


def _run_lines(run: Run) -> list[str]:
    metrics = run.json("metrics.json") or {}
    dataset = (run.json("dataset.json") or {}).get("dataset_key")
    key = f"dataset key `{dataset}`" if dataset else "dataset key not recorded"
    return [
        f"## Run `{run.name}`",
        "",
        f"`{perception_command(run)}`; {key}.",
        "",
        *_split_lines(metrics),
        *_subset_lines(metrics),
        *_segmentation_lines(run.json("segmentation.json")),
        *_sensor_ablation_lines(metrics),
        *demote(in_hand_ablation_table(metrics)),
        *demote(fusion_table(metrics)),
    ]


def perception_page(runs: tuple[Run, ...]) -> str:
    """The page's markdown: every perception run in name order (a note when there is none)."""
    lines = generated_header("Results: perception", [s for r in runs for s in r.sources])
    if not runs:
        lines += ["No perception run among the results (`ipbench eval perception`).", ""]
    for run in runs:
        lines += _run_lines(run)
    return "\n".join(lines).rstrip("\n") + "\n"
