"""What a sorting run's episodes add up to: per scene and policy the accuracy with its interval
over seeds, counts per category, and where the objects not sorted right were lost; beside the
thesis' Table 5.1.

Input is one JSON record per sorting episode (``episodes.jsonl``) with at least ``scene,
policy, seed, objects, correct, accuracy, per_category, inspections, grasp_failures,
wall_time_s, sim_time_s, decisions`` and ``losses`` (:func:`loss_decomposition`; records
without ``losses`` are read, their cells get no decomposition).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ipbench.assets.objects.catalog import CATEGORIES
from ipbench.eval.stats import bootstrap_ci  # re-exported

__all__ = [
    "LOSSES",
    "POLICY_ORDER",
    "SCENE_ORDER",
    "THESIS_TABLE_5_1",
    "ThesisResult",
    "group_episodes",
    "loss_decomposition",
    "ordered",
    "summarize",
    "summarize_groups",
]

POLICY_ORDER = (
    "oracle", "oracle-scene", "gp-ipm", "gp-ipm-area", "svm-ipm", "deep-ipm", "random",
)  # fmt: skip
SCENE_ORDER = ("uncluttered", "cluttered")
_REQUIRED = (
    "scene",
    "policy",
    "seed",
    "objects",
    "correct",
    "accuracy",
    "per_category",
    "inspections",
    "grasp_failures",
    "wall_time_s",
    "sim_time_s",
    "decisions",
)
LOSSES: tuple[str, ...] = ("label", "wrong_object", "misplaced", "dropped", "left")
"""Where an object not sorted into its own bin was lost (the keys of a record's ``losses``;
see :func:`loss_decomposition`)."""
_LEFT = ("on_table", "in_inspection_area", "in_hand")


# --------------------------------------------------------------------------- thesis numbers


@dataclass(frozen=True)
class ThesisResult:
    """One total of the thesis' Table 5.1: ``correct`` of ``total`` objects sorted right.

    ``label`` is the thesis' own name of the method.
    """

    label: str
    correct: int
    total: int

    @property
    def percent(self) -> float:
        """``100 * correct / total`` (%)."""
        return 100.0 * self.correct / self.total


THESIS_TABLE_5_1: dict[str, dict[str, ThesisResult]] = {
    "uncluttered": {
        "gp-ipm": ThesisResult("GP-based interactive sorting", 9, 9),
        "random": ThesisResult("random", 9, 9),
    },
    "cluttered": {
        "gp-ipm": ThesisResult("GP-based interactive sorting", 12, 14),
        "random": ThesisResult("random", 8, 14),
    },
}
"""Totals of the thesis' Table 5.1 (Glasgow 2018) by scene and our policy name.

