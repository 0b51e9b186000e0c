"""``ipbench eval compare BASE OTHER``: two sorting runs paired by seed.

Two folders written by ``ipbench eval sorting`` (their ``episodes.jsonl``) that differ in one
setting — the robot's cell (``--extrinsics``), the env, the code — are compared episode by
episode: for every scene and policy both ran, on the seeds both ran, the accuracy of each
run (mean and 95 % bootstrap interval), failed grasps per episode, and OTHER − BASE paired
over seeds (:func:`ipbench.eval.stats.paired_test`: bootstrap interval of the mean difference,
two-sided sign-flip p). Pairs are by seed only: runs on other seeds of a scene and policy are
left out and counted.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ipbench.eval.episodes import load_episodes
from ipbench.eval.stats import PairedTest, bootstrap_ci, paired_test

__all__ = ["CompareError", "RunComparison", "as_json", "compare_runs", "comparison_markdown"]


class CompareError(ValueError):
    """A folder that is not a sorting run, or two runs with nothing in common."""


@dataclass(frozen=True)
class RunComparison:
    """One scene and policy of two runs, on their common seeds.

    Attributes
    ----------
    scene, policy : what both runs ran.
    n : common seeds; ``unpaired``: episodes of either run on other seeds (left out).
    base, other : accuracy (fraction) mean, 95 % CI low, high on the common seeds.
    base_grasp_failures, other_grasp_failures : failed grasps per episode (mean).
    diff : OTHER − BASE paired over the common seeds.
    """

    scene: str
    policy: str
    n: int
    unpaired: int
    base: tuple[float, float, float]
    other: tuple[float, float, float]
    base_grasp_failures: float
    other_grasp_failures: float
    diff: PairedTest


def _episodes(folder: Path, name: str) -> dict[tuple[str, str, int], dict]:
    path = Path(folder) / "episodes.jsonl"
    if not path.is_file():
        raise CompareError(
            f"{name} {folder} has no episodes.jsonl; give a folder written by "
            "`ipbench eval sorting --out DIR`"
        )
    try:
        records = load_episodes(path)
        return {(r["scene"], r["policy"], int(r["seed"])): r for r in records}
    except (ValueError, KeyError, TypeError) as err:
        raise CompareError(f"{name} {path} is not a sorting episode log ({err})") from err


def compare_runs(base: Path, other: Path) -> list[RunComparison]:
    """Every scene and policy of both runs, paired by seed (module docstring), in BASE's order."""
    a, b = _episodes(base, "BASE"), _episodes(other, "OTHER")
    groups: dict[tuple[str, str], None] = {}
    for scene, policy, _ in a:
        groups.setdefault((scene, policy), None)
    rows = []
    for scene, policy in groups:
        sa = {s: r for (sc, p, s), r in a.items() if (sc, p) == (scene, policy)}
        sb = {s: r for (sc, p, s), r in b.items() if (sc, p) == (scene, policy)}
        common = sorted(set(sa) & set(sb))
        if not common:
            continue
        acc_a = {s: float(sa[s]["accuracy"]) for s in common}
        acc_b = {s: float(sb[s]["accuracy"]) for s in common}
        rows.append(
            RunComparison(
                scene,
                policy,
                len(common),
                len(sa) + len(sb) - 2 * len(common),
                bootstrap_ci(list(acc_a.values())),
                bootstrap_ci(list(acc_b.values())),
                float(np.mean([sa[s].get("grasp_failures", 0) for s in common])),
                float(np.mean([sb[s].get("grasp_failures", 0) for s in common])),
                paired_test(acc_b, acc_a),
            )
        )
    if not rows:
        raise CompareError(
            f"BASE {base} and OTHER {other} share no scene, policy and seed; compare runs of "
            "the same scenes, policies and seeds"
        )
    return rows


def _pct(v: tuple[float, float, float]) -> str:
    return f"{100 * v[0]:.1f} [{100 * v[1]:.1f}, {100 * v[2]:.1f}]"


def comparison_markdown(rows: Sequence[RunComparison], base: str, other: str) -> str:
    """A markdown table of :func:`compare_runs`' rows (accuracy %, failed grasps/episode)."""
    lines = [
        f"BASE: {base}  \nOTHER: {other}",
        "",
        "| scene | policy | seeds | BASE accuracy % | OTHER accuracy % | failed grasps "
        "BASE / OTHER | OTHER − BASE, points [95 % CI] | p |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        d = r.diff
        lines.append(
            f"| {r.scene} | {r.policy} | {r.n} | {_pct(r.base)} | {_pct(r.other)} | "
            f"{r.base_grasp_failures:.1f} / {r.other_grasp_failures:.1f} | "
            f"{100 * d.mean_diff:+.1f} [{100 * d.ci_low:+.1f}, {100 * d.ci_high:+.1f}] | "
            f"{d.p_value:.3g} |"
        )
    unpaired = sum(r.unpaired for r in rows)
    if unpaired:
        lines += ["", f"{unpaired} episodes on seeds only one run has were left out."]
    lines += ["", "Scenes and policies only one run has are not listed."]
    return "\n".join(lines) + "\n"


def as_json(rows: Sequence[RunComparison]) -> list[dict]:
    """The rows as JSON-ready dicts."""
    return [asdict(r) for r in rows]
