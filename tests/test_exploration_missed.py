"""Where the objects not found were lost: each cause by hand on a fake look, the order in which
causes are assigned, the records' optional field and the report's table."""

from __future__ import annotations

import copy
from types import SimpleNamespace

import numpy as np
import pytest

from ipbench.envs.exploration_scene import DATABASE_CLASSES
from ipbench.eval.exploration.missed import (
    MISSED_CAUSES,
    InstanceHistory,
    MissedTracker,
    known_objects,
)
from ipbench.eval.exploration.records import ExplorationReportError, check_record
from ipbench.eval.exploration.report import summarize_exploration, write_exploration_report
from ipbench.perception.saliency import InhibitionMap
from ipbench.policies.exploration import Fixation, same_object_m
from tests.exploration_records import episode_record

A, B = DATABASE_CLASSES[0], DATABASE_CLASSES[1]
CAMERA = np.array([0.0, 0.0, 0.5])


def _scene():
    """A camera at (0, 0, 0.5) looking along +x; instances of A and B at 1 m, 20 deg apart, an A
    out of view and a distractor."""
    side = np.radians(20.0)
    objects = {
        "a": {"class": A, "position": np.array([1.0, 0.0, 0.5])},
        "b": {"class": B, "position": np.array([np.cos(side), np.sin(side), 0.5])},
        "unseen": {"class": A, "position": np.array([-1.0, 0.0, 0.5])},
        "distractor": {"class": None, "position": np.array([1.0, -0.3, 0.5])},
    }
    pose = np.eye(4)
    pose[:3, 2] = (1.0, 0.0, 0.0)
    pose[:3, 3] = CAMERA
    mask = np.full((4, 4), -1, np.int32)
    mask[0, :2], mask[1, :2], mask[2, :2] = 0, 1, 3  # a, b, distractor in view
    return objects, {"head_left_pose": pose}, {"objects": objects, "head_left_mask": mask}


def _candidate(label, position):
    return SimpleNamespace(label=label, position=np.asarray(position, float))


def _policy(candidates=(), reported=(), inhibited=(), attending=None, last_kind="object"):
    """What the tracker reads of a policy after its act."""
    inhibition = InhibitionMap()
    for d in inhibited:
        inhibition.add(np.asarray(d, float))
    return SimpleNamespace(
        last_look=SimpleNamespace(candidates=tuple(candidates)),
        reported=list(reported),
        queue=[],
        inhibition=inhibition,
        fixations=[Fixation(last_kind, None, [1.0, 0.0, 0.0])],
        attending=attending,
    )


def _causes(policy, found=(), mistaken=(), looks=1):
    objects, obs, info = _scene()
    tracker = MissedTracker(objects)
    for _ in range(looks):
        tracker.look(policy, obs, info, known_objects(policy))
    return tracker.missed(found, mistaken)


def _only(**counts):
    return {c: counts.get(c, 0) for c in MISSED_CAUSES}


def test_in_view_and_recognised_by_hand():
    objects, _, _ = _scene()
    a, b = objects["a"]["position"], objects["b"]["position"]
    # nothing recognised: a and b were in view, "unseen" never; the distractor is no instance
    assert _causes(_policy()) == _only(never_in_view=1, never_recognised=2)
    # a recognised as a new object, b's class seen too far from b
    far_b = b + [0.0, 2.0 * same_object_m(B), 0.0]
    got = _causes(_policy([_candidate(A, a), _candidate(B, far_b)]))
    assert got == _only(never_in_view=1, never_recognised=1, not_attended=1)
    # a candidate of the wrong class on a recognises nothing
    got = _causes(_policy([_candidate(B, a)]))
    assert got == _only(never_in_view=1, never_recognised=2)
    # found instances have no cause; a report of the wrong class takes precedence
    assert _causes(_policy(), found=["a", "b"]) == _only(never_in_view=1)
    assert _causes(_policy(), mistaken=["unseen"]) == _only(wrong_class=1, never_recognised=2)


