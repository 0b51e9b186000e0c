"""One measurement on disjoint seed sets: the two-sample statistics, which runs are seed sets
of one measurement, each quantity per set, and the generated sentences."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ipbench.eval.replication import agreement
from ipbench.eval.report.readme import headline_block
from ipbench.eval.report.runs import Discovery, Run
from ipbench.eval.report.seed_sets import replications, seed_set_groups, seed_set_lines
from ipbench.eval.sorting.curve import curve
from ipbench.eval.stats import seeds_for_half_width, two_sample_test

N = 10  # objects per episode


def test_two_sample_test_finds_a_shift_and_not_a_relabelling():
    rng = np.random.default_rng(0)
    a, b = rng.normal(0.0, 1.0, 30), rng.normal(1.5, 1.0, 30)
    shifted = two_sample_test(a, b)
    assert shifted.mean_diff == pytest.approx(b.mean() - a.mean())
    assert 0 < shifted.ci_low < shifted.mean_diff < shifted.ci_high
    assert shifted.p_value < 0.001 and (shifted.n_a, shifted.n_b) == (30, 30)
    same = two_sample_test(a, rng.permutation(a))
    assert same.mean_diff == pytest.approx(0.0, abs=1e-12) and same.p_value > 0.9
    assert two_sample_test([1.0, 1.0], [1.0, 1.0]).p_value == 1.0
    with pytest.raises(ValueError, match="two or more finite values in b"):
        two_sample_test([1.0, 2.0], [3.0])


def test_seeds_for_half_width_by_hand():
    # (1.959964 * 0.05 / 0.02) ** 2 = 24.01 -> 25; a tenfold narrower interval needs 100x
    assert seeds_for_half_width(0.05, 0.02) == 25
    assert seeds_for_half_width(0.05, 0.002) == math.ceil((1.959964 * 0.05 / 0.002) ** 2)
    assert seeds_for_half_width(0.0, 0.02) == 1
    with pytest.raises(ValueError, match="half_width > 0"):
        seeds_for_half_width(0.05, 0.0)


def _episodes(seeds: range, shift: float) -> list[dict]:
    """A curve on ``seeds``: gp-ipm at 0, 0.5 and 1 inspections per object, random inspection
    of half, random sorting; the accuracies vary with the seed, gp-ipm@0.5 by ``shift``."""
    out = []
    for seed in seeds:
        wobble = 0.1 * (seed % 3)
        runs = {
            ("random", 0): 0.5 + wobble,
            ("gp-ipm@0.0", 0): 0.6 + wobble,
            ("gp-ipm@0.5", 5): 0.7 + wobble + shift,
            ("gp-ipm@1.0", 10): 0.7,
            ("random-inspect@0.5", 5): 0.6 + wobble,
            ("gp-ipm", 3): 0.7 + wobble,
        }
        for (policy, inspections), accuracy in runs.items():
            out.append(
                {
                    "scene": "cluttered",
                    "policy": policy,
                    "seed": seed,
                    "objects": N,
                    "correct": round(accuracy * N),
                    "accuracy": round(accuracy * N) / N,
                    "inspections": inspections,
                }
            )
    return out


def _run(name: str, seeds: range, shift: float = 0.0, fingerprint: str = "f00d") -> Run:
    eps = _episodes(seeds, shift)
    per_seed: dict = {}
    for e in eps:
        per_seed.setdefault(e["scene"], {}).setdefault(e["policy"], {})[str(e["seed"])] = e[
            "accuracy"
        ]
    run = {"fingerprint": fingerprint, "config": {"seeds": list(seeds)}}
    files = {
        "run.json": json.dumps(run),
        "curve.json": json.dumps(curve(eps)),
        "accuracy_per_seed.json": json.dumps(per_seed),
        "summary.json": json.dumps({}),
    }
    return Run("sorting", name, {k: v.encode() for k, v in files.items()})


def test_groups_need_one_fingerprint_and_disjoint_seeds():
    a, b = _run("a", range(0, 6)), _run("b", range(6, 12))
    overlapping, other = _run("c", range(3, 9)), _run("d", range(20, 26), fingerprint="beef")
    groups = seed_set_groups((a, b, overlapping, other))
    assert [[r.name for r in g] for g in groups] == [["a", "b"]]
    assert seed_set_groups((a, overlapping)) == []


def test_each_quantity_per_set_the_gap_and_the_union():
    a, b = _run("a", range(0, 6)), _run("b", range(6, 12), shift=0.1)
    rows = {(r.scene, r.quantity): r for r in replications((a, b))}
    assert sorted(rows) == [
        ("cluttered", "gp-ipm score"),
        ("cluttered", "gp-ipm − random"),
        ("cluttered", "random"),
    ]
    score = rows["cluttered", "gp-ipm score"]
    first, second = (s.mean for s in score.sets)
    # gp-ipm@0.5 lifts the curve's midpoint by 0.1 above the line: a triangle of mean 0.05
    assert second - first == pytest.approx(0.05)
    assert score.gap.mean_diff == pytest.approx(0.05)
    assert score.pooled.mean == pytest.approx((first + second) / 2)
    assert score.pooled.seeds == tuple(range(12))
    assert score.seeds_needed[0.02] == seeds_for_half_width(score.pooled.sd, 0.02)
    diff = rows["cluttered", "gp-ipm − random"]
    assert [s.mean for s in diff.sets] == pytest.approx([0.2, 0.2])
    assert diff.gap.mean_diff == pytest.approx(0.0, abs=1e-12)
    assert rows["cluttered", "random"].pooled_p is None and diff.pooled_p is not None


def test_the_sentences_say_where_the_sets_disagree():
    a = _run("a", range(0, 12))
    agree = replications((a, _run("b", range(12, 24))))
    assert agreement(agree).startswith("The seed sets agree")
    apart = replications((a, _run("b", range(12, 24), shift=0.2)))
    sentence = agreement(apart)
    assert "land apart" in sentence and "gp-ipm score" in sentence
    lines = seed_set_lines((a, _run("b", range(12, 24), shift=0.2)))
    assert lines[0] == "## One measurement on disjoint seed sets"
    assert "### Seed sets: `a` on seeds 0–11 (12), `b` on seeds 12–23 (12)" in lines
    assert seed_set_lines((a,)) == []


def test_readme_gives_the_verdict_over_every_seed_set():
    def headline(name: str, seeds: range) -> Run:
        run = _run(name, seeds)
        cell = {"accuracy_mean": 0.7, "ci_low": 0.6, "ci_high": 0.8, "n": len(seeds)}
        summary = {"cluttered": {"random": cell, "gp-ipm": cell}}
        return Run("sorting", name, {**run.files, "summary.json": json.dumps(summary).encode()})

    a, b = headline("a", range(0, 12)), headline("b", range(12, 24))
    block = headline_block(Discovery(runs=(a, b), check=None, notes=()), "docs/index.md", "a")
    assert "Over all 24 seeds of the seed sets `a`, `b`:" in block
    assert "on seeds 0–11" in block and "on seeds 12–23" in block
    alone = headline_block(Discovery(runs=(a,), check=None, notes=()), "docs/index.md", "a")
    assert "Over all" not in alone and "Inspecting the objects GP-IPM" in alone
