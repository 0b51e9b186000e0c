"""The exploration report: summary.json's public shape and values, the markdown, the figure,
input validation; and the statistics' move to ipbench.eval.stats."""

from __future__ import annotations

import copy
import json
import math

import pytest
from exploration_records import episode_record as _record

from ipbench.eval.episodes import load_episodes
from ipbench.eval.exploration.report import (
    FEATURES,
    SCENES,
    THESIS_FIGURES,
    ExplorationReportError,
    recall_auc,
    summarize_exploration,
    write_exploration_report,
)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
BUDGET = 4
PUBLIC = ("performance_mean", "ci_low", "ci_high", "n", "true_positives", "false_positives")
MORE = ("not_found", "recovered", "recall_auc", "saccades_to_all_mean", "refixation_rate")
MORE += ("localisation_mm_median", "cycle_s")


# The hand-made cell: simple scene, active-vision, SIFT, seeds 0-2.
HAND = [
    _record(
        "simple", "active-vision", "sift", 0, 3, 1, 0, [0.0, 1 / 3, 2 / 3, 1.0],
        recovered=1, refixation_rate=0.0, cycle_s=0.1, localisation_mm=[1.0, 2.0, 3.0],
        fp_reasons={"wrong_class": 1, "already_reported": 0, "nothing_there": 0},
    ),
    _record(
        "simple", "active-vision", "sift", 1, 2, 0, 1, [0.0, 0.0, 2 / 3],
        refixation_rate=0.5, cycle_s=0.2, localisation_mm=[4.0, 5.0],
    ),
    _record(
        "simple", "active-vision", "sift", 2, 3, 0, 0, [0.0, 1.0],
        refixation_rate=0.25, cycle_s=0.3, localisation_mm=[6.0, 7.0, 8.0],
    ),
]  # fmt: skip


def _records() -> list[dict]:
    """2 scenes x 2 policies x 2 features x 3 seeds; the hand-made cell among them."""
    out = list(HAND)
    for scene in ("complex", "simple"):
        for policy in ("random-gaze", "active-vision"):
            for feature in ("akaze", "sift"):
                if (scene, policy, feature) == ("simple", "active-vision", "sift"):
                    continue
                for seed in (2, 0, 1):  # any order
                    tp = 1 + seed % 2
                    out.append(_record(scene, policy, feature, seed, tp, 1, 3 - tp, [0.0, tp / 3]))
    return out


def test_names_follow_the_env_and_the_features():
    from ipbench.envs.exploration_scene import LEVELS
    from ipbench.perception.features2d import FEATURE_TYPES

    assert SCENES == tuple(LEVELS)
    assert FEATURES == tuple(FEATURE_TYPES)


def test_recall_auc_by_hand():
    # trapezoids of [0, 1/3, 2/3, 1, 1] = 1/6 + 1/2 + 5/6 + 1 = 2.5 -> / 4
    assert recall_auc([0.0, 1 / 3, 2 / 3, 1.0], 4) == pytest.approx(0.625)
    assert recall_auc([0.0, 0.0, 2 / 3], 4) == pytest.approx(5 / 12)  # held at 2/3
    assert recall_auc([1.0], 4) == pytest.approx(1.0)  # all found before the first saccade
    assert recall_auc([0.0] * 5 + [1.0, 1.0], 4) == 0.0  # found after the budget: cut
    with pytest.raises(ExplorationReportError, match="budget"):
        recall_auc([0.0, 1.0], 0)


def test_summary_public_shape_and_hand_computed_values(tmp_path):
    paths = write_exploration_report(_records(), tmp_path / "report", BUDGET)
    summary = json.loads(paths.summary.read_text())
    assert paths.summary == tmp_path / "report" / "summary.json"
    assert list(summary) == ["simple", "complex"]  # env order, not input order
    assert list(summary["simple"]) == ["active-vision", "random-gaze"]
    for by_policy in summary.values():
        for by_feature in by_policy.values():
            assert list(by_feature) == ["sift", "akaze"]
            for cell in by_feature.values():
                assert set(PUBLIC + MORE) <= set(cell)
                assert cell["n"] == 3
                assert cell["ci_low"] <= cell["performance_mean"] <= cell["ci_high"]

    cell = summary["simple"]["active-vision"]["sift"]
    assert cell["performance_mean"] == pytest.approx((3 / 4 + 2 / 3 + 1.0) / 3)
    assert cell["ci_low"] < cell["performance_mean"] < cell["ci_high"]  # seeds differ
    assert 2 / 3 <= cell["ci_low"] and cell["ci_high"] <= 1.0  # within the seeds' range
    assert (cell["true_positives"], cell["false_positives"], cell["not_found"]) == (8, 1, 1)
    assert cell["recovered"] == 1
    assert cell["fp_reasons"] == {"wrong_class": 1, "already_reported": 0, "nothing_there": 0}
    assert cell["recall_auc"] == pytest.approx(23 / 36)  # (0.625 + 5/12 + 0.875) / 3
    assert cell["found_all"] == 2
    assert cell["saccades_to_all_mean"] == pytest.approx(2.0)  # seeds 0 (3) and 2 (1)
    assert cell["sim_s_to_all_mean"] == pytest.approx(3.0)
    assert cell["refixation_rate"] == pytest.approx(0.25)
    assert cell["localisation_mm_median"] == pytest.approx(4.5)  # median of 1..8 mm
    assert cell["cycle_s"] == pytest.approx(0.2)

    # a generated cell: tp = 1, 2, 1 of 3; one false positive each
    other = summary["complex"]["random-gaze"]["akaze"]
    assert other["performance_mean"] == pytest.approx((0.25 + 0.5 + 0.25) / 3)
    assert (other["true_positives"], other["false_positives"], other["not_found"]) == (4, 3, 5)
    assert other["recall_auc"] == pytest.approx((3.5 / 12 + 7 / 12 + 3.5 / 12) / 3)
    assert other["saccades_to_all_mean"] is None and other["found_all"] == 0


