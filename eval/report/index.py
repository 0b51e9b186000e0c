"""The overview results page (``docs/results/index.md``) of ``ipbench report docs``: what was
run and on what.

For each run (:mod:`ipbench.eval.report.runs`): the command line that makes it, the environment
id (and whether it was released when the run was made), the policy code version, the
perception dataset and model keys (sorting), the cameras and recognition databases
(exploration), the inspection thresholds and how they were chosen, the seeds (for a
calibration run: the seeds, the simulated cell and the intervals' confidence); and, when
``--from`` holds an ``ipbench check --json`` report, its verdict and the platform it records.
"""

from __future__ import annotations

from collections.abc import Mapping

from ipbench.eval.markdown import generated_header, seeds_text, table
from ipbench.eval.report.calibration_data import (
    calibration_command,
    confidence_text,
    robot_text,
    seeds_prose,
)
from ipbench.eval.report.exploration import exploration_items
from ipbench.eval.report.perception import perception_command
from ipbench.eval.report.runs import CheckFile, Discovery, Run
from ipbench.eval.report.sorting import sorting_command

__all__ = ["RULES", "index_page", "threshold_text"]

RULES: dict[str, str] = {
    "logistic-precision": "the lowest of 0, 0.05, …, 1 at which the labels left uninspected "
    "are right with a fitted probability (logistic calibration of confidence) of at least "
    "{target}",
}
"""How each threshold rule (``run.json``'s ``validated_thresholds[*].rule``) chooses, in words;
``{target}`` is its target accuracy."""
_PLATFORM_KEYS = (
    "cpu", "cores", "machine", "system", "libc", "python", "ipbench", "numpy", "scipy",
    "mujoco", "opencv", "numba", "open3d", "scikit-learn", "gymnasium", "blas", "gl",
)  # fmt: skip


def _text(value) -> str:
    if isinstance(value, list | tuple):
        return "; ".join(map(str, value))
    return str(value)


def threshold_text(run: Mapping) -> str:
    """The classifiers' inspection thresholds of ``run.json`` and how they were chosen."""
    config = run.get("config", {})
    validated = run.get("validated_thresholds", {})
    parts = []
    for classifier, value in run.get("thresholds", {}).items():
        v = validated.get(classifier)
        if config.get("threshold") is not None:
            how = "set by `--threshold`" + (
                f" (the validated one: {v['threshold']:g})" if v else ""
            )
        elif v:
            target = f"{100 * v.get('target_precision', float('nan')):.0f} %"
            rule = RULES.get(v.get("rule"), "rule `{rule}`").format(
                target=target, rule=v.get("rule")
            )
            how = (
                f"validated by rule `{v.get('rule')}`: {rule}; on {v.get('decisions')} decisions, "
                f"{v.get('data')}"
            )
        else:
            how = "not validated"
        parts.append(f"{classifier} {value:g}, {how}")
    return "; ".join(parts) or "none (no confidence-driven policy)"


_UNDER_DEVELOPMENT = {
    "under development": " (under development when the run was made: its behaviour may still "
    "change until its release, so these figures are not the released id's)"
}


def _sorting_items(run: Run) -> list[str]:
    info = run.json("run.json") or {}
    config = info.get("config", {})
    perception = config.get("perception", {})
    keys = ", ".join(f"{k} `{v}`" for k, v in info.get("model_keys", {}).items() if v)
    fixed = [p for p in config.get("policies", []) if "@" in p]
    items = [
        f"Command: `{sorting_command(run)}`",
        f"Environment: `{perception.get('dataset', {}).get('env_id', 'not recorded')}`"
        + _UNDER_DEVELOPMENT.get(info.get("env_status"), ""),
        f"Policy code version: {info.get('policy_version', 'not recorded')} "
        "(`ipbench.policies.POLICY_VERSION`)",
        f"Scenes: {', '.join(config.get('scenes', []))}; policies: "
        + ", ".join(f"`{p}`" for p in config.get("policies", [])),
        f"Test seeds: {seeds_text(config.get('seeds', []))[1]}, the same for every policy "
        "(paired); thresholds validated on the first views of seeds "
        f"{seeds_text(config.get('validation_seeds', []))[1]}",
        f"Perception: key `{info.get('perception_key', 'not recorded')}`; trained models: "
        f"{keys or 'none'}; classifiers compared when trained: "
        + ", ".join(perception.get("classifiers", [])),
        f"Inspection thresholds: {threshold_text(info)}"
        + (f"; the `@T` policies ({', '.join(fixed)}) run at their own T" if fixed else ""),
        f"Views fused per inspected object: {config.get('n_views', '–')} "
        f"({config.get('fusion', '–')}); camera extrinsics: {config.get('extrinsics', '–')}; "
        f"step limit: {config.get('steps_per_object', '–')} steps per object + 10",
        f"Run fingerprint: `{info.get('fingerprint', 'not recorded')}`",
    ]
    return items


