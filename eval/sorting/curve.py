"""The accuracy–inspection curve of the sorting evaluation and a threshold-free score.

A confidence-driven policy (``gp-ipm``, ``gp-ipm-area``, ``svm-ipm``, ``deep-ipm``) run at
inspection thresholds ``T`` (records ``<family>@T``) traces sorting accuracy against
inspection effort; ``random-inspect@P`` (a random fraction ``P`` of the objects inspected,
GP labels) gives the line any policy reaches by inspecting blindly; ``oracle-inspect``
(exactly the objects whose first label is wrong) the best use of inspections; ``random``
(random sorting) the floor. :func:`curve` turns episode records into these points: x is
inspections per object (pooled over seeds: total inspections / total objects), y the mean
over seeds of the per-episode accuracy (fraction in ``[0, 1]``) with its 95 % percentile
bootstrap interval (:func:`ipbench.eval.stats.bootstrap_ci`).

The score does not depend on a threshold. Like the area under the risk–coverage curve of
selective classification (Geifman & El-Yaniv 2017, "Selective classification for deep
neural networks"; AURC: Geifman et al. 2019, "Bias-reduced uncertainty estimation for deep
neural classifiers"), it summarises a whole curve: the mean accuracy gain over random
inspection at equal inspection effort,
``score = 1 / (hi - lo) * integral_lo^hi (family(x) - random_line(x)) dx``, in accuracy
points (fractions), where both are linear between their points and ``[lo, hi]`` is where
both exist — ``[0, x_max]`` (x_max: the family's largest inspections per object) when the
random line reaches x_max. The random line runs through the ``random-inspect@P`` points and
the family's own ``@0`` and ``@1.0`` runs, which inspect nothing and everything: what random
inspection is at P = 0 and 1 (``random-inspect`` labels with the GP, so for another
classifier's family the line's inner points are the GP's). The family's curve is its ``@T``
runs; the validated run (plain name) is a point shown, not integrated.
Each paired seed gives one score (fixed x, per-seed accuracies); ``normalized`` divides it
by ``oracle-inspect``'s gain over the same random line at its own x (the fraction of the
achievable gain).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ipbench.eval.sorting.curve_plot import curve_lines, curve_png
from ipbench.eval.stats import bootstrap_ci, paired_test
from ipbench.policies import INTERACTIVE, split_policy_name

__all__ = [
    "CONFIDENCE_FAMILIES",
    "curve",
    "curve_lines",
    "decomposition",
    "per_seed_scores",
    "write_curve",
]

CONFIDENCE_FAMILIES: tuple[str, ...] = tuple(INTERACTIVE)
"""Policies that inspect the objects whose confidence is below a threshold."""
_FAMILIES = (*CONFIDENCE_FAMILIES, "random-inspect", "oracle-inspect", "random")
_SCENE_ORDER = ("uncluttered", "cluttered")
_REQUIRED = ("scene", "policy", "seed", "objects", "correct", "accuracy", "inspections")


@dataclass(frozen=True)
class _Run:
    """One policy's episodes in one scene: ``episodes[seed]`` is a record."""

    policy: str
    family: str
    value: float | None  # T or P from the name
    episodes: Mapping[int, Mapping]

    def x(self, seeds: Sequence[int]) -> float:
        """Inspections per object pooled over ``seeds``."""
        eps = [self.episodes[s] for s in seeds]
        return sum(float(e["inspections"]) for e in eps) / max(
            1, sum(int(e["objects"]) for e in eps)
        )

    def y(self, seeds: Sequence[int]) -> np.ndarray:
        """Per-seed accuracy (fraction)."""
        return np.array([float(self.episodes[s]["accuracy"]) for s in seeds])


def _ordered(names, preferred: Sequence[str]) -> list[str]:
    names = set(names)
    return [n for n in preferred if n in names] + sorted(names - set(preferred))


