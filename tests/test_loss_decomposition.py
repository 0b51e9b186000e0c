"""The per-episode loss decomposition: where the objects not sorted right were
lost — to labels (the aimed object, into a wrong bin) or to handling (another object into a
wrong bin, dropped, left) — in the episode records, ``summary.json`` and ``sorting.md``."""

from __future__ import annotations

import json

import numpy as np
import pytest
from small_models import small_models

import ipbench.eval.sorting.evaluate as sorting
from ipbench.eval.sorting.evaluate import SortingEvalConfig, Task
from ipbench.eval.sorting.report import LOSSES, loss_decomposition, write_report
from ipbench.policies.oracle import true_category, true_object

FAST = SortingEvalConfig(scenes=("uncluttered",), seeds=(0,), steps_per_object=1)
CATS = ["mug", "bowl", "mug", "juice_box"]
T, H, A, D = "on_table", "in_hand", "in_inspection_area", "dropped"


def _bin(category: str) -> str:
    return f"in_bin:{category}"


def _check_totals(record: dict) -> None:
    losses = record["losses"]
    assert set(losses) == set(LOSSES)
    assert sum(losses.values()) == record["objects"] - record["correct"]
    assert losses["label"] + losses["wrong_object"] == record["wrong_bin"]
    assert losses["dropped"] == record["dropped"] and losses["left"] == record["left"]


# -- the classification, on hand-made status sequences -------------------------------------------
def test_the_aimed_object_in_a_wrong_bin_is_a_label_loss() -> None:
    start = [T, T, T, T]
    losses = loss_decomposition(CATS, [start, [_bin("bowl"), T, T, T]], [0])
    assert losses == {"label": 1, "wrong_object": 0, "misplaced": 0, "dropped": 0, "left": 3}


def test_a_neighbour_taken_into_a_wrong_bin_is_a_wrong_object_loss() -> None:
    start = [T, T, T, T]
    # aimed at 0, took 1 (a bowl) into the mug bin
    losses = loss_decomposition(CATS, [start, [T, _bin("mug"), T, T]], [0])
    assert losses == {"label": 0, "wrong_object": 1, "misplaced": 0, "dropped": 0, "left": 3}
    # the aimed object and a neighbour dragged along, both into the juice-box bin
    both = loss_decomposition(CATS, [start, [_bin("juice_box"), _bin("juice_box"), T, T]], [0])
    assert both == {"label": 1, "wrong_object": 1, "misplaced": 0, "dropped": 0, "left": 2}
    # no aimed object (background pixels) or no decision: whatever went into a wrong bin
    assert loss_decomposition(CATS, [start, [_bin("bowl"), T, T, T]], [None])["wrong_object"] == 1


def test_the_aimed_object_falling_into_another_bin_than_sent_to_is_misplaced() -> None:
    """Sent to its own bin (the label was right), it tipped over into the neighbouring one."""
    start = [T, T, T, T]
    rows = [start, [_bin("bowl"), T, T, T]]
    losses = loss_decomposition(CATS, rows, [0], [CATS[0]])
    assert losses["misplaced"] == 1 and losses["label"] == 0
    assert loss_decomposition(CATS, rows, [0], ["bowl"])["label"] == 1  # sent there: label
    with pytest.raises(ValueError, match="bins"):
        loss_decomposition(CATS, rows, [0], [])


def test_a_wrong_object_carried_into_its_own_bin_is_correct() -> None:
    start = [T, T, T, T]
    # aimed at 0 (a mug), labelled bowl, took 1 (a bowl) into the bowl bin: right by luck
    losses = loss_decomposition(CATS, [start, [T, _bin("bowl"), T, T]], [0])
    assert losses == {"label": 0, "wrong_object": 0, "misplaced": 0, "dropped": 0, "left": 3}


def test_inspections_are_attributed_to_the_decision_that_picked() -> None:
    start = [T, T, T, T]
    # in hand: pick 2 (aimed 2), two turns, place into the bowl bin: the label's fault
    hand = [start, [T, T, H, T], [T, T, H, T], [T, T, H, T], [T, T, _bin("bowl"), T]]
    assert loss_decomposition(CATS, hand, [2, 2, 2, 2])["label"] == 1
    # in the area: aimed at 0, took 3 (a juice box) to the area, views, into the mug bin
    area = [start, [T, T, T, A], [T, T, T, A], [T, T, T, _bin("mug")]]
    assert loss_decomposition(CATS, area, [0, 0, 0]) == {
        "label": 0,
        "wrong_object": 1,
        "misplaced": 0,
        "dropped": 0,
        "left": 3,
    }
    # it slipped out of the hand onto the table; a later decision aimed at it, wrong bin
    slip = [start, [H, T, T, T], [T, T, T, T], [_bin("bowl"), T, T, T]]
    assert loss_decomposition(CATS, slip, [0, 0, 0])["label"] == 1
    # it slipped, a decision aimed at its neighbour knocked it into a wrong bin
    assert loss_decomposition(CATS, slip, [0, 0, 1])["wrong_object"] == 1


