"""Fused accuracy against the number of views of one object, in hand and on the table.

GP-IPM fuses the labels of the views it takes of an object it holds (thesis: majority vote
over three views turned 30 deg apart). How fast does fusing help, and is an in-hand view
sequence worth as much as the same number of table-top views? For each test view set, every
run of ``k`` consecutive views of one instance in capture order (k = 1 ..
:data:`FUSION_VIEWS`) is fused by each rule of :data:`~ipbench.policies.fusion.FUSIONS`
(``majority``: the thesis' vote; ``bayes``: the normalised product) and scored against the
instance's category. In hand, consecutive views are the turns of one grasp (30 deg apart; a
grasp that ended early lets a run reach into the next grasp of the instance); on the table they
are yaw steps of one elevation (20 deg apart; a run may reach into the next elevation or
pose). k = 1 is the single-view accuracy of the same views.
"""

from __future__ import annotations

import numpy as np

from ipbench.assets.objects import instances
from ipbench.perception.viewset import ViewSet
from ipbench.policies.fusion import FUSIONS, fuse

__all__ = [
    "CONDITION_SPLITS",
    "FUSION_VIEWS",
    "fused_accuracy",
    "fusion_by_views",
    "fusion_metrics",
    "split_of_views",
    "view_windows",
]

CONDITION_SPLITS: dict[str, tuple[str, ...]] = {
    "in_hand": ("in_hand",),
    "table_top": ("similar", "novel"),
}
"""Viewing condition -> the test sets of ``metrics.json["splits"]`` whose views it fuses: the
in-hand views (in-hand model) and the similar and novel table-top views (table-top model)."""

FUSION_VIEWS = 6
"""Views fused at most (``accuracy_by_views`` has this many entries, index k - 1 for k)."""


def view_windows(instance: np.ndarray, k: int) -> list[np.ndarray]:
    """Index arrays (k,) of every run of ``k`` consecutive views of one instance, for the (n,)
    instance names ``instance`` in capture order (an instance's views are contiguous)."""
    if k < 1:
        raise ValueError(f"k={k}; valid: k >= 1 views")
    instance = np.asarray(instance)
    starts = np.flatnonzero(np.r_[True, instance[1:] != instance[:-1]])
    ends = np.r_[starts[1:], len(instance)]
    return [
        np.arange(i, i + k) for s, e in zip(starts, ends, strict=True) for i in range(s, e - k + 1)
    ]


def fused_accuracy(
    probs: np.ndarray, labels: np.ndarray, instance: np.ndarray, k: int, rule: str = "majority"
) -> tuple[float | None, int]:
    """(accuracy, runs) of ``rule`` fusing every run of ``k`` views (:func:`view_windows`):
    ``probs`` (n, C) predictive probabilities, ``labels`` (n,) true classes, ``instance`` (n,)
    names. Accuracy None when no instance has ``k`` views."""
    runs = view_windows(instance, k)
    if not runs:
        return None, 0
    right = [fuse(probs[run], rule)[0] == labels[run[0]] for run in runs]
    return float(np.mean(right)), len(runs)


def fusion_by_views(
    probs: np.ndarray,
    labels: np.ndarray,
    instance: np.ndarray,
    split: np.ndarray | None = None,
    max_views: int = FUSION_VIEWS,
) -> dict:
    """Fused accuracy for k = 1 .. ``max_views``: ``accuracy_by_views`` (majority vote, the
    thesis' rule), ``{rule}_accuracy_by_views`` for every other rule of
    :data:`~ipbench.policies.fusion.FUSIONS`, ``runs_by_views``; with ``split`` (n,) also
    ``{split}_accuracy_by_views`` (majority) for each split name present. Lists have
    ``max_views`` entries (None where no instance has that many views)."""
    probs, labels = np.asarray(probs, float), np.asarray(labels)
    ks = range(1, max_views + 1)
    out: dict = {}
    for rule in FUSIONS:
        key = "accuracy_by_views" if rule == "majority" else f"{rule}_accuracy_by_views"
        scored = [fused_accuracy(probs, labels, instance, k, rule) for k in ks]
        out[key] = [a for a, _ in scored]
        out.setdefault("runs_by_views", [n for _, n in scored])
    if split is not None:
        split = np.asarray(split)
        for name in dict.fromkeys(split.tolist()):
            sel = split == name
            out[f"{name}_accuracy_by_views"] = [
                fused_accuracy(probs[sel], labels[sel], np.asarray(instance)[sel], k)[0] for k in ks
            ]
    return out


def split_of_views(views: ViewSet, catalog: str) -> np.ndarray:
    """(n,) the split (``train``, ``similar``, ``novel``) of each view's instance in
    ``catalog``."""
    split_of = {inst.name: inst.split for inst in instances(catalog=catalog)}
    return np.array([split_of.get(str(n), "train") for n in views.instance], dtype="U8")


def fusion_metrics(sets: dict[str, ViewSet], probs: dict, catalog: str) -> dict:
    """``{condition: {classifier: fusion_by_views(...)}}`` for each condition of
    :data:`CONDITION_SPLITS`: ``sets`` the test sets by split name
    (:func:`~ipbench.eval.perception.evaluate.split_tests`), ``probs[(split, classifier)]`` the
    classifier's (n, C) probabilities of that set's views, in its order."""
    out: dict = {}
    for condition, names in CONDITION_SPLITS.items():
        classifiers = dict.fromkeys(c for s, c in probs if s in names)
        for clf in classifiers:
            if not all((s, clf) in probs for s in names):
                continue
            views = ViewSet.concat([sets[s] for s in names])
            if not len(views):
                continue
            p = np.concatenate([probs[s, clf] for s in names if len(sets[s])])
            split = split_of_views(views, catalog)
            result = fusion_by_views(p, views.labels, views.instance, split)
            out.setdefault(condition, {})[clf] = result
    return out