Its per-category counts are not known to us, so only the totals are reproduced.
"""


# --------------------------------------------------------------------------- losses


def loss_decomposition(
    categories: Sequence[str],
    statuses: Sequence[Sequence[str]],
    aimed: Sequence[int | None],
    bins: Sequence[str | None] | None = None,
) -> dict[str, int]:
    """Where the objects of one episode that did not end in their own bin were lost.

    Parameters
    ----------
    categories : ``categories[k]``: object ``k``'s category.
    statuses : the env's object statuses (``info["objects"][k]["status"]``: ``on_table``,
        ``in_inspection_area``, ``in_hand``, ``in_bin:<category>``, ``dropped``) at reset
        (``statuses[0]``) and after each step ``t`` (``statuses[t + 1]``).
    aimed : ``aimed[t]``: the object step ``t``'s decision aimed at — the policy's last
        decision when it chose the action, which for an inspection is the decision that
        picked the object steps before —, i.e. the object owning most of the decision's
        pixels in the ground-truth mask of the view it was made on (None: background).
    bins : ``bins[t]``: the bin (category) step ``t`` sent its object to (``place_in_bin``),
        None for other steps; None: every place went where it was sent.

    Returns
    -------
    dict
        ``{"label", "wrong_object", "dropped", "left"}`` counts (:data:`LOSSES`) adding up to
        the objects not in their own bin at the end. An object in a wrong bin is attributed
        to the step that last changed its status (the one that put it there; for an
        inspection, the place that ended it, whose decision also made the pick): ``label``
        when it is the object that step's decision aimed at and that bin is the one the step
        sent it to — the grasp took the aimed object and the label sent it to a wrong bin —;
        ``misplaced`` when it is the aimed object but it fell into another bin than it was
        sent to (it tipped over the rim: handling); else ``wrong_object`` (a neighbour or another
        object than the aimed one went into a wrong bin). ``dropped``: off the table at the
        end; ``left``: on the table, in the inspection area or in hand at the end. An object
        that a wrong-object grasp carried into its own bin is correct, not a loss.

    Raises
    ------
    ValueError
        On a ``statuses`` row of the wrong length, ``len(statuses) != len(aimed) + 1`` or an
        unknown status.
    """
    n = len(categories)
    if len(statuses) != len(aimed) + 1 or any(len(row) != n for row in statuses):
        raise ValueError(
            f"loss_decomposition needs one status row of {n} objects at reset and one after "
            f"each of the {len(aimed)} steps, got {len(statuses)} rows of lengths "
            f"{sorted({len(row) for row in statuses})}"
        )
    if bins is not None and len(bins) != len(aimed):
        raise ValueError(f"loss_decomposition: {len(bins)} bins for {len(aimed)} steps")
    settled_by: list[int | None] = [None] * n  # aimed object of the step that last moved k
    sent_to: list[str | None] = [None] * n  # the bin that step sent its object to
    for t, aim in enumerate(aimed):
        for k in range(n):
            if statuses[t + 1][k] != statuses[t][k]:
                settled_by[k] = aim
                sent_to[k] = None if bins is None else bins[t]
    losses = dict.fromkeys(LOSSES, 0)
    for k, (category, status) in enumerate(zip(categories, statuses[-1], strict=True)):
        if status == f"in_bin:{category}":
            continue
        if status.startswith("in_bin:"):
            if settled_by[k] != k:
                losses["wrong_object"] += 1
            elif sent_to[k] is None or status == f"in_bin:{sent_to[k]}":
                losses["label"] += 1
            else:
                losses["misplaced"] += 1
        elif status == "dropped":
            losses["dropped"] += 1
        elif status in _LEFT:
            losses["left"] += 1
        else:
            raise ValueError(f"object {k} has an unknown status {status!r}")
    return losses


def _check_losses(record: Mapping, index: int) -> None:
    """A record's ``losses`` (when it has them) hold the :data:`LOSSES` counts, adding up to
    the objects not sorted right."""
    losses = record["losses"]
    where = (
        f"episode {index} (scene={record.get('scene')!r}, policy={record.get('policy')!r}, "
        f"seed={record.get('seed')!r})"
    )
    if not isinstance(losses, Mapping) or set(losses) != set(LOSSES):
        raise ValueError(f"{where}: losses must have the keys {', '.join(LOSSES)}, got {losses!r}")
    lost = int(record["objects"]) - int(record["correct"])
    if sum(int(losses[k]) for k in LOSSES) != lost or min(int(v) for v in losses.values()) < 0:
        raise ValueError(
            f"{where}: losses {dict(losses)} do not add up to the {lost} objects not sorted "
            "right (objects - correct)"
        )


# --------------------------------------------------------------------------- summary


def ordered(names: Iterable[str], preferred: Sequence[str]) -> list[str]:
    """``names`` in ``preferred`` order, the others after in alphabetical order."""
    names = set(names)
    return [n for n in preferred if n in names] + sorted(names - set(preferred))


def _check_episode(record: object, index: int) -> None:
    if not isinstance(record, Mapping):
        raise ValueError(f"episode {index} is a {type(record).__name__}, expected a dict")
    missing = [k for k in _REQUIRED if k not in record]
    if missing:
        raise ValueError(
            f"episode {index} (scene={record.get('scene')!r}, policy={record.get('policy')!r}, "
            f"seed={record.get('seed')!r}) lacks {', '.join(missing)}"
        )
    if record.get("losses") is not None:
        _check_losses(record, index)


def group_episodes(episodes: Sequence[Mapping]) -> dict[str, dict[str, list[Mapping]]]:
    """``{scene: {policy: [episode, ...]}}`` in display order, episodes sorted by seed.

    Raises ``ValueError`` on a missing required key or on two episodes with the same
    (scene, policy, seed): a seed is counted once.
    """
    groups: dict[tuple[str, str], dict[int, Mapping]] = {}
    for i, ep in enumerate(episodes):
        _check_episode(ep, i)
        runs = groups.setdefault((str(ep["scene"]), str(ep["policy"])), {})
        seed = int(ep["seed"])
        if seed in runs:
            raise ValueError(
                f"two episodes for scene={ep['scene']!r}, policy={ep['policy']!r}, seed={seed} "
                f"(the second is episode {i}); remove the duplicate record"
            )
        runs[seed] = ep
    out: dict[str, dict[str, list[Mapping]]] = {}
    for scene in ordered({s for s, _ in groups}, SCENE_ORDER):
        policies = ordered({p for s, p in groups if s == scene}, POLICY_ORDER)
        out[scene] = {p: [groups[scene, p][s] for s in sorted(groups[scene, p])] for p in policies}
    return out


def _per_category(runs: Sequence[Mapping]) -> dict[str, dict[str, int]]:
    counts: dict[str, dict[str, int]] = {}
    for ep in runs:
        for cat, c in ep["per_category"].items():
            acc = counts.setdefault(cat, {"correct": 0, "total": 0})
            acc["correct"] += int(c.get("correct", 0))
            acc["total"] += int(c.get("total", 0))
    return {cat: counts[cat] for cat in ordered(counts, CATEGORIES)}


def _losses_mean(runs: Sequence[Mapping]) -> dict[str, float] | None:
    """Mean per episode of each :data:`LOSSES` count; None when an episode has no
    ``losses`` (recorded before the decomposition)."""
    if any(ep.get("losses") is None for ep in runs):
        return None
    return {k: float(np.mean([ep["losses"][k] for ep in runs])) for k in LOSSES}


def _policy_summary(runs: Sequence[Mapping]) -> dict:
    mean, low, high = bootstrap_ci([float(ep["accuracy"]) for ep in runs])
    objects = sum(int(ep["objects"]) for ep in runs)
    dropped = sum(int(ep.get("dropped", 0)) for ep in runs)
    return {
        "accuracy_mean": mean,
        "ci_low": low,
        "ci_high": high,
        "n": len(runs),
        "seeds": [int(ep["seed"]) for ep in runs],
        "objects": objects,
        "correct": sum(int(ep["correct"]) for ep in runs),
        "inspections_mean": float(np.mean([ep["inspections"] for ep in runs])),
        "inspections_per_object": (
            sum(int(ep["inspections"]) for ep in runs) / objects if objects else 0.0
        ),
        "grasp_failures_mean": float(np.mean([ep["grasp_failures"] for ep in runs])),
        "wall_time_s_mean": float(np.mean([ep["wall_time_s"] for ep in runs])),
        "sim_time_s_mean": float(np.mean([ep["sim_time_s"] for ep in runs])),
        "truncated": sum(bool(ep.get("truncated", False)) for ep in runs),
        "dropped": dropped,
        "dropped_fraction": dropped / objects if objects else 0.0,
        "wrong_bin": sum(int(ep.get("wrong_bin", 0)) for ep in runs),
        "left": sum(int(ep.get("left", 0)) for ep in runs),
        "physics_undone": sum(int(ep.get("physics_undone", 0)) for ep in runs),
        "losses_mean": _losses_mean(runs),
        "losses_missing": sum(ep.get("losses") is None for ep in runs),
        "per_category": _per_category(runs),
    }


def summarize(episodes: Sequence[Mapping]) -> dict[str, dict[str, dict]]:
    """Per scene and policy: accuracy over seeds, counts and means per episode.

    Parameters
    ----------
    episodes : episode records in any order (one per scene, policy and seed).

    Returns
    -------
    dict
        ``{scene: {policy: {...}}}`` in display order (scenes ``uncluttered, cluttered``,
        policies ``oracle, gp-ipm, gp-ipm-area, svm-ipm, random``, others after in
        alphabetical order) with keys ``accuracy_mean, ci_low, ci_high`` (per-seed accuracy,
        fraction in ``[0, 1]``: mean and 95 % bootstrap interval), ``n`` (seeds), ``seeds``,
        ``objects`` and ``correct`` (summed over seeds), ``inspections_mean``,
        ``inspections_per_object`` (inspections / objects, pooled over seeds),
        ``grasp_failures_mean`` (per episode), ``wall_time_s_mean``, ``sim_time_s_mean``
        (s per episode), ``truncated`` (episodes cut by the step limit), ``dropped``,
        ``wrong_bin``, ``left`` (objects, summed over seeds), ``dropped_fraction`` (dropped
        objects / objects of the cell), ``physics_undone`` (steps whose contact blow-up the
        env rolled back), ``losses_mean`` (``{label, wrong_object, dropped, left}``: mean
        objects per episode lost each way, see :func:`loss_decomposition`; None when some
        record of the cell has no ``losses``), ``losses_missing`` (how many records have
        none) and ``per_category`` (``{category: {"correct", "total"}}`` summed over seeds, in
        bin order).

    Raises
    ------
    ValueError
        On a record without a required key or two records of one (scene, policy, seed).
    """
    return summarize_groups(group_episodes(episodes))


def summarize_groups(groups: Mapping[str, Mapping[str, Sequence[Mapping]]]) -> dict:
    return {
        scene: {policy: _policy_summary(runs) for policy, runs in by_policy.items()}
        for scene, by_policy in groups.items()
    }