def _exploration_run_items(run: Run) -> list[str]:
    info = run.json("run.json") or {}
    env = info.get("env", "not recorded")
    status = _UNDER_DEVELOPMENT.get(info.get("env_status"), "")
    command, *rest = exploration_items(run)
    return [command, f"Environment: `{env}`{status}", *rest]


def _perception_items(run: Run) -> list[str]:
    metrics = run.json("metrics.json") or {}
    dataset = (run.json("dataset.json") or {}).get("dataset_key", "not recorded")
    return [
        f"Command: `{perception_command(run)}` (the environment is not recorded in metrics.json)",
        f"Dataset key: `{dataset}`",
        "Class subsets: " + ", ".join(k for k in ("5class", "3class") if k in metrics),
        "Ablations: "
        + (", ".join(k for k in ("ablation", "in_hand_ablation") if metrics.get(k)) or "none"),
    ]


def _calibration_items(run: Run) -> list[str]:
    metrics = run.json("metrics.json") or {}
    return [
        f"Command: `{calibration_command(metrics)}`",
        f"Seeds: {seeds_prose(metrics)}; simulated in {robot_text(metrics)}",
        f"Intervals: bootstrap intervals of the mean over seeds at {confidence_text(metrics)}",
    ]


def _run_lines(run: Run, items: list[str], page: str) -> list[str]:
    data = ", ".join(f"[`{s.split('/')[-1]}`]({s})" for s in run.sources)
    return [
        f"### `{run.name}`",
        "",
        *(f"- {item}" for item in items),
        f"- Results: [{page}]({page}.md); data: {data}",
        "",
    ]


def _check_lines(check: CheckFile | None) -> list[str]:
    lines = ["## Platform and reproducibility", ""]
    if check is None:
        return lines + [
            "No `ipbench check` report among the results: the platform is not recorded. Run "
            "`ipbench check --json RESULTS/check.json` on the machine of the runs and "
            "regenerate.",
            "",
        ]
    report = check.report
    statuses: dict[str, list[str]] = {}
    for name, stage in report.get("stages", {}).items():
        statuses.setdefault(stage.get("status", "?"), []).append(name)
    stages = "; ".join(f"{s}: {', '.join(names)}" for s, names in statuses.items())
    complete = "" if report.get("complete", True) else " (only some stages were run)"
    lines += [
        f"`ipbench check` verdict: **{report.get('verdict')}**{complete}: "
        f"{report.get('meaning', '')}. Stages {stages}. Report: [`{check.name}`]({check.source}).",
        "",
    ]
    platform = report.get("platform", {})
    rows = [[k, _text(platform[k])] for k in _PLATFORM_KEYS if k in platform]
    if rows:
        lines += ["The platform the check ran on:", "", *table(["component", "value"], rows), ""]
    diffs = report.get("platform_differences", {})
    if diffs:
        rows = [[k, _text(v.get("here")), _text(v.get("reference"))] for k, v in diffs.items()]
        head = ["differs from the reference in", "here", "reference"]
        lines += [*table(head, rows), ""]
    return lines


def index_page(found: Discovery) -> str:
    """The overview page's markdown."""
    sources = [s for r in found.runs for s in r.sources if s.endswith("run.json")]
    sources += [f"data/{r.name}/metrics.json" for r in found.of_kind("perception")]
    sources += [f"data/{r.name}/metrics.json" for r in found.of_kind("calibration")]
    if found.check is not None:
        sources.append(found.check.source)
    lines = generated_header("Results", sources)
    lines += [
        "What was run, with what, and on what platform; the numbers are on the pages "
        "[Sorting](sorting.md), [Exploration](exploration.md), [Perception](perception.md) and "
        "[Calibration](calibration.md). "
        "Every page is generated from the results files, whose copies are kept beside them in "
        "`data/`.",
        "",
        *_check_lines(found.check),
    ]
    for kind, title, items in (
        ("sorting", "Sorting runs", _sorting_items),
        ("exploration", "Exploration runs", _exploration_run_items),
        ("perception", "Perception runs", _perception_items),
        ("calibration", "Calibration runs", _calibration_items),
    ):
        runs = found.of_kind(kind)
        lines += [f"## {title}", ""]
        if not runs:
            what = f"{kind} --seeds A:B" if kind == "calibration" else kind
            lines += [f"None among the results (`ipbench eval {what}`).", ""]
        for run in runs:
            lines += _run_lines(run, items(run), kind)
    return "\n".join(lines).rstrip("\n") + "\n"
