"""Every exploration comparison on disjoint seed sets: the split, the quantities' values by hand,
the verdict sentence, the markdown section and seed_sets.json."""

from __future__ import annotations

import json

import numpy as np
import pytest
from exploration_records import BUDGET, N, record, sample_records

from ipbench.eval.exploration.records import group_records
from ipbench.eval.exploration.report import write_exploration_report
from ipbench.eval.exploration.seed_sets import (
    seed_set_groups,
    seed_set_groups_from_records,
    seed_set_lines,
    seed_set_records,
    split_seeds,
)


def test_split_seeds_in_order_the_last_set_takes_the_remainder():
    assert split_seeds(range(20)) == [tuple(range(10)), tuple(range(10, 20))]
    assert split_seeds([24, *range(24), 3]) == [tuple(range(10)), tuple(range(10, 25))]
    assert split_seeds(range(19)) == []
    assert split_seeds(range(9), size=3) == [(0, 1, 2), (3, 4, 5), (6, 7, 8)]
    with pytest.raises(ValueError, match="size >= 2"):
        split_seeds(range(20), size=1)


def test_policies_differences_and_gap_by_hand():
    records = [r for r in sample_records(range(20), late_drop=1) if r["policy"] != "raster-scan"]
    (group,) = seed_set_groups(group_records(records))
    rows = {r.quantity: r for r in group.rows}
    assert list(rows) == [
        "active-vision",
        "oracle-gaze",
        "random-gaze",
        "active-vision − oracle-gaze",
        "active-vision − random-gaze",
        "oracle-gaze − random-gaze",
    ]
    av = {s: (5 + s % 3) / N for s in range(20)}
    rg = {s: av[s] - (2 + (s >= 10)) / N for s in range(20)}
    first, last = rows["active-vision − random-gaze"].sets
    assert first.mean == pytest.approx(0.2) and last.mean == pytest.approx(0.3)
    assert first.seeds == tuple(range(10)) and last.seeds == tuple(range(10, 20))
    diff = rows["active-vision − random-gaze"]
    assert diff.gap.mean_diff == pytest.approx(0.1)
    assert diff.gap.ci_low == pytest.approx(0.1) and diff.gap.ci_high == pytest.approx(0.1)
    assert diff.pooled.mean == pytest.approx(0.25) and diff.pooled_p is not None
    og = rows["oracle-gaze − random-gaze"].pooled
    assert og.mean == pytest.approx(np.mean([0.8 - rg[s] for s in range(20)]))
    level = rows["active-vision"]
    assert level.pooled_p is None
    assert level.sets[0].mean == pytest.approx(np.mean([av[s] for s in range(10)]))


def test_a_policy_on_fewer_seeds_limits_the_split_to_the_shared_seeds():
    # raster-scan ran seeds 0-9 only: the four policies share 10 seeds, too few to split
    assert seed_set_groups(group_records(sample_records(range(20)))) == []
    lines = seed_set_lines([])
    assert any("Not measured" in line and "--seeds 0:20" in line for line in lines)
    # with raster-scan on every seed, the split is back and has its rows
    full = sample_records(range(20)) + [
        record("simple", "raster-scan", s, 5 + s % 3, 0) for s in range(10, 20)
    ]
    (group,) = seed_set_groups(group_records(full))
    assert "active-vision − raster-scan" in {r.quantity for r in group.rows}


def test_the_verdict_names_a_comparison_whose_sets_land_apart():
    records = [r for r in sample_records(range(20), late_drop=3) if r["policy"] != "raster-scan"]
    found = seed_set_groups(group_records(records))
    md = "\n".join(seed_set_lines(found))
    assert "### simple scene, SIFT" in md and "seeds 0–9 (10)" in md and "seeds 10–19 (10)" in md
    assert "land apart beyond their intervals" in md
    assert "simple active-vision − random-gaze: +30.0" in md
    agree = [r for r in sample_records(range(20)) if r["policy"] != "raster-scan"]
    md = "\n".join(seed_set_lines(seed_set_groups(group_records(agree))))
    assert "The seed sets agree" in md


def test_report_writes_the_section_and_seed_sets_json(tmp_path):
    records = [r for r in sample_records(range(20), late_drop=1) if r["policy"] != "raster-scan"]
    paths = write_exploration_report(records, tmp_path, BUDGET)
    assert "## Seed sets: does each comparison hold on disjoint seeds?" in (
        paths.markdown.read_text()
    )
    rows = json.loads(paths.seed_sets.read_text())
    assert rows == seed_set_records(seed_set_groups(group_records(records)))
    row = next(r for r in rows if r["quantity"] == "active-vision − random-gaze")
    assert row["level"] is False and row["scene"] == "simple" and row["feature"] == "sift"
    assert [s["seeds"] for s in row["sets"]] == [list(range(10)), list(range(10, 20))]
    assert row["gap"]["mean_diff"] == pytest.approx(0.1)
    assert row["all"]["mean"] == pytest.approx(0.25) and len(row["all"]["seeds"]) == 20
    # fewer seeds: the section says what a split needs; seed_sets.json holds no rows
    few = [r for r in records if r["seed"] < 12]
    paths = write_exploration_report(few, tmp_path / "few", BUDGET)
    assert "Not measured" in paths.markdown.read_text()
    assert json.loads(paths.seed_sets.read_text()) == []


@pytest.mark.parametrize("late_drop", [0, 3])
def test_seed_sets_json_reads_back_into_the_same_section(late_drop):
    records = [r for r in sample_records(range(25), late_drop) if r["policy"] != "raster-scan"]
    found = seed_set_groups(group_records(records))
    rows = json.loads(json.dumps(seed_set_records(found)))
    back = seed_set_groups_from_records(rows)
    assert [g.sets for g in back] == [g.sets for g in found]
    assert seed_set_lines(back) == seed_set_lines(found)
    assert seed_set_records(back) == rows
