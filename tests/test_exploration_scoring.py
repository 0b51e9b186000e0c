"""Scoring rules of exploration reports (envs/exploration_scoring.py)."""

from __future__ import annotations

import pytest

from ipbench.envs.exploration_scoring import (
    GroundTruthObject,
    Scorer,
    ScoringError,
    performance,
)

LABELS = ("a", "b", "c")


def _scene():
    return [
        GroundTruthObject("o0", "a", (0.0, 0.0, 0.0), 0.1),
        GroundTruthObject("o1", "a", (1.0, 0.0, 0.0), 0.1),
        GroundTruthObject("o2", "b", (0.0, 1.0, 0.0), 0.1),
        GroundTruthObject("o3", None, (2.0, 0.0, 0.0), 0.1),  # a distractor
    ]


def test_table_3_2_arithmetic():
    # 63 database instances: 56 found, 7 never reported; 5 false reports
    objects = [GroundTruthObject(f"o{k}", "a", (float(k), 0.0, 0.0), 0.1) for k in range(63)]
    scorer = Scorer(objects, LABELS)
    for k in range(56):
        assert scorer.report("a", (float(k), 0.0, 0.05)).kind == "true_positive"
    for k in range(5):
        assert scorer.report("a", (float(k), 5.0, 0.0)).kind == "false_positive"
    s = scorer.score
    assert (s.true_positives, s.false_positives, s.not_found) == (56, 5, 7)
    assert round(100 * s.performance, 1) == 82.4
    assert performance(56, 5, 7) == pytest.approx(56 / 68)


def test_true_positive_needs_the_class_and_the_hit_radius():
    scorer = Scorer(_scene(), LABELS)
    out = scorer.report("a", (0.99, 0.0, 0.05))
    assert (out.kind, out.instance) == ("true_positive", "o1")
    assert scorer.report("a", (0.0, 0.0, 0.11)).reason == "nothing_there"  # just outside
    assert scorer.score.true_positives == 1 and scorer.score.false_positives == 1


def test_wrong_class_nothing_there_and_second_report_are_false_positives():
    scorer = Scorer(_scene(), LABELS)
    wrong = scorer.report("b", (0.0, 0.0, 0.0))
    assert (wrong.kind, wrong.reason, wrong.instance) == ("false_positive", "wrong_class", "o0")
    assert scorer.report("a", (2.0, 0.0, 0.0)).reason == "wrong_class"  # a distractor
    assert scorer.report("c", (5.0, 5.0, 5.0)).reason == "nothing_there"
    assert scorer.report("b", (0.0, 1.0, 0.0)).kind == "true_positive"
    again = scorer.report("b", (0.0, 1.0, 0.0))
    assert (again.reason, again.instance) == ("already_reported", "o2")
    assert scorer.score.false_positives == 4 and scorer.score.true_positives == 1


def test_two_instances_of_a_class_are_two_true_positives():
    scorer = Scorer(_scene(), LABELS)
    assert scorer.report("a", (0.0, 0.0, 0.0)).instance == "o0"
    assert scorer.report("a", (1.0, 0.0, 0.0)).instance == "o1"
    assert scorer.score.true_positives == 2


def test_not_found_counts_database_instances_only():
    scorer = Scorer(_scene(), LABELS)
    assert scorer.score.not_found == 3  # o0, o1, o2; never the distractor
    scorer.report("a", (0.0, 0.0, 0.0))
    s = scorer.score
    assert s.not_found == 2 and s.performance == pytest.approx(1 / 3)
    assert s.as_dict()["performance"] == s.performance


def test_nothing_to_find_and_nothing_reported_is_perfect():
    assert Scorer([], LABELS).score.performance == 1.0


def test_bad_input_is_a_clear_error():
    with pytest.raises(ScoringError, match="valid: a, b, c"):
        Scorer(_scene(), LABELS).report("z", (0.0, 0.0, 0.0))
    with pytest.raises(ScoringError, match="3 finite floats"):
        Scorer(_scene(), LABELS).report("a", (0.0, 0.0))
    with pytest.raises(ScoringError, match="unique"):
        Scorer(_scene() + _scene()[:1], LABELS)
    with pytest.raises(ScoringError, match="unknown object label"):
        Scorer([GroundTruthObject("x", "q", (0, 0, 0), 0.1)], LABELS)