def _runs(episodes: Sequence[Mapping]) -> dict[str, dict[str, _Run]]:
    """``{scene: {policy: _Run}}``; ValueError on a missing key or a repeated seed."""
    grouped: dict[tuple[str, str], dict[int, Mapping]] = {}
    for i, ep in enumerate(episodes):
        missing = [k for k in _REQUIRED if k not in ep]
        if missing:
            raise ValueError(f"episode {i} lacks {', '.join(missing)}")
        runs = grouped.setdefault((str(ep["scene"]), str(ep["policy"])), {})
        if int(ep["seed"]) in runs:
            raise ValueError(f"two episodes for {ep['scene']}/{ep['policy']}/seed {ep['seed']}")
        runs[int(ep["seed"])] = ep
    out: dict[str, dict[str, _Run]] = {}
    for (scene, policy), eps in grouped.items():
        family, value = split_policy_name(policy)
        out.setdefault(scene, {})[policy] = _Run(policy, family, value, dict(sorted(eps.items())))
    return {s: out[s] for s in _ordered(out, _SCENE_ORDER)}


def _point(run: _Run) -> dict:
    seeds = list(run.episodes)
    mean, low, high = bootstrap_ci(run.y(seeds))
    validated = run.family in CONFIDENCE_FAMILIES and run.value is None
    threshold = run.value
    if validated:
        found = {run.episodes[s].get("threshold") for s in seeds}
        threshold = float(found.pop()) if len(found) == 1 and None not in found else None
    return {
        "policy": run.policy,
        "threshold": threshold,
        "validated": validated,
        "inspections_per_object": run.x(seeds),
        "accuracy_mean": mean,
        "ci_low": low,
        "ci_high": high,
        "n": len(seeds),
    }


