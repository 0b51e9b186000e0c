"""Exploration episode records: their schema checked, grouped by scene, policy and feature.

The schema is :mod:`ipbench.eval.exploration.report`'s; :func:`check_record` raises
:class:`ExplorationReportError` naming the record and the field, :func:`group_records` groups
checked records in display order (one record per seed, duplicates refused).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from numbers import Integral, Real

from ipbench.eval.exploration.missed import MISSED_CAUSES

__all__ = [
    "FEATURES",
    "FP_REASONS",
    "PAIRED_KEY",
    "PROPOSED",
    "POLICY_ORDER",
    "SCENES",
    "ExplorationReportError",
    "Groups",
    "check_budget",
    "check_record",
    "group_records",
    "ordered",
]

SCENES: tuple[str, ...] = ("simple", "medium", "complex")
"""Scene levels, in display order (the keys of ``ipbench.envs.exploration_scene.LEVELS``)."""
FEATURES: tuple[str, ...] = ("sift", "kaze", "akaze", "orb")
"""Feature types, in display order (``ipbench.perception.features2d.FEATURE_TYPES``)."""
POLICY_ORDER = (
    "active-vision",
    "oracle-gaze",
    "raster-scan",
    "random-gaze",
    "active-vision-no-halt",
)
"""Display order of the policies (the benchmark's, then its ablations)."""
FP_REASONS = ("wrong_class", "already_reported", "nothing_there")
PROPOSED = "active-vision"
"""The policy the report compares with every other (paired over seeds)."""
PAIRED_KEY = "vs_active_vision"
"""The key of a baseline cell's paired test against :data:`PROPOSED` in ``summary.json``."""


class ExplorationReportError(ValueError):
    """Bad episode records or report settings; the message names the record and field."""


def _where(record: Mapping, index: int) -> str:
    keys = ("scene", "policy", "feature", "seed")
    return f"episode {index} (" + ", ".join(f"{k}={record.get(k)!r}" for k in keys) + ")"


def _is_int(v: object) -> bool:
    return isinstance(v, Integral) and not isinstance(v, bool)


def _is_real(v: object) -> bool:
    return isinstance(v, Real) and not isinstance(v, bool) and math.isfinite(float(v))


_FIELDS: dict[str, tuple[str, Callable[[object], bool]]] = {
    "n_database": ("an int >= 0", lambda v: _is_int(v) and v >= 0),
    "true_positives": ("an int >= 0", lambda v: _is_int(v) and v >= 0),
    "false_positives": ("an int >= 0", lambda v: _is_int(v) and v >= 0),
    "not_found": ("an int >= 0", lambda v: _is_int(v) and v >= 0),
    "recovered": ("an int >= 0", lambda v: _is_int(v) and v >= 0),
    "performance": ("a number in [0, 1]", lambda v: _is_real(v) and 0 <= v <= 1),
    "saccades": ("an int >= 0", lambda v: _is_int(v) and v >= 0),
    "steps": ("an int >= 0", lambda v: _is_int(v) and v >= 0),
    "sim_time_s": ("a number >= 0", lambda v: _is_real(v) and v >= 0),
    "wall_time_s": ("a number >= 0", lambda v: _is_real(v) and v >= 0),
    "cycle_s": ("a number >= 0", lambda v: _is_real(v) and v >= 0),
    "refixation_rate": ("a number in [0, 1]", lambda v: _is_real(v) and 0 <= v <= 1),
    "saccades_to_all": ("an int >= 0 or null", lambda v: v is None or (_is_int(v) and v >= 0)),
    "sim_s_to_all": ("a number >= 0 or null", lambda v: v is None or (_is_real(v) and v >= 0)),
    "halted": ("a bool", lambda v: isinstance(v, bool)),
    "truncated": ("a bool", lambda v: isinstance(v, bool)),
    "video": ("a str or null", lambda v: v is None or isinstance(v, str)),
    "fp_reasons": (
        f"a dict of ints >= 0 with the keys {', '.join(FP_REASONS)}",
        lambda v: (
            isinstance(v, Mapping)
            and set(v) == set(FP_REASONS)
            and all(_is_int(x) and x >= 0 for x in v.values())
        ),
    ),
    "recall_curve": (
        "a non-empty list of numbers in [0, 1]",
        lambda v: isinstance(v, list) and v and all(_is_real(x) and 0 <= x <= 1 for x in v),
    ),
    "localisation_mm": (
        "a list of numbers >= 0",
        lambda v: isinstance(v, list) and all(_is_real(x) and x >= 0 for x in v),
    ),
}
_REQUIRED = ("scene", "policy", "feature", "seed", *_FIELDS)


def _is_sighting(v: object) -> bool:
    return (
        isinstance(v, list)
        and len(v) == 3
        and _is_real(v[0])
        and 0 <= v[0] <= 180
        and isinstance(v[1], bool)
        and _is_int(v[2])
        and v[2] > 0
    )


_OPTIONAL: dict[str, tuple[str, Callable[[object], bool]]] = {
    "sightings": (
        "a list of [eccentricity_deg in [0, 180], recognised (bool), pixels (int > 0)]",
        lambda v: isinstance(v, list) and all(_is_sighting(x) for x in v),
    ),
    "false_candidates": ("an int >= 0", lambda v: _is_int(v) and v >= 0),
    "looks": ("an int >= 0", lambda v: _is_int(v) and v >= 0),
}
"""Fields of the records that carry recognition against eccentricity
(:mod:`ipbench.eval.exploration.sightings`); older records lack them, and a record has all
three or none."""


def _is_missed(v: object) -> bool:
    return (
        isinstance(v, Mapping)
        and set(v) == set(MISSED_CAUSES)
        and all(_is_int(n) and n >= 0 for n in v.values())
    )


def check_record(record: object, index: int) -> None:
    """Raise :class:`ExplorationReportError` naming the record and field on a bad record."""
    if not isinstance(record, Mapping):
        raise ExplorationReportError(f"episode {index} is a {type(record).__name__}, not a dict")
    where = _where(record, index)
    missing = [k for k in _REQUIRED if k not in record]
    if missing:
        raise ExplorationReportError(f"{where} lacks {', '.join(missing)}")
    if record["scene"] not in SCENES:
        raise ExplorationReportError(
            f"{where}: unknown scene {record['scene']!r}; valid: {', '.join(SCENES)}"
        )
    if record["feature"] not in FEATURES:
        raise ExplorationReportError(
            f"{where}: unknown feature {record['feature']!r}; valid: {', '.join(FEATURES)}"
        )
    if not isinstance(record["policy"], str) or not record["policy"]:
        raise ExplorationReportError(f"{where}: policy must be a non-empty str")
    if not _is_int(record["seed"]):
        raise ExplorationReportError(f"{where}: seed must be an int, got {record['seed']!r}")
    for key, (what, ok) in _FIELDS.items():
        if not ok(record[key]):
            raise ExplorationReportError(f"{where}: {key} must be {what}, got {record[key]!r}")
    present = [k for k in _OPTIONAL if k in record]
    if present and len(present) != len(_OPTIONAL):
        lacking = [k for k in _OPTIONAL if k not in record]
        raise ExplorationReportError(
            f"{where} has {', '.join(present)} but lacks {', '.join(lacking)} (all or none)"
        )
    for key in present:
        what, ok = _OPTIONAL[key]
        if not ok(record[key]):
            raise ExplorationReportError(f"{where}: {key} must be {what}, got {record[key]!r}")
    tp, fp, nf = (record[k] for k in ("true_positives", "false_positives", "not_found"))
    if "missed" in record:  # optional: older records lack it (ipbench.eval.exploration.missed)
        if not _is_missed(record["missed"]):
            raise ExplorationReportError(
                f"{where}: missed must map each of {', '.join(MISSED_CAUSES)} to an int >= 0, "
                f"got {record['missed']!r}"
            )
        if sum(record["missed"].values()) != nf:
            raise ExplorationReportError(
                f"{where}: missed {dict(record['missed'])} does not add up to not_found = {nf} "
                "(every instance not found has one cause)"
            )
    if tp + nf != record["n_database"]:
        raise ExplorationReportError(
            f"{where}: true_positives + not_found = {tp + nf} but n_database = "
            f"{record['n_database']} (every database instance is found or not found)"
        )
    if sum(record["fp_reasons"].values()) != fp:
        raise ExplorationReportError(
            f"{where}: fp_reasons {dict(record['fp_reasons'])} do not add up to "
            f"false_positives = {fp}"
        )
    expected = tp / (tp + fp + nf) if tp + fp + nf else 1.0
    if abs(record["performance"] - expected) > 1e-6:
        raise ExplorationReportError(
            f"{where}: performance {record['performance']} is not TP / (TP + FP + not found) "
            f"= {expected:.6f}"
        )
    if record["recovered"] > tp:
        raise ExplorationReportError(f"{where}: recovered {record['recovered']} > TP {tp}")
    if len(record["localisation_mm"]) != tp:
        raise ExplorationReportError(
            f"{where}: localisation_mm has {len(record['localisation_mm'])} errors for {tp} "
            "true positives (one per true positive)"
        )
    if len(record["recall_curve"]) != record["saccades"] + 1:
        raise ExplorationReportError(
            f"{where}: recall_curve has {len(record['recall_curve'])} values for "
            f"{record['saccades']} saccades (k = 0..saccades: saccades + 1 values)"
        )


def ordered(names: Iterable[str], preferred: Sequence[str]) -> list[str]:
    """``names`` in ``preferred`` order, the others after in alphabetical order."""
    names = set(names)
    return [n for n in preferred if n in names] + sorted(names - set(preferred))


Groups = dict[str, dict[str, dict[str, list[Mapping]]]]


def group_records(episodes: Sequence[Mapping]) -> Groups:
    """``{scene: {policy: {feature: [record, ...]}}}`` in display order, records by seed."""
    cells: dict[tuple[str, str, str], dict[int, Mapping]] = {}
    for i, ep in enumerate(episodes):
        check_record(ep, i)
        runs = cells.setdefault((ep["scene"], ep["policy"], ep["feature"]), {})
        if ep["seed"] in runs:
            raise ExplorationReportError(
                f"two records of scene={ep['scene']!r}, policy={ep['policy']!r}, "
                f"feature={ep['feature']!r}, seed={ep['seed']} (the second is episode {i}); "
                "remove the duplicate"
            )
        runs[int(ep["seed"])] = ep
    out: Groups = {}
    for scene in ordered({k[0] for k in cells}, SCENES):
        out[scene] = {}
        for policy in ordered({k[1] for k in cells if k[0] == scene}, POLICY_ORDER):
            feats = ordered({k[2] for k in cells if k[:2] == (scene, policy)}, FEATURES)
            out[scene][policy] = {
                f: [cells[scene, policy, f][s] for s in sorted(cells[scene, policy, f])]
                for f in feats
            }
    return out


def check_budget(budget: object) -> None:
    """Raise :class:`ExplorationReportError` unless ``budget`` (saccades) is an int >= 1."""
    if not _is_int(budget) or budget < 1:
        raise ExplorationReportError(f"budget must be an int >= 1 (saccades), got {budget!r}")
