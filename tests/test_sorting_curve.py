"""The accuracy–inspection curve: policy names, points, the gain over random inspection, the
decomposition of what inspection did, and the files."""

from __future__ import annotations

import json

import pytest

from ipbench.eval.sorting.curve import (
    curve,
    decomposition,
    per_seed_scores,
    write_curve,
)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
N = 10  # objects per episode


def _ep(policy: str, seed: int, accuracy: float, inspections: int, **extra) -> dict:
    correct = round(accuracy * N)
    record = {
        "scene": "cluttered",
        "policy": policy,
        "seed": seed,
        "objects": N,
        "correct": correct,
        "accuracy": correct / N,
        "inspections": inspections,
        "grasp_failures": 0,
        "dropped": 0,
        "left": 0,
        "decisions": [],
        "threshold": None,
    }
    record.update(extra)
    return record


# The toy curve: gp-ipm at x = 0, 0.5, 1 inspections per object; random inspection of half the
# objects at x = 0.5; gp-ipm@0 and gp-ipm@1.0 (nothing / everything inspected) end the random
# line at x = 0 and 1. Per seed: accuracies.
TOY = {
    ("gp-ipm@0.0", 0): (0.5, 0.6),
    ("gp-ipm@0.5", 5): (0.8, 0.7),
    ("gp-ipm@1.0", 10): (0.9, 0.9),
    ("random-inspect@0.5", 5): (0.6, 0.7),
}


def _toy(extra: dict | None = None) -> list[dict]:
    runs = {**TOY, **(extra or {})}
    return [
        _ep(policy, seed, acc, inspections)
        for (policy, inspections), accs in runs.items()
        for seed, acc in enumerate(accs)
    ]


def _by_hand() -> list[float]:
    """The per-seed score: trapezoids of the family minus the random line over [0, 1]."""
    scores = []
    for s in (0, 1):
        a0, a05, a1 = (
            TOY[k][s] for k in (("gp-ipm@0.0", 0), ("gp-ipm@0.5", 5), ("gp-ipm@1.0", 10))
        )
        r05 = TOY["random-inspect@0.5", 5][s]
        family = 0.5 * (a0 + a05) / 2 + 0.5 * (a05 + a1) / 2
        line = 0.5 * (a0 + r05) / 2 + 0.5 * (r05 + a1) / 2
        scores.append((family - line) / 1.0)
    return scores  # [0.1, 0.0]


def test_score_equals_the_trapezoid_by_hand():
    s0, s1 = _by_hand()
    score = curve(_toy())["cluttered"]["gp-ipm"]["score"]
    assert score["mean"] == pytest.approx((s0 + s1) / 2)
    assert (s0, s1) == pytest.approx((0.1, 0.0))
    assert score["ci_low"] == pytest.approx(0.0) and score["ci_high"] == pytest.approx(0.1)
    assert score["p_vs_random_inspect"] == pytest.approx(1.0)  # exact: one seed gains nothing
    assert score["n"] == 2 and score["x_range"] == [0.0, 1.0] and score["note"] is None
    assert score["normalized"] is None  # no oracle-inspect in the run


def test_normalized_by_oracle_gain():
    eps = _toy({("oracle-inspect", 2): (1.0, 0.9)})  # x = 0.2
    score = curve(eps)["cluttered"]["gp-ipm"]["score"]
    gains = [1.0 - (0.5 + 0.4 * (0.6 - 0.5)), 0.9 - (0.6 + 0.4 * (0.7 - 0.6))]
    assert score["normalized"] == pytest.approx(sum(_by_hand()) / sum(gains))


def test_range_is_clipped_to_the_random_line():
    # the family reaches x = 0.8, the random line (gp-ipm@0 and P = 0.5) only x = 0.5
    eps = _toy({("gp-ipm@0.8", 8): (0.85, 0.8)})
    eps = [e for e in eps if e["policy"] != "gp-ipm@1.0"]
    points = curve(eps)["cluttered"]["gp-ipm"]["points"]
    assert max(p["inspections_per_object"] for p in points) == pytest.approx(0.8)
    score = curve(eps)["cluttered"]["gp-ipm"]["score"]
    assert score["x_range"] == [0.0, 0.5]
    assert score["mean"] == pytest.approx(((0.8 - 0.6) / 2 + (0.7 - 0.7) / 2) / 2)


def test_pairing_drops_seeds_missing_for_a_policy():
    eps = _toy()
    extra = [_ep(p, 2, 0.0 if p == "gp-ipm@1.0" else 1.0, i) for (p, i) in TOY if p != "gp-ipm@0.5"]
    score = curve(eps + extra)["cluttered"]["gp-ipm"]["score"]
    assert score["n"] == 2
    assert score["mean"] == pytest.approx(sum(_by_hand()) / 2)
    point = next(p for p in curve(eps + extra)["cluttered"]["gp-ipm"]["points"] if p["n"] == 3)
    assert point["policy"] in ("gp-ipm@0.0", "gp-ipm@1.0")  # the points keep all their seeds


