"""The sorting results page (``docs/results/sorting.md``) of ``ipbench report docs``.

Per sorting run (:mod:`ipbench.eval.report.runs`): accuracy per scene and policy as
``summary.json`` records it (mean over seeds, 95 % bootstrap interval, seeds), the paired
differences against random sorting (the run report's test, :func:`ipbench.eval.stats.
paired_test`, on the per-seed accuracies kept in ``accuracy_per_seed.json``), and, when the
run has a ``curve.json``, the accuracy–inspection curve and each confidence family's score
with its interval and p, beside the curve figure (copied next to the page); then runs that
are seed sets of one measurement side by side (:mod:`ipbench.eval.report.seed_sets`).
"""

from __future__ import annotations

from collections.abc import Mapping

from ipbench.eval.markdown import (
    generated_header,
    number,
    p_value,
    percent,
    percent_interval,
    points,
    points_interval,
    seeds_text,
    table,
)
from ipbench.eval.report.runs import Run
from ipbench.eval.report.seed_sets import seed_set_lines
from ipbench.eval.stats import PairedTest, paired_test

__all__ = ["curve_figure_name", "paired_against_random", "sorting_command", "sorting_page"]

_ACCURACY_HOW_TO_READ = (
    "Objects sorted into their own bin. `mean` is the mean over seeds of the per-episode "
    "accuracy, `95 % CI` its percentile bootstrap interval (10,000 resamples of the seeds) "
    "and `seeds` the episodes per cell, as the run's `summary.json` records them; `objects` "
    "pools every episode. `thesis` is the total of the thesis' Table 5.1 (one run on the real "
    "robot per scene), where it has one."
)
_PAIRED_HOW_TO_READ = (
    "Each policy's per-seed accuracy minus random sorting's on the same seeds (the same scenes "
    "and objects), in percentage points: the mean, its 95 % bootstrap interval and the "
    "two-sided sign-flip permutation p (exact up to 16 pairs, else 100,000 random sign "
    "flips); the run report's test, on the per-seed accuracies of `accuracy_per_seed.json`."
)
_CURVE_HOW_TO_READ = (
    "x: inspections per object, pooled over seeds; accuracy: mean over seeds with its 95 % "
    "bootstrap interval. `threshold` is T of `<family>@T` (the validated T for the plain "
    "name) or P of `random-inspect@P`. A family's gain over random inspection is the area "
    "between its curve (its `@T` runs) and the random-inspection line divided by the range of "
    "inspections per object both cover: the mean accuracy gain at equal inspection effort, in "
    "percentage points, with its 95 % bootstrap interval and sign-flip p over the paired seeds."
)


def curve_figure_name(run: Run) -> str:
    """The file name of ``run``'s curve figure next to the page (``curve-<run>.png``)."""
    return "curve-" + run.name.replace("/", "-") + ".png"


def sorting_command(run: Run) -> str:
    """The ``ipbench eval sorting`` command line that makes ``run`` (result options only)."""
    info = run.json("run.json") or {}
    config = info.get("config", {})
    env = config.get("perception", {}).get("dataset", {}).get("env_id")
    parts = ["ipbench eval sorting"]
    if env:
        parts.append(f"--env {env}")
    parts.append(f"--scenes {','.join(config.get('scenes', []))}")
    parts.append(f"--policies {','.join(config.get('policies', []))}")
    parts.append(f"--seeds {seeds_text(config.get('seeds', []))[0]}")
    if config.get("threshold") is not None:
        parts.append(f"--threshold {config['threshold']:g}")
    if config.get("fusion", "majority") != "majority":
        parts.append(f"--fusion {config['fusion']}")
    if config.get("extrinsics", "true") != "true":
        parts.append(f"--extrinsics {config['extrinsics']}")
        if config.get("calibration"):
            parts.append(f"--calibration {config['calibration']}")
        parts.append(f"--robot-seed {config.get('robot_seed', 0)}")
    return " ".join(parts)


def paired_against_random(run: Run) -> dict[str, dict[str, PairedTest]]:
    """``{scene: {policy: test of policy - random}}`` over the seeds both ran, for every
    policy of scenes where random sorting ran (none without ``accuracy_per_seed.json``)."""
    per_seed = run.json("accuracy_per_seed.json") or {}
    summary = run.json("summary.json") or {}
    out: dict[str, dict[str, PairedTest]] = {}
    for scene, by_policy in per_seed.items():
        if "random" not in by_policy:
            continue
        base = {int(s): float(a) for s, a in by_policy["random"].items()}
        order = [p for p in summary.get(scene, by_policy) if p in by_policy and p != "random"]
        for policy in order:
            values = {int(s): float(a) for s, a in by_policy[policy].items()}
            out.setdefault(scene, {})[policy] = paired_test(values, base)
    return out


