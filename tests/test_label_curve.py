"""The label curve read off an inspect-everything run, on scripted decisions."""

from __future__ import annotations

import pytest

from ipbench.eval.sorting.label_curve import label_curve


def _d(conf: float, first: str, final: str, truth: str | None, views: int = 3) -> dict:
    return {
        "first_confidence": conf, "first_label": first, "label": final,
        "true_category": truth, "views": views, "kind": "inspect",
    }  # fmt: skip


def test_each_threshold_takes_the_first_label_above_it_and_the_inspected_one_below() -> None:
    decisions = [
        _d(0.9, "mug", "bowl", "mug"),  # right first, broken by inspection
        _d(0.6, "bowl", "mug", "mug"),  # wrong first, fixed by inspection
        _d(0.3, "bowl", "bowl", "mug"),  # wrong both ways
        _d(0.2, "mug", "bowl", "mug", views=0),  # the inspection failed: the first label
        _d(0.5, "mug", "mug", None),  # no truth: left out
    ]
    everything = {"scene": "cluttered", "policy": "gp-ipm@1.0", "decisions": decisions}
    half = {"scene": "cluttered", "policy": "gp-ipm@0.5", "decisions": decisions[:2]}
    other = {"scene": "cluttered", "policy": "svm-ipm@1.0", "decisions": decisions}
    curve = label_curve([everything, half, other])["cluttered"]
    at = dict(zip(curve["thresholds"], curve["label_accuracy"], strict=True))
    inspected = dict(zip(curve["thresholds"], curve["inspected_fraction"], strict=True))
    assert curve["decisions"] == 4
    assert at[0.0] == pytest.approx(2 / 4) and inspected[0.0] == 0.0  # first labels
    assert at[0.65] == pytest.approx(3 / 4) and inspected[0.65] == pytest.approx(3 / 4)
    assert at[1.0] == pytest.approx(2 / 4) and inspected[1.0] == 1.0  # the 0.9 one broken
    assert [m["threshold"] for m in curve["measured"]] == [0.5, 1.0]
    assert curve["measured"][0]["label_accuracy"] == pytest.approx(1 / 2)


def test_scenes_without_an_inspect_everything_run_are_left_out() -> None:
    run = {"scene": "uncluttered", "policy": "gp-ipm@0.5", "decisions": []}
    assert label_curve([run]) == {}


def test_the_lines_set_each_measured_run_beside_the_labels_read_off() -> None:
    from ipbench.eval.sorting.label_curve import label_curve_lines

    decisions = [_d(0.9, "mug", "mug", "mug"), _d(0.4, "bowl", "mug", "mug")]
    runs = [
        {"scene": "uncluttered", "policy": p, "decisions": decisions}
        for p in ("gp-ipm@1.0", "gp-ipm@0.5")
    ]
    text = "\n".join(label_curve_lines(label_curve(runs)))
    assert "| uncluttered | 0.5 | 50.0 % | 100.0 % | 100.0 % |" in text
    assert label_curve_lines({}) == []