def test_curve_keys_and_families():
    eps = _toy({("oracle-inspect", 2): (1.0, 0.9), ("random", 0): (0.2, 0.3)})
    eps += [_ep("gp-ipm", s, 0.8, 4, threshold=0.7) for s in (0, 1)]
    eps += [_ep("oracle", s, 1.0, 0) for s in (0, 1)]
    out = json.loads(json.dumps(curve(eps), allow_nan=False))
    fams = out["cluttered"]
    assert list(fams) == ["gp-ipm", "random-inspect", "oracle-inspect", "random"]
    point_keys = {"policy", "threshold", "validated", "inspections_per_object"}
    point_keys |= {"accuracy_mean", "ci_low", "ci_high", "n"}
    score_keys = {"mean", "ci_low", "ci_high", "p_vs_random_inspect", "normalized", "n"}
    score_keys |= {"x_range", "note"}
    for name, fam in fams.items():
        assert set(fam) == {"points", "score"}
        assert all(set(p) == point_keys for p in fam["points"])
        xs = [p["inspections_per_object"] for p in fam["points"]]
        assert xs == sorted(xs)
        assert (fam["score"] is None) == (name != "gp-ipm")
    assert set(fams["gp-ipm"]["score"]) == score_keys
    validated = [p for p in fams["gp-ipm"]["points"] if p["validated"]]
    assert len(validated) == 1 and validated[0]["threshold"] == 0.7
    assert validated[0]["inspections_per_object"] == pytest.approx(0.4)
    assert [p["threshold"] for p in fams["random-inspect"]["points"]] == [0.5]
    assert fams["random"]["points"][0]["inspections_per_object"] == 0.0


def test_score_needs_a_random_line():
    eps = [e for e in _toy() if e["policy"] not in ("random-inspect@0.5", "gp-ipm@1.0")]
    score = curve(eps)["cluttered"]["gp-ipm"]["score"]
    assert score["mean"] is None and "random-inspection line" in score["note"]


def test_duplicate_seed_is_rejected():
    with pytest.raises(ValueError, match="two episodes"):
        curve(_toy() + _toy()[:1])


def _inspect(first: str, final: str, truth: str | None) -> dict:
    return {"kind": "inspect", "first_label": first, "label": final, "true_category": truth}


def test_decomposition_counts():
    decisions = [
        _inspect("bowl", "mug", "mug"),  # fixed
        _inspect("mug", "bowl", "mug"),  # broken
        _inspect("mug", "mug", "mug"),  # right both times
        _inspect("bowl", "bowl", "mug"),  # wrong both times
        _inspect("bowl", "mug", None),  # truth unknown
        {"kind": "place", "first_label": "bowl", "label": "mug", "true_category": "mug"},
    ]
    eps = [
        _ep("gp-ipm@0.5", 0, 0.5, 5, decisions=decisions, dropped=2, left=1),
        _ep("gp-ipm@0.5", 1, 0.5, 0, dropped=0, left=0),
        _ep("gp-ipm@0.0", 0, 0.5, 0, dropped=1, left=0),
        _ep("random", 0, 0.1, 0, dropped=3),
    ]
    out = decomposition(eps)["cluttered"]
    row = out["gp-ipm@0.5"]
    assert row["fixed"] == 0.5 and row["broken"] == 0.5 and row["unknown"] == 0.5
    assert row["lost"] == 2.0 and row["lost_baseline"] == "gp-ipm@0.0" and row["lost_n"] == 1
    assert out["gp-ipm@0.0"]["lost"] == 0.0
    assert out["random"]["lost"] is None and out["random"]["lost_baseline"] is None


def test_decomposition_falls_back_to_random_inspect_at_zero():
    eps = [
        _ep("svm-ipm@0.5", 0, 0.5, 3, left=2),
        _ep("random-inspect@0.0", 0, 0.5, 0, left=1),
        _ep("oracle-inspect", 0, 0.9, 2, dropped=1),
    ]
    out = decomposition(eps)["cluttered"]
    assert out["svm-ipm@0.5"]["lost"] == 1.0
    assert out["oracle-inspect"]["lost_baseline"] == "random-inspect@0.0"


def test_write_curve(tmp_path):
    eps = _toy({("oracle-inspect", 2): (1.0, 0.9), ("random", 0): (0.2, 0.3)})
    result = write_curve(eps, tmp_path / "report")
    assert result["png"].read_bytes()[:8] == PNG_MAGIC
    assert json.loads(result["json"].read_text()) == result["curve"]
    text = "\n".join(result["lines"])
    assert "### cluttered" in text and "`gp-ipm`, mean gain over random inspection" in text
    assert "+5.0 points" in text and "What inspection did" in text and "(curve.png)" in text
    with pytest.raises(ValueError, match="at least one"):
        write_curve([], tmp_path)


def _accuracy_per_seed(episodes: list[dict]) -> dict:
    out: dict = {}
    for e in episodes:
        out.setdefault(e["scene"], {}).setdefault(e["policy"], {})[str(e["seed"])] = e["accuracy"]
    return out


def test_per_seed_scores_from_data_files_equal_the_curves_score():
    eps = _toy({("oracle-inspect", 2): (1.0, 0.9), ("gp-ipm@0.8", 8): (0.85, 0.8)})
    data = json.loads(json.dumps(curve(eps)))  # as read back from curve.json
    scores = per_seed_scores(data, _accuracy_per_seed(eps))
    assert list(scores) == ["cluttered"] and list(scores["cluttered"]) == ["gp-ipm"]
    per_seed = scores["cluttered"]["gp-ipm"]
    assert sorted(per_seed) == [0, 1]
    assert sum(per_seed.values()) / 2 == pytest.approx(data["cluttered"]["gp-ipm"]["score"]["mean"])


def test_per_seed_scores_by_hand_and_none_without_a_line():
    eps = _toy()
    per_seed = per_seed_scores(curve(eps), _accuracy_per_seed(eps))["cluttered"]["gp-ipm"]
    assert [per_seed[0], per_seed[1]] == pytest.approx(_by_hand())
    no_line = [e for e in eps if e["policy"] != "random-inspect@0.5"]
    no_line = [e for e in no_line if e["policy"] != "gp-ipm@1.0"]
    assert per_seed_scores(curve(no_line), _accuracy_per_seed(no_line)) == {}
