"""The sorting report: bootstrap and paired statistics, the summary, the files, JSONL loading."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ipbench.eval.sorting.report import (
    THESIS_TABLE_5_1,
    PairedTest,
    ReportPaths,
    ThresholdSweep,
    bootstrap_ci,
    load_episodes,
    paired_test,
    summarize,
    write_report,
)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _episode(scene: str, policy: str, seed: int, counts: dict, **extra) -> dict:
    """A record with ``counts = {category: (correct, total)}``."""
    objects = sum(t for _, t in counts.values())
    correct = sum(c for c, _ in counts.values())
    record = {
        "scene": scene,
        "policy": policy,
        "seed": seed,
        "objects": objects,
        "correct": correct,
        "accuracy": correct / objects,
        "per_category": {k: {"total": t, "correct": c} for k, (c, t) in counts.items()},
        "inspections": 0,
        "grasp_failures": 0,
        "wall_time_s": 10.0,
        "sim_time_s": 40.0,
        "decisions": [],
    }
    record.update(extra)
    return record


def _inspect(label: str, truth: str | None, before: float, after: float) -> dict:
    return {
        "step": 1,
        "kind": "inspect",
        "label": label,
        "confidence": after,
        "first_label": "bowl",
        "first_confidence": before,
        "views": 3,
        "true_category": truth,
    }


# The hand-made input: three episodes, two of them one policy's seeds in one scene.
THREE = [
    _episode(
        "cluttered",
        "gp-ipm",
        1,
        {"mug": (2, 3), "bowl": (1, 1), "juice_box": (0, 1)},
        inspections=2,
        grasp_failures=1,
        wall_time_s=20.0,
    ),
    _episode(
        "cluttered",
        "gp-ipm",
        0,
        {"mug": (3, 3), "juice_bottle": (2, 2)},
        inspections=4,
        grasp_failures=3,
        wall_time_s=30.0,
    ),
    _episode("uncluttered", "random", 0, {"mug": (1, 2)}),
]


# --------------------------------------------------------------------------- bootstrap_ci


def test_bootstrap_interval_contains_the_mean_and_narrows_with_more_seeds():
    rng = np.random.default_rng(1)
    few = rng.uniform(0.5, 1.0, 8)
    many = rng.uniform(0.5, 1.0, 200)
    mean, low, high = bootstrap_ci(few)
    assert mean == pytest.approx(few.mean())
    assert low < mean < high
    assert 0.5 <= low and high <= 1.0
    m2, l2, h2 = bootstrap_ci(many)
    assert l2 < m2 < h2
    assert h2 - l2 < 0.5 * (high - low)  # ~sqrt(8 / 200) = 0.2 times as wide
    assert (h2 - l2) == pytest.approx(2 * 1.96 * many.std() / math.sqrt(200), rel=0.1)


def test_bootstrap_is_deterministic_for_a_seed_and_level_widens_it():
    values = np.random.default_rng(2).uniform(0.4, 1.0, 15)
    assert bootstrap_ci(values, seed=3) == bootstrap_ci(values, seed=3)
    assert bootstrap_ci(values, seed=3) != bootstrap_ci(values, seed=4)
    _, l95, h95 = bootstrap_ci(values)
    _, l50, h50 = bootstrap_ci(values, level=0.5)
    assert l95 < l50 < h50 < h95


def test_bootstrap_single_and_constant_values_and_errors():
    assert bootstrap_ci([0.75]) == (0.75, 0.75, 0.75)
    assert bootstrap_ci([0.1] * 5) == (0.1, 0.1, 0.1)
    with pytest.raises(ValueError, match="non-empty"):
        bootstrap_ci([])
    with pytest.raises(ValueError, match="finite"):
        bootstrap_ci([0.5, float("nan")])
    with pytest.raises(ValueError, match="level"):
        bootstrap_ci([0.5, 0.6], level=1.5)


# --------------------------------------------------------------------------- paired_test


def test_paired_test_finds_a_clear_difference():
    a = {s: 0.8 + 0.01 * s for s in range(12)}
    b = {s: v - 0.3 for s, v in a.items()}
    t = paired_test(a, b)
    assert isinstance(t, PairedTest)
    assert (t.n, t.method) == (12, "exact")
    assert t.mean_diff == pytest.approx(0.3)
    assert t.ci_low == pytest.approx(0.3) and t.ci_high == pytest.approx(0.3)
    assert t.p_value == pytest.approx(2 / 2**12)  # only all-plus and all-minus reach 0.3
    assert t.p_value < 0.01
    assert paired_test(b, a).mean_diff == pytest.approx(-0.3)


def test_paired_test_on_identical_data_gives_p_one():
    a = {s: 0.5 + 0.02 * s for s in range(10)}
    t = paired_test(a, dict(a))
    assert t.p_value == 1.0 and t.mean_diff == 0.0
    big = {s: 0.5 + 0.01 * s for s in range(20)}
    t = paired_test(big, dict(big))
    assert (t.method, t.p_value) == ("monte-carlo", 1.0)


def test_exact_p_of_a_hand_computable_case():
    # Three equal positive differences: of 8 sign patterns only +++ and --- reach |mean| 0.1.
    t = paired_test({0: 0.9, 1: 0.8, 2: 0.7}, {0: 0.8, 1: 0.7, 2: 0.6})
    assert t.p_value == pytest.approx(2 / 8)
    # Differences 0.1, 0.2, 0.4: |sum| >= 0.7 only for +++ and ---; >= 0.3 adds ++- and --+.
    t = paired_test({0: 0.1, 1: 0.2, 2: 0.4}, {0: 0.0, 1: 0.0, 2: 0.0})
    assert t.p_value == pytest.approx(2 / 8)
    # Differences 0.4, 0.2, -0.1 (|sum| 0.5): |sum| of the 8 patterns is 0.5, 0.7, 0.1, 0.3,
    # 0.3, 0.1, 0.7, 0.5, so 4 of 8 reach it.
    t = paired_test({0: 0.4, 1: 0.2, 2: 0.0}, {0: 0.0, 1: 0.0, 2: 0.1})
    assert t.p_value == pytest.approx(4 / 8)
    assert t.mean_diff == pytest.approx(0.5 / 3)


def test_paired_test_pairs_by_seed_and_handles_no_common_seed():
    t = paired_test({0: 1.0, 1: 0.9, 7: 0.0}, {1: 0.6, 0: 0.7, 9: 1.0})
    assert t.n == 2 and t.mean_diff == pytest.approx(0.3)
    empty = paired_test({0: 1.0}, {1: 1.0})
    assert (empty.n, empty.method) == (0, "none")
    assert math.isnan(empty.p_value) and math.isnan(empty.mean_diff)


def test_monte_carlo_test_above_sixteen_pairs():
    rng = np.random.default_rng(0)
    a = {s: float(v) for s, v in enumerate(rng.uniform(0.6, 1.0, 20))}
    b = {s: v - 0.2 for s, v in a.items()}
    t = paired_test(a, b)
    assert t.method == "monte-carlo" and t.n == 20
    assert t.p_value < 1e-3
    assert t.p_value == paired_test(a, b).p_value  # fixed seed


# --------------------------------------------------------------------------- summarize


def test_summarize_sums_categories_over_seeds():
    s = summarize(THREE)
    assert list(s) == ["uncluttered", "cluttered"]
    gp = s["cluttered"]["gp-ipm"]
    assert gp["per_category"] == {
        "juice_bottle": {"correct": 2, "total": 2},
        "bowl": {"correct": 1, "total": 1},
        "mug": {"correct": 5, "total": 6},
        "juice_box": {"correct": 0, "total": 1},
    }
    assert list(gp["per_category"]) == ["juice_bottle", "bowl", "mug", "juice_box"]  # bin order
    assert (gp["n"], gp["objects"], gp["correct"], gp["seeds"]) == (2, 10, 8, [0, 1])
    assert gp["accuracy_mean"] == pytest.approx((3 / 5 + 5 / 5) / 2)
    assert gp["ci_low"] == pytest.approx(0.6) and gp["ci_high"] == pytest.approx(1.0)
    assert gp["inspections_mean"] == 3.0 and gp["grasp_failures_mean"] == 2.0
    assert gp["wall_time_s_mean"] == 25.0
    rnd = s["uncluttered"]["random"]
    assert (rnd["accuracy_mean"], rnd["ci_low"], rnd["ci_high"], rnd["n"]) == (0.5, 0.5, 0.5, 1)


def test_summarize_orders_policies_and_rejects_bad_input():
    eps = [
        _episode("cluttered", name, 0, {"mug": (1, 1)})
        for name in ("zeta", "random", "alpha", "gp-ipm", "oracle", "svm-ipm", "gp-ipm-area")
    ]
    eps.append(_episode("lab", "random", 0, {"mug": (1, 1)}))
    s = summarize(eps)
    assert list(s) == ["cluttered", "lab"]
    assert list(s["cluttered"]) == [
        "oracle",
        "gp-ipm",
        "gp-ipm-area",
        "svm-ipm",
        "random",
        "alpha",
        "zeta",
    ]
    with pytest.raises(ValueError, match="seed=0"):
        summarize([eps[0], dict(eps[0])])
    broken = dict(eps[0])
    del broken["correct"]
    with pytest.raises(ValueError, match="lacks correct"):
        summarize([broken])


# --------------------------------------------------------------------------- write_report


def _report_episodes() -> list[dict]:
    eps = []
    for seed in range(6):
        # gp-ipm: 12/14 on every seed; random: 8/14.
        eps.append(
            _episode(
                "cluttered",
                "gp-ipm",
                seed,
                {"mug": (4, 4), "bowl": (3, 4), "juice_box": (5, 6)},
                inspections=3,
                grasp_failures=2,
                wall_time_s=19.5,
                decisions=[
                    _inspect("mug", "mug", 0.4, 0.8),
                    _inspect("bowl", "mug", 0.5, 0.45),
                    _inspect("", "mug", 0.3, float("nan")),  # cut short: not counted
                    {"step": 9, "kind": "place", "label": "mug", "confidence": 0.9},
                ],
            )
        )
        eps.append(
            _episode(
                "cluttered",
                "random",
                seed,
                {"mug": (2, 4), "bowl": (2, 4), "juice_box": (4, 6)},
                wall_time_s=9.0,
            )
        )
    eps.append(_episode("uncluttered", "gp-ipm", 0, {"mug": (9, 9)}))
    return eps[::-1]  # any order


def test_write_report_writes_the_table_the_thesis_line_and_the_files(tmp_path):
    sweep = ThresholdSweep(
        thresholds=np.linspace(0.3, 0.9, 7),
        accuracy=np.linspace(0.7, 0.9, 7),
        inspected_fraction=np.linspace(0.0, 0.8, 7),
        chosen=0.6,
        source="Synthetic sweep for the test.",
    )
    paths = write_report(_report_episodes(), tmp_path / "report", threshold_sweep=sweep)
    assert isinstance(paths, ReportPaths)
    names = [p.name for p in paths.plots]
    assert names == ["accuracy_by_policy.png", "confidence_inspection.png", "threshold_sweep.png"]
    for png in paths.plots:
        data = png.read_bytes()
        assert len(data) > 1000 and data.startswith(PNG_MAGIC)

    md = paths.markdown.read_text()
    assert md.startswith("# ")
    assert "| gp-ipm | 18/24 | 24/24 | 30/36 | 72/84 (86 %) | 85.7 % | [85.7, 85.7] % | 6 |" in md
    assert "| random | 12/24 | 12/24 | 24/36 | 48/84 (57 %) | 57.1 % |" in md
    assert "| 3.0 | 2.0 | 0 / 0 / 0 | 19.5 s |" in md  # no drops in the synthetic records
    assert "| grasp failures | dropped / wrong bin / left | wall time |" in md
    assert "| policy | bowl | mug | juice box | Total | mean | 95 % CI | seeds |" in md
    assert md.index("## uncluttered") < md.index("## cluttered")
    assert md.index("| gp-ipm |", md.index("## cluttered")) < md.index("| random |")
    assert "`gp-ipm`) 12/14 (86 %); random (`random`) 8/14 (57 %)." in md
    assert "`gp-ipm`) 9/9 (100 %)" in md
    assert "mean difference +28.6 points" in md and "p = 0.0312" in md  # 2 / 2**6
    assert "n = 6 paired seeds" in md and "intervals do not overlap" in md
    assert "uncluttered, `gp-ipm`" not in md  # no random there: no test
    assert md.index("8/14 (57 %)") < md.index("**Paired test, cluttered") < md.index("## Plots")
    assert "12 inspections (all policies); the confidence rose in 6 of them" in md
    assert "the fused label was right in 6 of the 12 with known ground truth" in md
    for png in names:
        assert f"({png})" in md
    assert "Synthetic sweep for the test. Chosen threshold: 0.60" in md

    summary = json.loads(paths.summary.read_text())
    gp = summary["cluttered"]["gp-ipm"]
    assert {"accuracy_mean", "ci_low", "ci_high", "n"} <= set(gp)
    assert gp["n"] == 6 and gp["accuracy_mean"] == pytest.approx(12 / 14)
    assert gp["per_category"]["bowl"] == {"correct": 18, "total": 24}


def test_write_report_without_inspections_or_sweep(tmp_path):
    eps = [_episode("cluttered", "random", s, {"mug": (s % 2, 1)}) for s in range(4)]
    paths = write_report(eps, tmp_path)
    assert [p.name for p in paths.plots] == ["accuracy_by_policy.png"]
    assert not (tmp_path / "confidence_inspection.png").exists()
    assert "Paired test" not in paths.markdown.read_text()
    with pytest.raises(ValueError, match="at least one episode"):
        write_report([], tmp_path)


def test_thesis_numbers():
    assert THESIS_TABLE_5_1["cluttered"]["gp-ipm"].percent == pytest.approx(85.714, abs=1e-3)
    assert round(THESIS_TABLE_5_1["cluttered"]["random"].percent) == 57
    assert THESIS_TABLE_5_1["uncluttered"]["random"].correct == 9


# --------------------------------------------------------------------------- load_episodes


def test_load_episodes_skips_a_truncated_last_line(tmp_path):
    path = tmp_path / "episodes.jsonl"
    lines = [json.dumps(e) for e in THREE]
    path.write_text("\n".join(lines) + "\n\n" + lines[0][:25])
    with pytest.warns(UserWarning, match=r"episodes.jsonl:5: skipping a truncated last line"):
        loaded = load_episodes(path)
    assert loaded == THREE


def test_load_episodes_raises_on_a_corrupt_middle_line(tmp_path):
    path = tmp_path / "episodes.jsonl"
    lines = [json.dumps(e) for e in THREE]
    lines[1] = lines[1][:30]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"episodes.jsonl:2: not valid JSON"):
        load_episodes(path)
    path.write_text(json.dumps(THREE[0]) + "\n[1, 2]\n" + json.dumps(THREE[1]) + "\n")
    with pytest.raises(ValueError, match=r"episodes.jsonl:2: expected a JSON object"):
        load_episodes(path)


def test_every_policy_is_tested_against_random_and_gp_against_svm(tmp_path):
    """One paired test per policy against random sorting (GP-IPM's first), and GP-IPM
    against SVM-IPM, each over the seeds both ran."""
    right = {"oracle": 4, "gp-ipm": 3, "svm-ipm": 2, "random": 1}
    eps = [
        _episode("cluttered", p, s, {"mug": (right[p] if s < 4 else 2, 4)})
        for p in right
        for s in range(6)
    ]
    md = write_report(eps, tmp_path).markdown.read_text()
    tests = [ln for ln in md.splitlines() if ln.startswith("**Paired test")]
    assert [ln.split("`")[1:4:2] for ln in tests] == [
        ["gp-ipm", "random"],
        ["oracle", "random"],
        ["svm-ipm", "random"],
        ["gp-ipm", "svm-ipm"],
    ]
    # oracle - random: +75 points on four seeds of six, 0 on two: +50 points
    assert "mean difference +50.0 points" in tests[1]
    assert "mean difference +16.7 points" in tests[3]  # 25 points on 4 of 6 seeds