def test_paired_comparison_against_active_vision(tmp_path):
    summary = summarize_exploration(_records(), BUDGET)
    t = summary["simple"]["random-gaze"]["sift"]["vs_active_vision"]
    # per-seed differences 0.75 - 0.25, 2/3 - 0.5, 1 - 0.25
    assert t["n"] == 3
    assert t["mean_diff"] == pytest.approx((0.5 + 1 / 6 + 0.75) / 3)
    assert t["p_value"] == pytest.approx(2 / 8)  # exact: only all + and all - reach it
    assert t["method"] == "exact"
    assert "vs_active_vision" not in summary["simple"]["active-vision"]["sift"]
    same = summary["complex"]["random-gaze"]["sift"]["vs_active_vision"]
    assert same["mean_diff"] == 0.0 and same["p_value"] == 1.0  # identical per-seed values


def test_markdown_tables_thesis_figures_and_plot(tmp_path):
    lines = [json.dumps(r) for r in _records()]
    (tmp_path / "episodes.jsonl").write_text("\n".join(lines) + "\n")
    episodes = load_episodes(tmp_path / "episodes.jsonl")  # the JSON-lines round trip
    paths = write_exploration_report(episodes, tmp_path, BUDGET)
    md = paths.markdown.read_text()
    assert paths.markdown.name == "exploration.md"
    head = "| policy | true positives | false positives | not found | recovered | performance"
    assert md.count(head) == 4  # 2 features x 2 scenes
    for needle in ("## SIFT", "## AKAZE", "### simple scene, SIFT", "### complex scene, AKAZE"):
        assert needle in md
    for figure in THESIS_FIGURES:
        assert f"{figure.percent:g} %" in md
    assert "93.5 %" in md and "77 %" in md and "83 %" in md and "60 %" in md
    assert "SURF" in md and "pip wheel" in md
    # the hand-made cell's row: totals and mean [CI] in %
    row = next(r for r in md.splitlines() if r.startswith("| active-vision | 8 | 1 | 1 | 1 |"))
    assert "80.6 [" in row
    assert "recall AUC" in md and "re-fixation" in md and "3-D error (mm)" in md
    assert "| simple | sift | random-gaze | 3 | +47.2 |" in md  # paired: points
    assert paths.recall_plot.read_bytes()[:8] == PNG_MAGIC
    assert paths.recall_plot.stat().st_size > 5_000


def _broken(index: int, **changes) -> list[dict]:
    records = copy.deepcopy(_records())
    records[index].update(changes)
    return records


@pytest.mark.parametrize(
    ("records", "match"),
    [
        (_broken(1, scene="cluttered"), r"episode 1 .*unknown scene 'cluttered'; valid: simple"),
        (_broken(0, feature="surf"), r"episode 0 .*unknown feature 'surf'; valid: sift, kaze"),
        (_broken(2, performance=0.9), r"episode 2 .*performance 0.9 is not TP / \(TP \+ FP"),
        (_broken(0, false_positives=2), r"episode 0 .*fp_reasons .* false_positives = 2"),
        (_broken(3, recall_curve=[0.0, 1.5]), r"episode 3 .*recall_curve must be a non-empty"),
        (_broken(0, localisation_mm=[1.0]), r"episode 0 .*localisation_mm has 1 errors for 3"),
        (_broken(1, true_positives="2"), r"episode 1 .*true_positives must be an int >= 0"),
        (_broken(4, seed=2.0), r"episode 4 .*seed must be an int"),
        (_broken(0, saccades=5), r"episode 0 .*recall_curve has 4 values for 5 saccades"),
        (_records() + [_records()[0]], r"two records of scene='simple', .*seed=0"),
        ([{"scene": "simple"}], r"episode 0 .*lacks policy, feature, seed, n_database"),
        (["not a dict"], r"episode 0 is a str, not a dict"),
        ([], r"at least one record"),
    ],
)
def test_bad_records_raise_clear_errors(tmp_path, records, match):
    with pytest.raises(ExplorationReportError, match=match):
        write_exploration_report(records, tmp_path, BUDGET)
    assert not (tmp_path / "summary.json").exists()  # nothing half-written


def test_bad_budget(tmp_path):
    with pytest.raises(ExplorationReportError, match="budget must be an int >= 1"):
        write_exploration_report(_records(), tmp_path, 0)


def test_statistics_live_in_stats_and_are_re_exported():
    from ipbench.eval import stats
    from ipbench.eval.sorting import report as sorting_report

    for name in ("bootstrap_ci", "paired_test", "PairedTest"):
        assert getattr(sorting_report, name) is getattr(stats, name)
    mean, low, high = stats.bootstrap_ci([0.0, 1.0, 1.0, 0.5])
    assert mean == pytest.approx(0.625) and low < mean < high
    t = stats.paired_test({0: 1.0, 1: 0.5}, {1: 0.0, 2: 9.0})
    assert t.n == 1 and t.mean_diff == 0.5 and t.method == "exact"
    assert math.isnan(stats.paired_test({0: 1.0}, {1: 1.0}).p_value)
