"""The calibration results page (``docs/results/calibration.md``) of ``ipbench report docs``.

Per multi-seed calibration run (``ipbench eval calibration --seeds A:B``,
:mod:`ipbench.eval.report.calibration_data`), from its ``metrics.json``: the reconstruction of
the 24 mm board by the head and the wrist camera beside the thesis' figures, how often the
head's dynamic update fell back to the encoders, the paired differences between methods, the
cell's self-calibration (nominal against calibrated hand-eye ``X``) and the hand-eye methods'
errors, each a mean over seeds with its bootstrap interval; and the run's spread figure when
it has one (copied next to the page). Several runs are shown one after the other, by name.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

from ipbench.eval.markdown import generated_header, p_value, table
from ipbench.eval.report.calibration_data import (
    FIGURE,
    RECONSTRUCTION_ROWS,
    calibration_command,
    confidence_text,
    distribution,
    interval_text,
    median_text,
    n_text,
    rate_text,
    robot_text,
    seeds_prose,
    thesis_text,
)
from ipbench.eval.report.runs import Run

__all__ = ["calibration_figure_name", "calibration_page", "comparison_name"]

_RECONSTRUCTION_HOW_TO_READ = (
    "RMSE in mm, per seed over its trials, then the mean over seeds with its {confidence} "
    "bootstrap interval, the median and the seeds that gave a value. Head rows: distances "
    "between adjacent corners of the board triangulated by the stereo head after a gaze change, "
    "against 24 mm, with the cameras' true poses, the calibrated poses carried by the encoders "
    "(nominal pan-tilt kinematics), and the dynamic update from the images (thesis §4.4.4), with "
    "and without its consistency check. Wrist rows: the wrist camera's depth, as board shape, "
    "and the corners carried into the robot frame by the calibrated or the nominal hand-eye X "
    "against their true positions. `thesis`: the thesis' figure (Table 4.3: the head; Table "
    "4.4: the Xtion in the robot frame, measured on a real arm)."
)
_COMPARISON_HOW_TO_READ = (
    "Paired over seeds: per seed, the first minus the second; the mean difference with its "
    "{confidence} bootstrap interval and the two-sided paired permutation p (a mean of 0)."
)
_SELF_HOW_TO_READ = (
    "The error of each camera's hand-eye X against the truth, before (`nominal`: the nominal "
    "model's camera mount) and after (`calibrated`) the cell calibrates itself: mean over seeds "
    "with its {confidence} bootstrap interval."
)
_HAND_EYE_HOW_TO_READ = (
    "The error of each hand-eye method's X against the truth, per camera: mean over seeds with "
    "its {confidence} bootstrap interval."
)
_NAMED = {
    "head_dynamic_minus_encoders_rmse_mm": ("head RMSE: dynamic update − encoders", "mm", 3),
    "head_dynamic_minus_true_rmse_mm": ("head RMSE: dynamic update − true extrinsics", "mm", 3),
    "head_encoders_minus_true_rmse_mm": ("head RMSE: encoders − true extrinsics", "mm", 3),
    "wrist_robot_calibrated_minus_nominal_rmse_mm": (
        "wrist RMSE in robot frame: calibrated X − nominal X",
        "mm",
        2,
    ),
}
_CAMERA_X = re.compile(r"(?P<camera>.+)_calibrated_minus_nominal_(?P<what>translation|rotation)_")


def calibration_figure_name(run: Run) -> str:
    """The file name of ``run``'s spread figure next to the page (``calibration-<run>.png``)."""
    return "calibration-" + run.name.replace("/", "-") + ".png"


def comparison_name(key: str) -> tuple[str, str, int]:
    """A ``comparisons`` key in words, with its unit and decimals:
    ``head_dynamic_minus_encoders_rmse_mm`` -> ``("head RMSE: dynamic update − encoders",
    "mm", 3)``; a key of no known form is shown as it is."""
    if key in _NAMED:
        return _NAMED[key]
    unit, digits = ("°", 3) if key.endswith("_deg") else ("mm", 2)
    found = _CAMERA_X.match(key)
    if found:
        return f"{found['camera']} X {found['what']} error: calibrated − nominal", unit, digits
    return f"`{key}`", unit if key.endswith(("_deg", "_mm")) else "", 3


def _section(title: str, how: str, conf: str, head: list[str], rows: list[list[str]]) -> list[str]:
    if not rows:
        return []
    return [f"### {title}", "", how.format(confidence=conf), "", *table(head, rows), ""]


