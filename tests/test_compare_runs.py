"""``ipbench eval compare``: two sorting runs paired by seed."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ipbench.eval.cli import main
from ipbench.eval.sorting.compare import CompareError, compare_runs, comparison_markdown


def _run(folder, accuracies: dict[tuple[str, str, int], float]):
    folder.mkdir()
    lines = [
        json.dumps({"scene": sc, "policy": p, "seed": s, "accuracy": a, "grasp_failures": s % 3})
        for (sc, p, s), a in accuracies.items()
    ]
    (folder / "episodes.jsonl").write_text("\n".join(lines) + "\n")
    return folder


def test_differences_are_paired_by_seed_and_unpaired_seeds_left_out(tmp_path):
    rng = np.random.default_rng(0)
    base_acc = rng.uniform(0.5, 0.9, 12)
    base = _run(tmp_path / "a", {("cluttered", "gp-ipm", s): base_acc[s] for s in range(12)})
    # OTHER: 0.1 better on seeds 0-9 (10 and 11 missing), one extra seed 40, another policy
    other_acc = {("cluttered", "gp-ipm", s): base_acc[s] + 0.1 for s in range(10)}
    other_acc[("cluttered", "gp-ipm", 40)] = 0.0
    other_acc[("cluttered", "random", 0)] = 0.5
    other = _run(tmp_path / "b", other_acc)
    (row,) = compare_runs(base, other)
    assert (row.scene, row.policy, row.n, row.unpaired) == ("cluttered", "gp-ipm", 10, 3)
    assert row.diff.mean_diff == pytest.approx(0.1)
    assert row.diff.ci_low == pytest.approx(0.1) and row.diff.p_value < 0.01
    assert row.base[0] == pytest.approx(base_acc[:10].mean())
    assert row.other_grasp_failures == pytest.approx(np.mean([s % 3 for s in range(10)]))
    text = comparison_markdown([row], "a", "b")
    assert "| cluttered | gp-ipm | 10 |" in text and "+10.0 [+10.0, +10.0]" in text
    assert "3 episodes on seeds only one run has were left out" in text


def test_bad_folders_are_refused_with_what_to_give(tmp_path, capsys):
    good = _run(tmp_path / "a", {("uncluttered", "random", 0): 0.5})
    with pytest.raises(CompareError, match="no episodes.jsonl; give a folder written by"):
        compare_runs(good, tmp_path / "missing")
    other = _run(tmp_path / "b", {("uncluttered", "random", 1): 0.5})
    with pytest.raises(CompareError, match="share no scene, policy and seed"):
        compare_runs(good, other)
    (tmp_path / "c").mkdir()
    (tmp_path / "c" / "episodes.jsonl").write_text('{"seed": 1}\n')
    with pytest.raises(CompareError, match="not a sorting episode log"):
        compare_runs(good, tmp_path / "c")
    with pytest.raises(SystemExit, match="ipbench: .*share no scene"):
        main(["eval", "compare", str(good), str(other)])


def test_the_command_prints_the_table_and_writes_json(tmp_path, capsys):
    a = _run(tmp_path / "a", {("pile", "oracle", s): 0.8 for s in range(4)})
    b = _run(tmp_path / "b", {("pile", "oracle", s): 0.7 for s in range(4)})
    assert main(["eval", "compare", str(a), str(b), "--json", str(tmp_path / "c.json")]) == 0
    out = capsys.readouterr().out
    assert "| pile | oracle | 4 | 80.0 [80.0, 80.0] | 70.0 [70.0, 70.0]" in out
    rows = json.loads((tmp_path / "c.json").read_text())
    assert rows[0]["diff"]["mean_diff"] == pytest.approx(-0.1)