def _line(runs: Sequence[_Run], seeds: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """Increasing x (pooled over ``seeds``) and (k, n_seeds) accuracies; equal x averaged."""
    xs = np.array([r.x(seeds) for r in runs])
    ys = np.array([r.y(seeds) for r in runs])
    ux, inverse = np.unique(xs, return_inverse=True)
    uy = np.array([ys[inverse == j].mean(axis=0) for j in range(ux.size)])
    return ux, uy


def _per_seed(fam: Sequence[_Run], rand: Sequence[_Run]) -> dict:
    """``{"per_seed": {seed: score}, "x_range": (lo, hi), "line": (x, (k, n) y), "n": seeds,
    "note": None}``; without a score, ``per_seed`` None and ``note`` says why (see the module
    docstring)."""
    out = {"per_seed": None, "x_range": None, "line": None, "n": 0, "note": None}
    sweep = [r for r in fam if r.value is not None]  # the validated run is not on the sweep
    # the family at 0 and 1 inspects nothing / everything: random inspection at P = 0 and 1
    ends = {r.value: r for r in sweep if r.value in (0.0, 1.0)}
    line = [*ends.values(), *(r for r in rand if r.value is not None and r.value not in ends)]
    if len(sweep) < 2 or len(line) < 2:
        out["note"] = "needs two or more @T runs and a random-inspection line of two points"
        return out
    seeds = sorted(set.intersection(*(set(r.episodes) for r in (*sweep, *line))))
    out["n"] = len(seeds)
    if not seeds:
        out["note"] = "no seed common to the family's @T runs and the random-inspection line"
        return out
    (xf, yf), (xr, yr) = _line(sweep, seeds), _line(line, seeds)
    lo, hi = max(xf[0], xr[0]), min(xf[-1], xr[-1])
    if not hi > lo:
        out["note"] = "the family's curve and the random-inspection line share no x range"
        return out
    grid = np.unique(np.clip(np.concatenate([xf, xr, [lo, hi]]), lo, hi))
    per_seed = {}
    for j, s in enumerate(seeds):
        d = np.interp(grid, xf, yf[:, j]) - np.interp(grid, xr, yr[:, j])
        per_seed[s] = float(np.sum((d[1:] + d[:-1]) / 2 * np.diff(grid)) / (hi - lo))
    out.update(per_seed=per_seed, x_range=(float(lo), float(hi)), line=(xr, yr))
    return out


def _score(fam: Sequence[_Run], rand: Sequence[_Run], oracle: _Run | None) -> dict:
    """The family's mean gain over the random-inspection line (see the module docstring)."""
    out = dict.fromkeys(("mean", "ci_low", "ci_high", "p_vs_random_inspect", "normalized"))
    out.update(n=0, x_range=None, note=None)
    found = _per_seed(fam, rand)
    out["n"], out["note"] = found["n"], found["note"]
    if found["per_seed"] is None:
        return out
    per_seed, (lo, hi), (xr, yr) = found["per_seed"], found["x_range"], found["line"]
    seeds = list(per_seed)
    out["mean"], out["ci_low"], out["ci_high"] = bootstrap_ci(list(per_seed.values()))
    out["p_vs_random_inspect"] = paired_test(per_seed, dict.fromkeys(seeds, 0.0)).p_value
    out["x_range"] = [lo, hi]
    if oracle is not None:
        both = [j for j, s in enumerate(seeds) if s in oracle.episodes]
        xo = oracle.x([seeds[j] for j in both]) if both else math.nan
        if both and xr[0] <= xo <= xr[-1]:
            yo = oracle.y([seeds[j] for j in both])
            gain = np.mean([yo[i] - np.interp(xo, xr, yr[:, j]) for i, j in enumerate(both)])
            mean = np.mean([per_seed[seeds[j]] for j in both])
            out["normalized"] = float(mean / gain) if gain > 0 else None
    return out


def per_seed_scores(
    curve_data: Mapping, accuracy_per_seed: Mapping
) -> dict[str, dict[str, dict[int, float]]]:
    """Each paired seed's score, recomputed from a run's data files.

    Parameters
    ----------
    curve_data : a run's ``curve.json`` (:func:`curve`): the points' policies and their
        inspections per object.
    accuracy_per_seed : ``{scene: {policy: {seed: accuracy}}}`` (fractions; seeds as str or
        int), the per-seed accuracies kept of the run's episodes.

    Returns
    -------
    ``{scene: {family: {seed: score}}}`` for every confidence family with a score, in accuracy
    points (fractions). Each point's x is pooled over all of its seeds, so the scores equal
    :func:`curve`'s when every run of the curve has the same seeds (as in one
    ``ipbench eval sorting`` run).
    """
    out: dict[str, dict[str, dict[int, float]]] = {}
    for scene, families in curve_data.items():
        accuracy = accuracy_per_seed.get(scene, {})
        runs: dict[str, list[_Run]] = {}
        for family, entry in families.items():
            for point in entry.get("points", []):
                if point["policy"] not in accuracy:
                    continue
                x = float(point["inspections_per_object"])
                episodes = {
                    int(s): {"inspections": x, "objects": 1, "accuracy": float(a)}
                    for s, a in accuracy[point["policy"]].items()
                }
                _, value = split_policy_name(point["policy"])
                runs.setdefault(family, []).append(_Run(point["policy"], family, value, episodes))
        for family in (f for f in CONFIDENCE_FAMILIES if f in runs):
            found = _per_seed(runs[family], runs.get("random-inspect", []))["per_seed"]
            if found is not None:
                out.setdefault(scene, {})[family] = found
    return out


def _position(point: Mapping) -> tuple[float, float]:
    return point["inspections_per_object"], point["threshold"] or 0.0


def curve(episodes: Sequence[Mapping]) -> dict:
    """Accuracy against inspections per object, per scene and policy family.

    Returns
    -------
    dict
        ``{scene: {family: {"points": [...], "score": {...} | None}}}``, families among
        :data:`CONFIDENCE_FAMILIES`, ``random-inspect``, ``oracle-inspect``, ``random``
        (``oracle`` and other policies are not on the curve). A point: ``policy`` (record
        name), ``threshold`` (T, P, the record's validated threshold for the plain name, else
        None), ``validated`` (the plain-name run), ``inspections_per_object`` (total
        inspections / total objects over its seeds), ``accuracy_mean``, ``ci_low``,
        ``ci_high`` (per-seed accuracy, fraction: mean and 95 % bootstrap interval), ``n``
        (its seeds); sorted by ``inspections_per_object``. ``score`` (confidence families
        only, else None): ``mean``, ``ci_low``, ``ci_high`` (accuracy points, fractions, over
        the paired seeds), ``p_vs_random_inspect`` (sign-flip test of the per-seed scores
        against 0), ``normalized`` (score / oracle-inspect's gain, None without it), ``n``
        (paired seeds: those of every @T run and random-inspection point used),
        ``x_range`` (``[lo, hi]`` integrated, inspections per object) and ``note`` (why the
        score is None, else None).
    """
    out: dict[str, dict] = {}
    for scene, runs in _runs(episodes).items():
        by_family: dict[str, list[_Run]] = {}
        for run in runs.values():
            by_family.setdefault(run.family, []).append(run)
        rand, oracle = by_family.get("random-inspect", []), runs.get("oracle-inspect")
        out[scene] = {}
        for family in (f for f in _FAMILIES if f in by_family):
            points = sorted(map(_point, by_family[family]), key=_position)
            score = (
                _score(by_family[family], rand, oracle) if family in CONFIDENCE_FAMILIES else None
            )
            out[scene][family] = {"points": points, "score": score}
    return out


def _counterpart(run: _Run, runs: Mapping[str, _Run]) -> _Run | None:
    """The same loop's no-inspection run: ``<family>@0``, else ``random-inspect@0``."""
    if run.family not in (*CONFIDENCE_FAMILIES, "random-inspect", "oracle-inspect"):
        return None
    for family in (run.family, "random-inspect"):
        for r in runs.values():
            if r.family == family and r.value == 0.0:
                return r
    return None


def _handled(run: _Run, seeds: Sequence[int]) -> np.ndarray:
    """Per seed: objects dropped or left (on the table, in the inspection area, in hand)."""
    return np.array(
        [sum(int(run.episodes[s].get(k, 0)) for k in ("dropped", "left")) for s in seeds]
    )


def decomposition(episodes: Sequence[Mapping]) -> dict:
    """What inspection did to the labels and what the extra handling cost, per policy.

    Only inspect decisions (``kind == "inspect"``) with a known ``true_category`` count:

    - ``fixed``: first label wrong, final label right (objects per episode, mean over seeds);
    - ``broken``: first label right, final label wrong (objects per episode);
    - ``unknown``: inspect decisions whose true category is unknown (per episode);
    - ``lost``: objects lost to the extra handling — mean over the seeds both ran of
      ``dropped + left`` (off the table, or still on it / in the inspection area / in hand at
      the end) minus the same of the no-inspection counterpart (``<family>@0``, else
      ``random-inspect@0``; objects per episode, may be negative), None without one;
      ``lost_baseline`` names it, ``lost_n`` counts the paired seeds.

    Returns ``{scene: {policy: {"fixed", "broken", "unknown", "lost", "lost_baseline",
    "lost_n"}}}`` for every policy of the records.
    """
    out: dict[str, dict] = {}
    for scene, runs in _runs(episodes).items():
        out[scene] = {}
        for policy in _ordered(runs, ()):
            run = runs[policy]
            counts = {"fixed": [], "broken": [], "unknown": []}
            for ep in run.episodes.values():
                decisions = [d for d in ep.get("decisions") or [] if d.get("kind") == "inspect"]
                known = [d for d in decisions if d.get("true_category") is not None]
                first = [d.get("first_label") == d["true_category"] for d in known]
                final = [d.get("label") == d["true_category"] for d in known]
                counts["fixed"].append(sum(not a and b for a, b in zip(first, final, strict=True)))
                counts["broken"].append(sum(a and not b for a, b in zip(first, final, strict=True)))
                counts["unknown"].append(len(decisions) - len(known))
            row = {k: float(np.mean(v)) for k, v in counts.items()}
            base = _counterpart(run, runs)
            seeds = sorted(set(run.episodes) & set(base.episodes)) if base else []
            row["lost"] = (
                float(np.mean(_handled(run, seeds) - _handled(base, seeds))) if seeds else None
            )
            row["lost_baseline"] = base.policy if base else None
            row["lost_n"] = len(seeds)
            out[scene][policy] = row
    return out


def _json_safe(value):
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Mapping):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


def write_curve(episodes: Sequence[Mapping], out_dir: Path) -> dict:
    """Write ``curve.json`` (:func:`curve`, NaN as null) and ``curve.png`` into ``out_dir``.

    Returns ``{"curve", "decomposition", "json", "png", "lines"}``: the two dicts, the two
    paths and the report's markdown lines (:func:`curve_lines`). Raises ``ValueError`` on no
    episodes.
    """
    if not episodes:
        raise ValueError("write_curve needs at least one episode record, got none")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    data, parts = _json_safe(curve(episodes)), _json_safe(decomposition(episodes))
    json_path, png_path = out_dir / "curve.json", out_dir / "curve.png"
    json_path.write_text(json.dumps(data, indent=2, allow_nan=False) + "\n")
    curve_png(png_path, data)
    lines = curve_lines(data, parts)
    return {
        "curve": data,
        "decomposition": parts,
        "json": json_path,
        "png": png_path,
        "lines": lines,
    }