def test_taken_for_reported_inhibited_and_attended():
    objects, _, _ = _scene()
    a = objects["a"]["position"]
    near = a + [0.0, 0.5 * same_object_m(A), 0.0]  # within same_object_m of a
    # an A already reported next to a: its candidate is taken for that object
    got = _causes(_policy([_candidate(A, a)], reported=[(A, near)]))
    assert got["taken_for_reported"] == 1 and got["not_attended"] == 0
    # reported far away, or of another class: a is new
    far = a + [0.0, 2.0 * same_object_m(A), 0.0]
    assert _causes(_policy([_candidate(A, a)], reported=[(A, far)]))["not_attended"] == 1
    assert _causes(_policy([_candidate(A, a)], reported=[(B, near)]))["not_attended"] == 1
    # a's direction inhibited when the policy chose: inhibited
    looking_at_a = a - CAMERA
    got = _causes(_policy([_candidate(A, a)], inhibited=[looking_at_a]))
    assert got["inhibited"] == 1 and got["not_attended"] == 0
    # ... except when that inhibition is the salient place the policy chose after it
    got = _causes(_policy([_candidate(A, a)], inhibited=[looking_at_a], last_kind="salient"))
    assert got["not_attended"] == 1
    # an inhibited direction 20 deg away (b's) does not inhibit a
    got = _causes(_policy([_candidate(A, a)], inhibited=[objects["b"]["position"] - CAMERA]))
    assert got["not_attended"] == 1
    # a policy without an inhibition map inhibits nothing
    plain = _policy([_candidate(A, a)], inhibited=[looking_at_a])
    del plain.inhibition
    assert _causes(plain)["not_attended"] == 1
    # attended (the policy's hypothesis is a's), never verified
    got = _causes(_policy([_candidate(A, a)], inhibited=[looking_at_a], attending=_candidate(A, a)))
    assert got["attended_not_verified"] == 1 and got["inhibited"] == 0


def test_the_first_cause_that_holds_is_taken():
    order = list(MISSED_CAUSES)
    histories = [
        (InstanceHistory(), True),
        (InstanceHistory(), False),
        (InstanceHistory(in_view=3), False),
        (InstanceHistory(in_view=3, recognised=2, as_new=1, inhibited=1, attended=1), False),
        (InstanceHistory(in_view=3, recognised=2, as_new=1, inhibited=1), False),
        (InstanceHistory(in_view=3, recognised=2, as_new=1, taken_for_reported=1), False),
        (InstanceHistory(in_view=3, recognised=2, taken_for_reported=2), False),
    ]
    assert [h.cause(m) for h, m in histories] == order
    # looks add up per instance
    objects, _, _ = _scene()
    tracker = MissedTracker(objects)
    _, obs, info = _scene()
    policy = _policy([_candidate(A, objects["a"]["position"])])
    for _ in range(3):
        tracker.look(policy, obs, info, [])
    assert (tracker.history["a"].in_view, tracker.history["a"].as_new) == (3, 3)
    assert tracker.history["unseen"].in_view == 0 and "distractor" not in tracker.history


def test_known_objects_are_reported_and_queued_ones():
    policy = _policy(reported=[(A, [1.0, 0.0, 0.0])])
    policy.queue = [_candidate(B, [0.0, 1.0, 0.0])]
    got = known_objects(policy)
    assert [g[0] for g in got] == [A, B]
    assert np.allclose(got[1][1], [0.0, 1.0, 0.0])


def _records():
    causes = _only(never_recognised=1, inhibited=2)
    return [
        episode_record("complex", "active-vision", "sift", s, 5, 0, 3, [0.0, 1.0], missed=causes)
        for s in range(3)
    ] + [episode_record("complex", "random-gaze", "sift", 0, 5, 0, 3, [0.0, 1.0])]


def test_records_carry_missed_or_not_and_it_must_add_up():
    good = _records()[0]
    check_record(good, 0)
    check_record(_records()[-1], 0)  # optional
    wrong_sum = copy.deepcopy(good)
    wrong_sum["missed"]["inhibited"] = 1
    with pytest.raises(ExplorationReportError, match="does not add up to not_found = 3"):
        check_record(wrong_sum, 0)
    unknown = copy.deepcopy(good)
    unknown["missed"]["lost_in_space"] = 0
    with pytest.raises(ExplorationReportError, match="missed must map each of wrong_class"):
        check_record(unknown, 0)
    negative = copy.deepcopy(good)
    negative["missed"].update(inhibited=3, never_recognised=-1, not_attended=1)
    with pytest.raises(ExplorationReportError, match="int >= 0"):
        check_record(negative, 0)


def test_the_report_sums_causes_and_tables_them(tmp_path):
    summary = summarize_exploration(_records(), budget=30)
    cell = summary["complex"]["active-vision"]["sift"]["missed"]
    assert cell == {"episodes": 3, "causes": _only(never_recognised=3, inhibited=6)}
    assert "missed" not in summary["complex"]["random-gaze"]["sift"]
    write_exploration_report(_records(), tmp_path, budget=30)
    text = (tmp_path / "exploration.md").read_text()
    assert "## Where the objects not found were lost" in text
    row = next(line for line in text.splitlines() if line.startswith("| complex | sift | active"))
    assert "| 9 |" in row and "67 % (6)" in row and "33 % (3)" in row