def _thesis(scene: str, policy: str) -> str:
    from ipbench.eval.sorting.report import THESIS_TABLE_5_1

    ref = THESIS_TABLE_5_1.get(scene, {}).get(policy)
    return "–" if ref is None else f"{ref.correct}/{ref.total} ({ref.percent:.0f} %)"


def _accuracy_lines(summary: Mapping) -> list[str]:
    rows = []
    for scene, by_policy in summary.items():
        for policy, s in by_policy.items():
            rows.append(
                [
                    scene,
                    f"`{policy}`",
                    percent(s.get("accuracy_mean")),
                    percent_interval(s.get("ci_low"), s.get("ci_high")),
                    str(s.get("n", "–")),
                    f"{s.get('correct', '–')}/{s.get('objects', '–')}",
                    number(s.get("inspections_per_object"), 3),
                    _thesis(scene, policy),
                ]
            )
    head = ["scene", "policy", "mean", "95 % CI", "seeds", "objects", "inspections / object"]
    return ["### Accuracy", "", _ACCURACY_HOW_TO_READ, "", *table([*head, "thesis"], rows), ""]


def _paired_lines(run: Run) -> list[str]:
    tests = paired_against_random(run)
    if not tests:
        reason = (
            "no random sorting to compare with"
            if "accuracy_per_seed.json" in run.files
            else "the run has no per-seed accuracies (episodes.jsonl)"
        )
        return ["### Paired differences against random", "", f"None: {reason}.", ""]
    rows = [
        [
            scene,
            f"`{policy}` − `random`",
            points(t.mean_diff),
            points_interval(t.ci_low, t.ci_high),
            p_value(t.p_value),
            str(t.n),
        ]
        for scene, by_policy in tests.items()
        for policy, t in by_policy.items()
    ]
    head = ["scene", "difference", "points", "95 % CI", "p", "paired seeds"]
    return [
        "### Paired differences against random",
        "",
        _PAIRED_HOW_TO_READ,
        "",
        *table(head, rows),
        "",
    ]


def _score_row(scene: str, family: str, s: Mapping) -> list[str]:
    if s.get("mean") is None:
        return [scene, f"`{family}`", f"not computed: {s.get('note') or 'no score'}", *["–"] * 5]
    lo, hi = s.get("x_range") or (None, None)
    normalized = s.get("normalized")
    return [
        scene,
        f"`{family}`",
        points(s["mean"]),
        points_interval(s.get("ci_low"), s.get("ci_high")),
        p_value(s.get("p_vs_random_inspect")),
        str(s.get("n", "–")),
        f"{number(lo)}–{number(hi)}",
        "–" if normalized is None else f"{100 * normalized:.0f} %",
    ]


def _curve_lines(run: Run) -> list[str]:
    curve = run.json("curve.json")
    if not curve:
        return []
    lines = ["### Accuracy against inspection effort", "", _CURVE_HOW_TO_READ, ""]
    head = ["family", "policy", "threshold", "inspections / object", "accuracy", "95 % CI"]
    scores = []
    for scene, families in curve.items():
        rows = []
        for family, entry in families.items():
            for p in entry.get("points", []):
                t = p.get("threshold")
                rows.append(
                    [
                        family,
                        f"`{p['policy']}`",
                        "–" if t is None else f"{t:g}",
                        number(p.get("inspections_per_object")),
                        percent(p.get("accuracy_mean")),
                        percent_interval(p.get("ci_low"), p.get("ci_high")),
                        str(p.get("n", "–")),
                    ]
                )
            if entry.get("score") is not None:
                scores.append(_score_row(scene, family, entry["score"]))
        lines += [f"#### {scene}", "", *table([*head, "seeds"], rows), ""]
    if scores:
        head = ["scene", "family", "gain over random inspection (points)", "95 % CI", "p"]
        head += ["paired seeds", "inspections / object", "share of oracle-inspect's gain"]
        lines += ["#### Score: gain over random inspection", "", *table(head, scores), ""]
    if "curve.png" in run.files:
        name = curve_figure_name(run)
        lines += [f"![accuracy against inspections per object, run {run.name}]({name})", ""]
    return lines


def _run_lines(run: Run) -> list[str]:
    summary = run.json("summary.json") or {}
    return [
        f"## Run `{run.name}`",
        "",
        f"`{sorting_command(run)}`; what else defines the run (environment, policy version, "
        "perception models, thresholds) is in the [overview](index.md).",
        "",
        *_accuracy_lines(summary),
        *_paired_lines(run),
        *_curve_lines(run),
    ]


def sorting_page(runs: tuple[Run, ...]) -> str:
    """The page's markdown: every sorting run in name order (a note when there is none)."""
    sources = [s for r in runs for s in r.sources if not s.endswith(".png")]
    lines = generated_header("Results: sorting", sources)
    if not runs:
        lines += ["No sorting run among the results (`ipbench eval sorting`).", ""]
    for run in runs:
        lines += _run_lines(run)
    lines += seed_set_lines(runs)
    return "\n".join(lines).rstrip("\n") + "\n"
