"""The exploration results page (``docs/results/exploration.md``) of ``ipbench report docs``.

Per exploration run (:mod:`ipbench.eval.report.runs`), the run's own report, rendered from the
files it keeps: the objects found in the layout of the thesis' Tables 3.2 and 3.3 with the
thesis' figures beside, search efficiency, paired comparisons and recognition against
eccentricity (:func:`~ipbench.eval.exploration.markdown.markdown_lines` of ``summary.json``),
and every comparison on disjoint seed sets
(:func:`~ipbench.eval.exploration.seed_sets.seed_set_lines` of ``seed_sets.json``). Its
headings move one level down under the run's, and its recall figure is copied beside the page
as ``exploration-<run>.png``. What was run (command, environment, cameras, databases) is on
the overview page (:mod:`ipbench.eval.report.index`).

Runs that ran the same scene, policy and feature type — the same scenes through other cameras
(another resolution, with or without a fovea) or another id — are set side by side first
(:func:`across_runs_lines`): each run's mean over seeds with its own interval, and whether the
seeds are the same.
"""

from __future__ import annotations

from collections.abc import Sequence

from ipbench.eval.exploration.markdown import markdown_lines
from ipbench.eval.exploration.records import FEATURES, POLICY_ORDER, SCENES
from ipbench.eval.exploration.seed_sets import seed_set_groups_from_records, seed_set_lines
from ipbench.eval.markdown import generated_header, seeds_text
from ipbench.eval.report.runs import DocsReportError, Run

__all__ = [
    "across_runs_lines",
    "exploration_command",
    "exploration_figure_name",
    "exploration_items",
    "exploration_page",
]


def exploration_figure_name(run: Run) -> str:
    """The file name of ``run``'s recall figure next to the page (``exploration-<run>.png``)."""
    return "exploration-" + run.name.replace("/", "-") + ".png"


def _config(run: Run) -> dict:
    return (run.json("run.json") or {}).get("config", {})


def exploration_command(run: Run) -> str:
    """The ``ipbench eval exploration`` command line that makes ``run`` (result options only)."""
    config = _config(run)
    parts = ["ipbench eval exploration"]
    if config.get("env_id"):
        parts.append(f"--env {config['env_id']}")
    for option, key in (("--scenes", "scenes"), ("--policies", "policies")):
        parts.append(f"{option} {','.join(config.get(key, []))}")
    parts.append(f"--features {','.join(config.get('features', []))}")
    parts.append(f"--seeds {seeds_text(config.get('seeds', []))[0]}")
    if config.get("head_size"):
        h, w = config["head_size"]
        parts.append(f"--head-size {h}x{w}")
    if config.get("fovea_factor", 1) != 1:
        parts.append(f"--fovea-factor {config['fovea_factor']}")
    parts.append(f"--budget {config.get('saccade_budget', '–')}")
    return " ".join(parts)


def _cameras(config: dict) -> str:
    if not config.get("head_size"):
        return "not recorded"
    h, w = config["head_size"]
    f = config.get("fovea_factor", 1)
    if f == 1:
        return f"each head image {w}x{h} px"
    return (
        f"each eye renders {w}x{h} px, foveated {f}x: the whole field at {w // f}x{h // f} px "
        f"and the central {w // f}x{h // f} px at full resolution"
    )


def exploration_items(run: Run) -> list[str]:
    """What was run, one item per line of the overview page (without the environment's
    status, which the overview adds)."""
    info = run.json("run.json") or {}
    config = _config(run)
    databases = "; ".join(
        f"{feature.upper()}: {d.get('classes', '–')} classes, {d.get('views', '–')} views, "
        f"keypoints per view {d.get('keypoints_per_view_min', '–')} / "
        f"{d.get('keypoints_per_view_median', '–')} / {d.get('keypoints_per_view_max', '–')} "
        "(min / median / max)"
        for feature, d in info.get("databases", {}).items()
    )
    return [
        f"Command: `{exploration_command(run)}`",
        f"Cameras: {_cameras(config)}",
        f"Policy code version: {info.get('policy_version', 'not recorded')} "
        "(`ipbench.policies.exploration`)",
        f"Recognition databases: {databases or 'not recorded'}",
        f"Seeds: {seeds_text(config.get('seeds', []))[1]} in the command; the report covers "
        "every episode in the run's folder, and each table gives its cells' seeds (the same "
        "for every policy: paired)",
        f"Run fingerprint: `{info.get('fingerprint', 'not recorded')}`",
    ]


