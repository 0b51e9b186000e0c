"""The calibration figures of several seeds as distributions (``ipbench eval calibration``).

One seed's record (:func:`~ipbench.eval.calibration.evaluate.run_calibration_seed`) holds one
hand-eye study, one self-calibration and one reconstruction run. A figure of one seed depends on
that seed's board poses and gazes, so every figure is reported over the seeds: per figure a
distribution :func:`distribution` (mean, median, percentile bootstrap interval of the mean, the
per-seed values), and per comparison that matters a paired difference over the seeds
:func:`comparison` (sign-flip permutation p):

- ``head_dynamic - head_encoders``: what the dynamic update (with its consistency check) gains
  over the encoders alone;
- ``head_dynamic - head_true`` and ``head_encoders - head_true``: how far each is from what the
  true cameras reconstruct (the floor set by corner detection);
- ``wrist_robot calibrated - nominal`` and, per camera, the self-calibrated X's error minus the
  nominal model's: what calibrating is worth.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ipbench.eval.calibration.reconstruction import THESIS
from ipbench.eval.stats import bootstrap_ci, paired_test

__all__ = [
    "HEAD_KEYS",
    "aggregate",
    "comparison",
    "distribution",
    "floor_geometry",
    "per_seed_figures",
]

HEAD_KEYS = {
    "head_true_rmse_mm": "true",
    "head_encoders_rmse_mm": "encoders",
    "head_dynamic_rmse_mm": "dynamic_checked",
    "head_dynamic_unchecked_rmse_mm": "dynamic_both",
    "head_dynamic_left_chain_rmse_mm": "dynamic",
}
"""metrics.json's head reconstruction figures and the method of
:func:`~ipbench.eval.calibration.reconstruction.reconstruct_head` each reports."""
_COMPARISONS = {
    "head_dynamic_minus_encoders_rmse_mm": ("head_dynamic_rmse_mm", "head_encoders_rmse_mm"),
    "head_dynamic_minus_true_rmse_mm": ("head_dynamic_rmse_mm", "head_true_rmse_mm"),
    "head_encoders_minus_true_rmse_mm": ("head_encoders_rmse_mm", "head_true_rmse_mm"),
    "wrist_robot_calibrated_minus_nominal_rmse_mm": (
        "wrist_robot_rmse_mm",
        "wrist_robot_nominal_rmse_mm",
    ),
}


def distribution(values: Sequence[float | None], level: float = 0.95) -> dict | None:
    """``{"mean", "median", "ci_low", "ci_high", "n", "values"}`` of the finite ``values`` (one
    per seed; None is left out), the interval a percentile bootstrap of the mean (None for
    fewer than two values); None when no value is finite."""
    kept = [float(v) for v in values if v is not None and np.isfinite(v)]
    if not kept:
        return None
    mean, low, high = bootstrap_ci(kept, level=level)
    wide = len(kept) >= 2
    return {
        "mean": mean,
        "median": float(np.median(kept)),
        "ci_low": low if wide else None,
        "ci_high": high if wide else None,
        "n": len(kept),
        "values": kept,
    }


def comparison(a: dict[int, float | None], b: dict[int, float | None]) -> dict | None:
    """``a - b`` paired over the seeds where both are finite: :func:`distribution` of the
    differences (the interval :func:`~ipbench.eval.stats.paired_test`'s) plus ``p_value``;
    None without a common seed."""
    ok = {s for s in a if a[s] is not None and b.get(s) is not None}
    if not ok:
        return None
    test = paired_test({s: a[s] for s in ok}, {s: b[s] for s in ok})
    diffs = [float(a[s]) - float(b[s]) for s in sorted(ok)]
    wide = test.n >= 2
    return {
        "mean": test.mean_diff,
        "median": float(np.median(diffs)),
        "ci_low": test.ci_low if wide else None,
        "ci_high": test.ci_high if wide else None,
        "n": test.n,
        "values": diffs,
        "p_value": test.p_value,
    }


def _rate(trials: list[dict], hit: Callable[[dict], bool]) -> float | None:
    return float(np.mean([hit(t) for t in trials])) if trials else None


def per_seed_figures(record: dict) -> dict:
    """The scalars of one seed's record that :func:`aggregate` distributes (None: not measured)."""
    rec = record["reconstruction"]
    head = rec.get("head") or {}
    methods = head.get("methods") or {}
    trials = head.get("per_trial") or []
    out: dict = {"seed": record["seed"]}
    for key, method in HEAD_KEYS.items():
        out[key] = methods[method]["rmse_mm"] if method in methods else None

    def worse(method: str) -> Callable[[dict], bool]:
        return lambda t: method in t["rmse_mm"] and t["rmse_mm"][method] > t["rmse_mm"]["encoders"]

    updated = [t for t in trials if "dynamic_both" in t["rmse_mm"]]
    out["head_fallback_rate"] = _rate(trials, lambda t: t["check"]["chosen"] != "dynamic_both")
    out["head_update_failure_rate"] = _rate(trials, lambda t: "dynamic_both" not in t["rmse_mm"])
    # against the truth (evaluation only): how often the update is worse than the encoders on
    # the board it is scored on, before and after the check
    out["head_unchecked_worse_rate"] = _rate(updated, worse("dynamic_both"))
    out["head_dynamic_worse_rate"] = _rate(trials, worse("dynamic_checked"))
    for key in ("wrist_rmse_mm", "wrist_robot_rmse_mm", "wrist_robot_nominal_rmse_mm"):
        out[key] = rec.get(key)
    for cam, c in record["self_calibration"]["cameras"].items():
        for which in ("nominal", "calibrated"):
            for unit in ("rotation_deg", "translation_mm"):
                out[f"self_calibration.{cam}.{which}.{unit}"] = c[which][unit]
    for cam, by_method in record["hand_eye"].items():
        for method, cell in by_method.items():
            for unit, value in cell.items():
                out[f"hand_eye.{cam}.{method}.{unit}"] = value
    return out


def floor_geometry(records: Sequence[dict]) -> dict | None:
    """What the floor (the true cameras' per-trial RMSE) depends on, over every trial of the
    seeds: its median and 90th percentile, and its Spearman rank correlation (rho, p) with the
    scored board's distance from the head and its incidence angle; None without trials."""
    from scipy.stats import spearmanr

    trials = [t for r in records for t in (r["reconstruction"].get("head") or {}).get(
        "per_trial", []) if "board_distance_m" in t]  # fmt: skip
    if len(trials) < 3:
        return None
    floor = np.array([t["rmse_mm"]["true"] for t in trials])
    out = {"trials": len(trials), "median_rmse_mm": float(np.median(floor)),
           "p90_rmse_mm": float(np.quantile(floor, 0.9))}  # fmt: skip
    for key in ("board_distance_m", "incidence_deg"):
        values = np.array([t[key] for t in trials])
        rho, p = spearmanr(values, floor)
        out[key] = {"min": float(values.min()), "max": float(values.max()),
                    "spearman_rho": float(rho), "p_value": float(p)}  # fmt: skip
    return out


def aggregate(records: Sequence[dict], robot_seed: int | None, level: float = 0.95) -> dict:
    """metrics.json of the seeds' ``records`` (one per seed, any order): every figure as a
    :func:`distribution`, the comparisons (module docstring) as :func:`comparison`, the
    thesis' figures, and ``per_seed`` (the scalars of :func:`per_seed_figures`, by seed)."""
    rows = sorted((per_seed_figures(r) for r in records), key=lambda r: r["seed"])
    keys = [k for k in rows[0] if k != "seed"] if rows else []

    def dist(key: str) -> dict | None:
        return distribution([r.get(key) for r in rows], level)

    def by_seed(key: str) -> dict[int, float | None]:
        return {r["seed"]: r.get(key) for r in rows}

    reconstruction = {k: dist(k) for k in keys if "." not in k}
    nested: dict = {"self_calibration": {}, "hand_eye": {}}
    for key in keys:
        if "." in key:
            block, cam, name, unit = key.split(".")
            nested[block].setdefault(cam, {}).setdefault(name, {})[unit] = dist(key)
    comparisons = {name: comparison(by_seed(a), by_seed(b)) for name, (a, b) in
                   _COMPARISONS.items()}  # fmt: skip
    for cam in nested["self_calibration"]:
        for unit in ("rotation_deg", "translation_mm"):
            comparisons[f"{cam}_calibrated_minus_nominal_{unit}"] = comparison(
                by_seed(f"self_calibration.{cam}.calibrated.{unit}"),
                by_seed(f"self_calibration.{cam}.nominal.{unit}"),
            )
    return {
        "seeds": [r["seed"] for r in rows],
        "robot_seed": robot_seed,
        "confidence": level,
        "reconstruction": reconstruction,
        "hand_eye": nested["hand_eye"],
        "self_calibration": nested["self_calibration"],
        "comparisons": comparisons,
        "head_floor": floor_geometry(records),
        "thesis": dict(THESIS),
        "per_seed": rows,
    }