def test_dropped_and_left_and_the_totals() -> None:
    final = [D, _bin("bowl"), A, H]
    losses = loss_decomposition(CATS, [[T, T, T, T], final], [1])
    assert losses == {
        "label": 0,
        "wrong_object": 0,
        "misplaced": 0,
        "dropped": 1,
        "left": 2,
    }  # 1: correct
    # the last change counts: in a wrong bin at first, then knocked out onto the floor
    moved = [[T] * 4, [_bin("bowl"), T, T, T], [D, T, T, T]]
    assert loss_decomposition(CATS, moved, [0, 1]) == {
        "label": 0,
        "wrong_object": 0,
        "misplaced": 0,
        "dropped": 1,
        "left": 3,
    }
    rng = np.random.default_rng(0)
    statuses = [T, H, A, D, *(_bin(c) for c in ("mug", "bowl", "juice_box", "milk_carton"))]
    for _ in range(200):  # random histories: the four always add up to the objects lost
        rows = [[T] * 4] + [list(rng.choice(statuses, 4)) for _ in range(rng.integers(1, 6))]
        aims = [None if a < 0 else int(a) for a in rng.integers(-1, 4, len(rows) - 1)]
        losses = loss_decomposition(CATS, rows, aims)
        wrong = sum(s != _bin(c) for s, c in zip(rows[-1], CATS, strict=True))
        assert sum(losses.values()) == wrong


def test_bad_histories_are_refused() -> None:
    with pytest.raises(ValueError, match="one status row"):
        loss_decomposition(CATS, [[T] * 4], [0])
    with pytest.raises(ValueError, match="one status row"):
        loss_decomposition(CATS, [[T] * 4, [T] * 3], [0])
    with pytest.raises(ValueError, match="unknown status"):
        loss_decomposition(CATS, [[T] * 4, [T, T, T, "flying"]], [0])


def test_true_category_is_the_category_of_true_object() -> None:
    mask = np.array([[-1, 0, 1], [1, 1, -1]], np.int16)
    info = {"wrist_mask": mask, "objects": {0: {"category": "mug"}, 1: {"category": "bowl"}}}
    assert true_object([0, 1, 2, 3, 4], info) == 1 and true_category([0, 1, 2, 3], info) == "bowl"
    assert true_object([1], info) == 0 and true_category([1], info) == "mug"
    assert true_object([0, 5], info) is None and true_category([0, 5], info) is None


# -- real episodes ---------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def models():
    return small_models((500, 501, 502), 32, 0.5)


@pytest.mark.parametrize("policy", ["oracle", "random"])
def test_the_decomposition_adds_up_on_real_episodes(policy: str, models) -> None:
    record = sorting.run_episode(Task("uncluttered", policy, 1), models, FAST)
    _check_totals(record)
    json.dumps(record)
    if policy == "oracle":  # true labels: no object is lost to its label
        assert record["losses"]["label"] == 0


# -- the report ------------------------------------------------------------------------------------
def _record(policy: str, seed: int, losses: dict | None, objects: int = 10) -> dict:
    lost = 0 if losses is None else sum(losses.values())
    correct = objects - (lost if losses is not None else 2)
    record = {
        "scene": "cluttered",
        "policy": policy,
        "seed": seed,
        "objects": objects,
        "correct": correct,
        "accuracy": correct / objects,
        "per_category": {"mug": {"total": objects, "correct": correct}},
        "inspections": 0,
        "grasp_failures": 1,
        "wall_time_s": 1.0,
        "sim_time_s": 4.0,
        "decisions": [],
        "dropped": 0 if losses is None else losses["dropped"],
    }
    if losses is not None:
        record["losses"] = losses
    return record


def _losses(label=0, wrong_object=0, dropped=0, left=0, misplaced=0) -> dict:
    return {
        "label": label,
        "wrong_object": wrong_object,
        "misplaced": misplaced,
        "dropped": dropped,
        "left": left,
    }


def test_the_report_has_the_table_and_the_summary_the_keys(tmp_path) -> None:
    episodes = [
        _record("gp-ipm", 0, _losses(label=1, dropped=1)),
        _record("gp-ipm", 1, _losses(wrong_object=2, left=1)),
        _record("random", 0, _losses(label=3, left=1)),
        _record("random", 1, _losses(label=2, wrong_object=1)),
        _record("oracle", 0, None),  # an old record: no decomposition for its cell
    ]
    paths = write_report(episodes, tmp_path)
    md = paths.markdown.read_text()
    assert "### Where the objects were lost" in md
    assert "| policy | label | wrong object | misplaced | dropped | left |" in md
    assert "| gp-ipm | 0.5 (5.0 %) | 1.0 (10.0 %) | 0.0 (0.0 %) | 0.5 (5.0 %) | 0.5 (5.0 %) |" in md
    assert "| random | 2.5 (25.0 %) | 0.5 (5.0 %) | 0.0 (0.0 %) | 0.0 (0.0 %) | 0.5 (5.0 %) |" in md
    assert "| oracle | 0.0" not in md
    assert "No loss decomposition for `oracle` (1 of 1 episodes without one)" in md
    assert "`label`: the grasp took the object it aimed at" in md

    summary = json.loads(paths.summary.read_text())
    required = {"accuracy_mean", "ci_low", "ci_high", "n", "grasp_failures_mean"}
    required |= {"dropped_fraction", "losses_mean"}
    for cell in summary["cluttered"].values():
        assert required <= set(cell)
    gp = summary["cluttered"]["gp-ipm"]
    assert gp["losses_mean"] == {
        "label": 0.5,
        "wrong_object": 1.0,
        "misplaced": 0,
        "dropped": 0.5,
        "left": 0.5,
    }
    assert gp["dropped_fraction"] == pytest.approx(1 / 20)
    assert summary["cluttered"]["oracle"]["losses_mean"] is None
    assert summary["cluttered"]["oracle"]["losses_missing"] == 1


def test_the_report_refuses_losses_that_do_not_add_up(tmp_path) -> None:
    bad = _record("random", 0, _losses(label=1))
    bad["correct"] -= 1  # two objects lost, one accounted for
    with pytest.raises(ValueError, match="do not add up"):
        write_report([bad], tmp_path)
    bad["losses"] = {"label": 2}
    with pytest.raises(ValueError, match="losses must have the keys"):
        write_report([bad], tmp_path)