def _reconstruction_lines(metrics: Mapping, conf: str) -> list[str]:
    rows = []
    for row in RECONSTRUCTION_ROWS:
        d = distribution(metrics, "reconstruction", row.key)
        rows.append(
            [
                row.label,
                interval_text(d, row.digits),
                median_text(d, row.digits),
                n_text(d),
                thesis_text(metrics, row),
            ]
        )
    head = ["reconstruction", f"RMSE (mm), mean [{conf} interval]", "median", "seeds", "thesis"]
    title = "Reconstruction of the 24 mm board (thesis Tables 4.2–4.5)"
    lines = _section(title, _RECONSTRUCTION_HOW_TO_READ, conf, head, rows)
    rate = rate_text(distribution(metrics, "reconstruction", "head_fallback_rate"))
    if rate == "–":
        return lines + ["The run does not record how often the consistency check fell back.", ""]

    def rate_of(key: str) -> str:
        return rate_text(distribution(metrics, "reconstruction", key))

    return lines + [
        "The dynamic update's consistency check fell back to the encoders in "
        f"{rate} of trials (mean over seeds of each seed's rate, with its {conf} interval); "
        f"the update itself failed, for want of stable features, in "
        f"{rate_of('head_update_failure_rate')}. Against the truth, the update was worse than "
        f"the encoders on the scored board in {rate_of('head_unchecked_worse_rate')} of the "
        f"trials it succeeded in, and the checked update in "
        f"{rate_of('head_dynamic_worse_rate')} of all trials.",
        "",
        *_floor_lines(metrics.get("head_floor")),
    ]


def _floor_lines(floor) -> list[str]:
    """What the floor (the true cameras' per-trial RMSE) depends on, when the run says."""
    if not isinstance(floor, Mapping):
        return []
    d, i = floor["board_distance_m"], floor["incidence_deg"]
    return [
        f"The floor, per trial ({floor['trials']} trials, the true cameras): median "
        f"{floor['median_rmse_mm']:.3f} mm, 90th percentile {floor['p90_rmse_mm']:.3f} mm; "
        f"Spearman rank correlation with the scored board's incidence angle "
        f"({i['min']:.0f}–{i['max']:.0f}°) {i['spearman_rho']:+.2f} (p {i['p_value']:.2g}), "
        f"with its distance ({d['min']:.2f}–{d['max']:.2f} m) {d['spearman_rho']:+.2f} "
        f"(p {d['p_value']:.2g}).",
        "",
    ]


def _comparison_lines(metrics: Mapping, conf: str) -> list[str]:
    comparisons = metrics.get("comparisons")
    rows = []
    for key, d in (comparisons if isinstance(comparisons, Mapping) else {}).items():
        name, unit, digits = comparison_name(key)
        d = d if isinstance(d, Mapping) else None
        p = p_value((d or {}).get("p_value"))
        rows.append([name, unit, interval_text(d, digits, signed=True), p, n_text(d)])
    head = ["difference", "unit", f"mean [{conf} interval]", "p", "seeds"]
    return _section("Paired comparisons", _COMPARISON_HOW_TO_READ, conf, head, rows)


def _cameras(metrics: Mapping, key: str) -> list[tuple[str, Mapping]]:
    value = metrics.get(key)
    items = value.items() if isinstance(value, Mapping) else ()
    return [(camera, entry) for camera, entry in items if isinstance(entry, Mapping)]


def _self_calibration_lines(metrics: Mapping, conf: str) -> list[str]:
    rows = [
        [
            camera,
            *(
                interval_text(distribution(entry, when, what), digits)
                for what, digits in (("rotation_deg", 3), ("translation_mm", 2))
                for when in ("nominal", "calibrated")
            ),
        ]
        for camera, entry in _cameras(metrics, "self_calibration")
    ]
    head = ["camera", "rotation (°), nominal", "rotation (°), calibrated"]
    head += ["translation (mm), nominal", "translation (mm), calibrated"]
    return _section("Self-calibration of the cell", _SELF_HOW_TO_READ, conf, head, rows)


def _hand_eye_lines(metrics: Mapping, conf: str) -> list[str]:
    rows = [
        [
            camera,
            f"`{method}`",
            interval_text(distribution(errors, "rotation_deg"), 3),
            interval_text(distribution(errors, "translation_mm"), 2),
            n_text(distribution(errors, "translation_mm")),
        ]
        for camera, by_method in _cameras(metrics, "hand_eye")
        for method, errors in by_method.items()
        if isinstance(errors, Mapping)
    ]
    head = ["camera", "method", "rotation (°)", "translation (mm)", "seeds"]
    return _section("Hand-eye methods", _HAND_EYE_HOW_TO_READ, conf, head, rows)


def _run_lines(run: Run) -> list[str]:
    metrics = run.json("metrics.json") or {}
    conf = confidence_text(metrics)
    lines = [
        f"## Run `{run.name}`",
        "",
        f"`{calibration_command(metrics)}`: seeds {seeds_prose(metrics)}, in "
        f"{robot_text(metrics)}; intervals at {conf} confidence. What else was run is in the "
        "[overview](index.md).",
        "",
        *_reconstruction_lines(metrics, conf),
        *_comparison_lines(metrics, conf),
        *_self_calibration_lines(metrics, conf),
        *_hand_eye_lines(metrics, conf),
    ]
    if FIGURE in run.files:
        name = calibration_figure_name(run)
        lines += [f"![the spread over seeds, run {run.name}]({name})", ""]
    return lines


def calibration_page(runs: tuple[Run, ...]) -> str:
    """The page's markdown: every calibration run in name order (a note when there is none)."""
    sources = [s for r in runs for s in r.sources if not s.endswith(".png")]
    lines = generated_header("Results: calibration", sources)
    if not runs:
        lines += [
            "No calibration run among the results (`ipbench eval calibration --seeds A:B`).",
            "",
        ]
    for run in runs:
        lines += _run_lines(run)
    return "\n".join(lines).rstrip("\n") + "\n"
