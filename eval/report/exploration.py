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
"""

from __future__ import annotations

from collections.abc import Sequence

from ipbench.eval.exploration.markdown import markdown_lines
from ipbench.eval.exploration.seed_sets import seed_set_groups_from_records, seed_set_lines
from ipbench.eval.markdown import generated_header, seeds_text
from ipbench.eval.report.runs import DocsReportError, Run

__all__ = [
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
    for run in runs:
        lines += _run_lines(run)
    return "\n".join(lines).rstrip("\n") + "\n"
