"""The README's headline block of ``ipbench report docs --readme FILE``.

One table, per scene: random sorting, GP-IPM and the oracle's accuracy (mean over seeds with
its 95 % interval), GP-IPM − random paired over seeds, and GP-IPM's gain over random
inspection (the accuracy–inspection curve's score) when a run has one; when the run is one of
several seed sets of its measurement (:mod:`ipbench.eval.report.seed_sets`), the verdict over all
their seeds and each set's score; stamped with the
environment id, the policy code version, the perception key, the threshold, the seeds and the
``ipbench check`` verdict. It replaces the text between :data:`START` and :data:`END` and
nothing else.

The headline run is the sorting run with random and GP-IPM in the most scenes (then: with the
oracle, with a curve score, with the most seeds, first by name), or ``--headline RUN``; the
oracle and the curve score may come from another run of the same environment and seeds (the
block names it).
"""

from __future__ import annotations

from collections.abc import Mapping

from ipbench.eval.markdown import (
    p_phrase,
    percent,
    percent_interval,
    points,
    points_interval,
    seeds_text,
    table,
)
from ipbench.eval.report.markers import replace_marked
from ipbench.eval.report.runs import Discovery, DocsReportError, Run
from ipbench.eval.report.seed_sets import replications, seed_set_groups
from ipbench.eval.report.sorting import curve_figure_name, paired_against_random

__all__ = ["END", "START", "choose_headline", "headline_block", "replace_block", "verdict"]

START = "<!-- results:headline:start -->"
END = "<!-- results:headline:end -->"
_GP, _RANDOM, _ORACLE = "gp-ipm", "random", "oracle"


def _summary(run: Run) -> dict:
    return run.json("summary.json") or {}


def _score(run: Run, scene: str) -> Mapping | None:
    score = ((run.json("curve.json") or {}).get(scene, {}).get(_GP) or {}).get("score")
    return score if score and score.get("mean") is not None else None


def _both(run: Run) -> int:
    return sum(_GP in s and _RANDOM in s for s in _summary(run).values())


def choose_headline(runs: tuple[Run, ...], name: str | None = None) -> Run:
    """The headline run among the sorting ``runs`` (see the module's docstring).

    Raises
    ------
    DocsReportError
        When ``name`` is no sorting run, or no run has random and GP-IPM in a scene.
    """
    names = ", ".join(r.name for r in runs) or "none"
    if name is not None:
        chosen = next((r for r in runs if r.name == name), None)
        if chosen is None:
            raise DocsReportError(f"--headline {name} is not a sorting run; valid: {names}")
        if not _both(chosen):
            raise DocsReportError(f"--headline {name} has no scene with both random and gp-ipm")
        return chosen
    candidates = [r for r in runs if _both(r)]
    if not candidates:
        raise DocsReportError(
            "the README's headline needs a sorting run with both `random` and `gp-ipm` in a "
            f"scene (ipbench eval sorting --policies random,gp-ipm); sorting runs: {names}"
        )

    def rank(run: Run) -> tuple:
        summary = _summary(run)
        seeds = max((p.get("n", 0) for s in summary.values() for p in s.values()), default=0)
        oracle = any(_ORACLE in s for s in summary.values())
        return (_both(run), oracle, any(_score(run, s) for s in summary), seeds)

    return max(candidates, key=rank)


def _same_protocol(a: Run, b: Run) -> bool:
    ca, cb = ((r.json("run.json") or {}).get("config", {}) for r in (a, b))
    env = [c.get("perception", {}).get("dataset", {}).get("env_id") for c in (ca, cb)]
    return env[0] == env[1] and sorted(ca.get("seeds", [])) == sorted(cb.get("seeds", []))


def _from_runs(head: Run, runs: tuple[Run, ...], get) -> tuple[object, Run | None]:
    """``get(run)`` of the headline run, else of the first other run of its protocol."""
    for run in (head, *(r for r in runs if r is not head and _same_protocol(head, r))):
        value = get(run)
        if value is not None:
            return value, run
    return None, None