def _short_cameras(config: dict) -> str:
    if not config.get("head_size"):
        return "cameras not recorded"
    h, w = config["head_size"]
    f = config.get("fovea_factor", 1)
    return f"{w}x{h}" + (f", fovea {f}x" if f != 1 else ", full frame")


def _cell_text(cell: dict) -> str:
    return (
        f"{100 * cell['performance_mean']:.1f} [{100 * cell['ci_low']:.1f}, "
        f"{100 * cell['ci_high']:.1f}] ({cell['n']})"
    )


def _rank(key: tuple[str, str, str]) -> tuple:
    scene, feature, policy = key
    order = [*POLICY_ORDER, policy]
    return (_index(SCENES, scene), _index(FEATURES, feature), order.index(policy), policy)


def _index(names: Sequence[str], name: str) -> int:
    return names.index(name) if name in names else len(names)


def across_runs_lines(runs: Sequence[Run]) -> list[str]:
    """The section setting side by side the runs' cells of the same scene, policy and feature
    type (none: no line), rows in display order (scenes, feature types, policies)."""
    summaries = {run.name: run.json("summary.json") or {} for run in runs}
    keys: dict[tuple[str, str, str], list[str]] = {}
    for name, summary in summaries.items():
        for scene, by_policy in summary.items():
            for policy, by_feature in by_policy.items():
                for feature in by_feature:
                    keys.setdefault((scene, feature, policy), []).append(name)
    shared = {k: v for k, v in keys.items() if len(v) > 1}
    if not shared:
        return []
    names = [r.name for r in runs if any(r.name in v for v in shared.values())]
    configs = {r.name: _config(r) for r in runs}
    lines = ["## Across runs", ""]
    lines += [
        "The same scene, policy and feature type in more than one run: objects found, TP / "
        "(TP + FP + not found) per episode, mean over seeds in % with each run's own 95 % "
        "bootstrap interval and its number of seeds. The runs differ in what their commands "
        "on the [overview](index.md) say (the environment and its cameras); `same seeds` says "
        "whether every run of the row ran the same seeds (scenes then match object for "
        "object). The intervals are not a paired test of the runs.",
        "",
    ]
    head = ["scene", "feature", "policy"]
    head += [
        f"`{n}` ({configs[n].get('env_id', '–')}, {_short_cameras(configs[n])})" for n in names
    ]
    lines += ["| " + " | ".join([*head, "same seeds"]) + " |"]
    lines += ["|" + "---|" * (len(head) + 1)]
    for (scene, feature, policy), with_it in sorted(shared.items(), key=lambda kv: _rank(kv[0])):
        cells = [summaries[n][scene][policy][feature] if n in with_it else None for n in names]
        seeds = {tuple(c.get("seeds", [])) for c in cells if c is not None}
        row = [scene, feature, policy, *("–" if c is None else _cell_text(c) for c in cells)]
        lines.append("| " + " | ".join([*row, "yes" if len(seeds) == 1 else "no"]) + " |")
    return [*lines, ""]


def _demoted(lines: Sequence[str]) -> list[str]:
    return [f"#{line}" if line.startswith("#") else line for line in lines]


def _run_lines(run: Run) -> list[str]:
    summary = run.json("summary.json") or {}
    config = _config(run)
    title = f"`{run.name}`: {config.get('env_id') or 'environment not recorded'}"
    budget = config.get("saccade_budget", 30)
    lines = markdown_lines(summary, budget, title, exploration_figure_name(run))
    if "seed_sets.json" in run.files:
        try:
            groups = seed_set_groups_from_records(run.json("seed_sets.json") or [])
        except (KeyError, TypeError, ValueError) as err:
            raise DocsReportError(
                f"cannot read data/{run.name}/seed_sets.json: {err!r}; regenerate it with "
                "`ipbench eval exploration` on the run's folder (it resumes, running nothing)"
            ) from err
        lines += seed_set_lines(groups)
    return _demoted(lines)


def exploration_page(runs: Sequence[Run]) -> str:
    """The exploration page's markdown for the exploration ``runs``."""
    sources = [s for r in runs for s in r.sources if not s.endswith(".png")]
    lines = generated_header("Results: exploration", sources)
    lines += [
        "Active exploration ([Exploration](../exploration.md)): how many of the database "
        "objects each gaze policy finds, per run. What each run was made with is on the "
        "[overview](index.md).",
        "",
    ]
    if not runs:
        lines += ["None among the results (`ipbench eval exploration`).", ""]
    lines += across_runs_lines(runs)
    for run in runs:
        lines += _run_lines(run)
    return "\n".join(lines).rstrip("\n") + "\n"
