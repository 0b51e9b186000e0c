"""A multi-seed calibration run (``ipbench eval calibration --seeds A:B``) as the results pages
read it: recognising its ``metrics.json``, the files kept of it, the reconstruction rows the
page and the README quote, and its distributions over seeds formatted one way for both.

A distribution is ``{"mean", "median", "ci_low", "ci_high", "n", "values"}`` over the seeds
(``ci_*``: the bootstrap interval of the mean at the run's ``confidence``; null below two
seeds); a paired comparison adds ``p_value``. Any of them may be null or missing, as a run on
few seeds or a camera that found no board leaves gaps: a gap reads ``–``, never an error.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ipbench.eval.markdown import number, percent, seeds_text

__all__ = [
    "FIGURE",
    "RECONSTRUCTION_ROWS",
    "ReconstructionRow",
    "calibration_command",
    "calibration_files",
    "confidence_text",
    "distribution",
    "interval_text",
    "is_calibration_metrics",
    "median_text",
    "n_text",
    "rate_text",
    "robot_text",
    "seeds_prose",
    "thesis_text",
]

FIGURE = "spread.png"
"""The run's figure of the per-seed spread, kept when present."""


@dataclass(frozen=True)
class ReconstructionRow:
    """A row of the reconstruction table: ``key`` of ``metrics["reconstruction"]``, ``label``,
    ``digits`` (decimals of its millimetres), and the thesis' figure beside it: ``thesis``, its
    key in ``metrics["thesis"]``, and ``source``, the thesis table (None: no figure)."""

    key: str
    label: str
    digits: int
    thesis: str | None = None
    source: str | None = None


_HEAD = ("head_rmse_mm", "Table 4.3")
_WRIST = ("xtion_rmse_mm", "Table 4.4")
RECONSTRUCTION_ROWS: tuple[ReconstructionRow, ...] = (
    ReconstructionRow("head_true_rmse_mm", "head, true extrinsics", 3, *_HEAD),
    ReconstructionRow("head_encoders_rmse_mm", "head, encoders", 3, *_HEAD),
    ReconstructionRow("head_dynamic_rmse_mm", "head, dynamic update (with the check)", 3, *_HEAD),
    ReconstructionRow(
        "head_dynamic_unchecked_rmse_mm", "head, dynamic update unchecked", 3, *_HEAD
    ),
    ReconstructionRow(
        "head_dynamic_left_chain_rmse_mm",
        "head, dynamic update of the left camera only",
        3,
        *_HEAD,
    ),
    ReconstructionRow("wrist_rmse_mm", "wrist depth (board shape)", 2),
    ReconstructionRow("wrist_robot_rmse_mm", "wrist in robot frame (calibrated X)", 2, *_WRIST),
    ReconstructionRow(
        "wrist_robot_nominal_rmse_mm", "wrist in robot frame (nominal X)", 2, *_WRIST
    ),
)
"""The rows of thesis Tables 4.2–4.5 the page shows, in order (the README quotes some)."""


def is_calibration_metrics(metrics: Mapping) -> bool:
    """Whether ``metrics`` is a multi-seed calibration run's: a ``seeds`` list and at least one
    reconstruction value that is a distribution (a dict with a ``mean``)."""
    rec = metrics.get("reconstruction")
    values = rec.values() if isinstance(rec, Mapping) else ()
    return isinstance(metrics.get("seeds"), list) and any(
        isinstance(v, Mapping) and "mean" in v for v in values
    )


def calibration_files(folder: Path, metrics: Mapping) -> dict[str, bytes] | None:
    """The files kept of the calibration run in ``folder`` (``metrics.json`` and, when present,
    :data:`FIGURE`; not the bulky ``episodes.jsonl``), None when ``metrics`` (its parsed
    ``metrics.json``) is no multi-seed calibration run's."""
    if not is_calibration_metrics(metrics):
        return None
    names = ("metrics.json", FIGURE)
    return {n: (folder / n).read_bytes() for n in names if (folder / n).is_file()}


def distribution(metrics: Mapping, *keys: str) -> Mapping | None:
    """The distribution at ``metrics[keys[0]][keys[1]]...``, None where any level is missing,
    null or not a dict."""
    value = metrics
    for key in keys:
        value = value.get(key) if isinstance(value, Mapping) else None
    return value if isinstance(value, Mapping) else None


def _finite(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def interval_text(d: Mapping | None, digits: int, signed: bool = False) -> str:
    """``0.162 [0.150, 0.175]``: the mean and its interval with ``digits`` decimals (``signed``:
    with a sign, for differences); the mean alone without an interval, ``–`` without a mean."""
    d = d or {}
    form = f"{{:{'+' if signed else ''}.{digits}f}}"
    mean, low, high = d.get("mean"), d.get("ci_low"), d.get("ci_high")
    if not _finite(mean):
        return "–"
    if not (_finite(low) and _finite(high)):
        return form.format(mean)
    return f"{form.format(mean)} [{form.format(low)}, {form.format(high)}]"


def rate_text(d: Mapping | None) -> str:
    """A fraction's distribution in percent: ``12.5 % [5.0, 20.0]``; ``–`` without a mean."""
    d = d or {}
    if not _finite(d.get("mean")):
        return "–"
    text = percent(d["mean"])
    low, high = d.get("ci_low"), d.get("ci_high")
    if _finite(low) and _finite(high):
        text += f" [{100 * low:.1f}, {100 * high:.1f}]"
    return text


def thesis_text(metrics: Mapping, row: ReconstructionRow) -> str:
    """The thesis' figure for ``row`` as ``0.16 (Table 4.3)``; ``""`` when the row has none,
    ``–`` when the run does not record it."""
    if row.thesis is None:
        return ""
    value = (metrics.get("thesis") or {}).get(row.thesis)
    return f"{value:g} ({row.source})" if _finite(value) else "–"


def robot_text(metrics: Mapping) -> str:
    """The simulated cell in words: its model-error seed, or the nominal cell."""
    seed = metrics.get("robot_seed")
    if seed is None:
        return "the nominal cell (no model errors)"
    return (
        f"the cell of model-error seed {seed} (`robot_seed`: its true model differs from the "
        "nominal one the robot believes)"
    )


def _seeds(metrics: Mapping) -> list[int]:
    seeds = metrics.get("seeds")
    seeds = seeds if isinstance(seeds, list) else []
    return [s for s in seeds if isinstance(s, int) and not isinstance(s, bool)]


def calibration_command(metrics: Mapping) -> str:
    """The ``ipbench eval calibration`` command line of the run (its seeds)."""
    return "ipbench eval calibration --seeds " + (seeds_text(_seeds(metrics))[0] or "–")


def confidence_text(metrics: Mapping) -> str:
    """The intervals' confidence (``95 %``), ``–`` when not recorded."""
    return percent(metrics.get("confidence"), 0)


def seeds_prose(metrics: Mapping) -> str:
    """The run's seeds in words: ``0–19 (20)``."""
    return seeds_text(_seeds(metrics))[1]


def n_text(d: Mapping | None) -> str:
    """The number of seeds a distribution is over, ``–`` when absent."""
    n = (d or {}).get("n")
    return str(n) if isinstance(n, int) and not isinstance(n, bool) else "–"


def median_text(d: Mapping | None, digits: int) -> str:
    """A distribution's median with ``digits`` decimals, ``–`` when absent."""
    return number((d or {}).get("median"), digits)
