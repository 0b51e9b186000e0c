"""Fused accuracy against the number of views (``metrics.json["fusion"]``)."""

from __future__ import annotations

import numpy as np
import pytest

from ipbench.assets.objects import CATEGORIES, instances
from ipbench.eval.perception.in_hand_report import fusion_table, in_hand_ablation_table
from ipbench.eval.perception.view_fusion import (
    FUSION_VIEWS,
    fused_accuracy,
    fusion_by_views,
    fusion_metrics,
    view_windows,
)
from ipbench.perception.viewset import ViewSet


def test_windows_are_consecutive_views_of_one_instance():
    names = np.array(["a", "a", "a", "b", "b", "c"])
    assert [list(w) for w in view_windows(names, 2)] == [[0, 1], [1, 2], [3, 4]]
    assert [list(w) for w in view_windows(names, 3)] == [[0, 1, 2]]
    assert view_windows(names, 4) == []
    assert len(view_windows(names, 1)) == len(names)
    with pytest.raises(ValueError, match="valid: k >= 1"):
        view_windows(names, 0)


def _probs(preds: list[int], confidence: float = 0.6) -> np.ndarray:
    p = np.full((len(preds), 5), (1 - confidence) / 4)
    p[np.arange(len(preds)), preds] = confidence
    return p


def test_fusion_outvotes_a_minority_of_wrong_views():
    # one instance of class 0: views 2 and 5 are wrong
    preds = [0, 0, 3, 0, 0, 3]
    probs, labels, names = _probs(preds), np.zeros(6, int), np.array(["x"] * 6)
    single, n = fused_accuracy(probs, labels, names, 1)
    assert single == pytest.approx(4 / 6) and n == 6
    assert fused_accuracy(probs, labels, names, 3)[0] == 1.0  # every run of 3: 2 right of 3
    assert fused_accuracy(probs, labels, names, 7) == (None, 0)
    out = fusion_by_views(probs, labels, names, np.array(["novel"] * 6))
    assert len(out["accuracy_by_views"]) == FUSION_VIEWS == 6
    assert len(out["bayes_accuracy_by_views"]) == 6 and len(out["novel_accuracy_by_views"]) == 6
    assert out["accuracy_by_views"][0] == pytest.approx(4 / 6)
    assert out["runs_by_views"] == [6, 5, 4, 3, 2, 1]


def test_bayes_and_majority_differ_where_confidence_matters():
    # two weak right votes against one confident wrong one
    probs = np.array(
        [[0.4, 0.3, 0.1, 0.1, 0.1], [0.4, 0.3, 0.1, 0.1, 0.1], [0.01, 0.96, 0.01, 0.01, 0.01]]
    )
    labels, names = np.zeros(3, int), np.array(["x"] * 3)
    assert fused_accuracy(probs, labels, names, 3, "majority")[0] == 1.0
    assert fused_accuracy(probs, labels, names, 3, "bayes")[0] == 0.0


def test_fusion_metrics_cover_both_conditions():
    by_split = {}
    for inst in instances(catalog="v2"):
        by_split.setdefault(inst.split, inst)
    rng = np.random.default_rng(0)

    def views(inst, source, n):
        descs = [np.ones((3, 33), np.float32)] * n
        label = CATEGORIES.index(inst.category)
        return ViewSet.from_views(descs, [label] * n, [inst.name] * n, [False] * n, source)

    sim, nov = by_split["similar"], by_split["novel"]
    sets = {
        "similar": views(sim, "isolated", 8),
        "novel": views(nov, "isolated", 8),
        "in_hand": ViewSet.concat([views(sim, "in_hand", 6), views(nov, "in_hand", 4)]),
        "clutter": views(sim, "cluttered", 2),
    }
    probs = {(s, "gp"): rng.dirichlet(np.ones(5), len(v)) for s, v in sets.items()}
    out = fusion_metrics(sets, probs, "v2")
    assert set(out) == {"in_hand", "table_top"}
    for condition in out.values():
        m = condition["gp"]
        assert len(m["accuracy_by_views"]) == 6
        assert {"similar_accuracy_by_views", "novel_accuracy_by_views"} <= set(m)
    hand = out["in_hand"]["gp"]
    assert hand["novel_accuracy_by_views"][4] is None  # the novel instance has 4 views
    assert hand["accuracy_by_views"][5] is not None  # the similar one has 6
    lines = "\n".join(fusion_table({"fusion": out}))
    assert "| in_hand, gp | majority |" in lines and "| table_top, gp | bayes |" in lines


def test_in_hand_ablation_table_lists_every_row():
    entry = {"n": 10, "accuracy": 0.5, "train_n": 5, "similar_accuracy": 0.6}
    rows = {r: {"gp": dict(entry)} for r in ("baseline", "true_mask")}
    rows["true_mask"]["gp"]["accuracy"] = 0.7
    text = "\n".join(in_hand_ablation_table({"in_hand_ablation": rows}))
    assert "## In-hand ablation" in text and "retrained per row" in text
    assert "0.700 / 0.600 / — (+0.200)" in text
    assert in_hand_ablation_table({}) == [] and fusion_table({}) == []