def _cell(stats: Mapping | None) -> str:
    if stats is None:
        return "–"
    interval = percent_interval(stats.get("ci_low"), stats.get("ci_high"))
    return f"{percent(stats.get('accuracy_mean'))} {interval.removesuffix(' %')}"


def _difference(mean, low, high, p) -> str:
    """``+7.9 [+4.3, +11.4], p = 0.0004`` (percentage points); ``–`` without a mean."""
    if mean is None:
        return "–"
    return f"{points(mean)} {points_interval(low, high)}, {p_phrase(p)}"


def _how_chosen(info: Mapping, classifier: str) -> str:
    if info.get("config", {}).get("threshold") is not None:
        return "set by --threshold"
    v = info.get("validated_thresholds", {}).get(classifier)
    if not v:
        return "not validated"
    return f"validated: {v.get('rule')}, {100 * v.get('target_precision', 0):.0f} %"


def verdict(scores: Mapping[str, Mapping]) -> str:
    """One sentence: per scene, whether inspecting by GP-IPM's confidence pays over inspecting
    blindly at equal effort — where the curve score's 95 % interval lies above 0 (pays), below 0
    (costs), or spans it (no measurable gain). Where the interval excludes 0 but the sign-flip
    p is 0.05 or more (or the other way round), the two tests disagree at the margin, and the
    sentence says so; ``""`` without a score."""
    parts = []
    for scene, sc in scores.items():
        low, high = sc.get("ci_low"), sc.get("ci_high")
        p_val = sc.get("p_vs_random_inspect")
        significant = p_val is not None and p_val < 0.05
        above, below = low is not None and low > 0, high is not None and high < 0
        words = (
            ("pays" if above else "costs")
            if (above or below) and significant
            else "is at the margin of measurable"
            if above or below or significant
            else "gains nothing measurable"
        )
        interval = f"{points(sc.get('mean'))} points {points_interval(low, high)}"
        p = p_phrase(sc.get("p_vs_random_inspect"))
        parts.append(f"in the {scene} scene it {words} ({interval}, {p})")
    if not parts:
        return ""
    return (
        "Inspecting the objects GP-IPM is least sure of, rather than a random choice of as many: "
        + "; ".join(parts)
        + "."
    )


def _seed_set_sentences(head: Run, runs: tuple[Run, ...]) -> list[str]:
    """When ``head`` is one of several seed sets of its measurement: the verdict over all their
    seeds, and each set's score with how far apart the sets land (a paragraph), else none."""
    group = next((g for g in seed_set_groups(runs) if head in g), None)
    rows = [r for r in replications(group) if r.quantity == f"{_GP} score"] if group else []
    if not rows:
        return []
    pooled = {
        r.scene: {
            "mean": r.pooled.mean,
            "ci_low": r.pooled.ci_low,
            "ci_high": r.pooled.ci_high,
            "p_vs_random_inspect": r.pooled_p,
        }
        for r in rows
    }
    n = len(rows[0].pooled.seeds)
    sets = "; ".join(
        f"{r.scene}: "
        + ", ".join(
            f"{points(e.mean)} {points_interval(e.ci_low, e.ci_high)} on seeds "
            f"{seeds_text(e.seeds)[1].split(' (')[0]}"
            for e in r.sets
        )
        + f", {points(r.gap.mean_diff)} points apart {points_interval(r.gap.ci_low, r.gap.ci_high)}"
        for r in rows
    )
    runs_named = ", ".join(f"`{run.name}`" for run in group)
    return [
        f"Over all {n} seeds of the seed sets {runs_named}: "
        + verdict(pooled)[0].lower()
        + verdict(pooled)[1:]
        + f" Each set's score — {sets}.",
        "",
    ]


def _stamp(head: Run, found: Discovery, others: list[str], link: str) -> str:
    info = head.json("run.json") or {}
    config = info.get("config", {})
    env = config.get("perception", {}).get("dataset", {}).get("env_id", "env not recorded")
    thresholds = [
        f"{classifier} {value:g} ({_how_chosen(info, classifier)})"
        for classifier, value in info.get("thresholds", {}).items()
    ]
    verdict = found.check.report.get("verdict") if found.check else "no check report"
    return (
        "Objects sorted into their own bin, mean over seeds with its 95 % bootstrap interval; "
        "GP-IPM − random: per-seed differences over the same seeds in percentage points, with "
        "the sign-flip p. "
        f"`{env}`, policy version {info.get('policy_version', '–')}, "
        + (f"dataset version {info['dataset_version']}, " if "dataset_version" in info else "")
        + f"perception key `{info.get('perception_key', '–')}`, inspection threshold "
        f"{', '.join(thresholds) or 'none'}, seeds {seeds_text(config.get('seeds', []))[1]}, "
        f"`ipbench check`: {verdict}. Run `{head.name}`"
        + "".join(others)
        + f"; details in [Results]({link})."
    )


def headline_block(found: Discovery, link: str, name: str | None = None) -> str:
    """The block's markdown (ends with a newline); ``link``: the results overview's path
    relative to the README. Raises :class:`DocsReportError` as :func:`choose_headline`."""
    runs = found.of_kind("sorting")
    head = choose_headline(runs, name)
    paired = paired_against_random(head)
    summary = _summary(head)
    rows, sources, scores = [], {}, {}
    scenes = [s for s, by in summary.items() if _GP in by and _RANDOM in by]
    for scene in scenes:
        by_policy = summary[scene]
        oracle, o_run = _from_runs(
            head, runs, lambda r, s=scene: _summary(r).get(s, {}).get(_ORACLE)
        )
        score, s_run = _from_runs(head, runs, lambda r, s=scene: _score(r, s))
        for what, run in (("the oracle", o_run), ("the curve score", s_run)):
            if run is not None and run is not head:
                sources.setdefault(what, run.name)
        test = paired.get(scene, {}).get(_GP)
        diff = (
            "–"
            if test is None
            else _difference(test.mean_diff, test.ci_low, test.ci_high, test.p_value)
        )
        if score:
            scores[scene] = score
        score = score or {}
        gain = _difference(
            score.get("mean"),
            score.get("ci_low"),
            score.get("ci_high"),
            score.get("p_vs_random_inspect"),
        )
        rows.append(
            [scene, _cell(by_policy[_RANDOM]), _cell(by_policy[_GP]), _cell(oracle), diff, gain]
        )
    head_cells = ["scene", "random", "GP-IPM", "oracle", "GP-IPM − random (points)"]
    head_cells.append("GP-IPM gain over random inspection (points)")
    if all(r[-1] == "–" for r in rows):
        head_cells, rows = head_cells[:-1], [r[:-1] for r in rows]
    others = [f"; {what} from run `{run}`" for what, run in sources.items()]
    lines = [
        f"<!-- generated by `ipbench report docs` from the run `{head.name}`: do not edit by "
        "hand -->",
        "",
    ]
    if scores and sources.get("the curve score") is None and "curve.png" in head.files:
        figure = link.rsplit("/", 1)[0] + "/" + curve_figure_name(head) if "/" in link else ""
        lines += [f"![accuracy against inspections per object, run {head.name}]({figure})", ""]
    sets = _seed_set_sentences(head, runs)  # the verdict over every seed set replaces the run's
    sentence = verdict(scores)
    lines += [*table(head_cells, rows), "", *(sets or ([sentence, ""] if sentence else []))]
    lines.append(_stamp(head, found, others, link))
    return "\n".join(lines) + "\n"


def replace_block(text: str, block: str, where: str = "README.md") -> str:
    """``text`` with the lines between :data:`START` and :data:`END` replaced by ``block``;
    everything else, the markers and the line endings kept.

    Raises
    ------
    DocsReportError
        When the markers are missing, repeated or out of order, saying which to add.
    """
    return replace_marked(text, block, START, END, where, "headline")
