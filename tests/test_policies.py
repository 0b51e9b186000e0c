"""Policies: view fusion, the threshold rule, grasp aiming, and the GP-IPM decision loop."""

from __future__ import annotations

import dataclasses
import importlib

import numpy as np
import pytest

from ipbench.envs.skills import SkillConfig
from ipbench.envs.sorting import MAX_JAW_OPENING
from ipbench.perception.segmentation import Segment
from ipbench.policies import POLICIES, PolicyError, make_policy
from ipbench.policies.base import place_action
from ipbench.policies.fusion import FusionError, bayes_fusion, fuse, majority_vote
from ipbench.policies.grasping.boxes import OPENING_MARGIN, TOP_MARGIN
from ipbench.policies.grasping.segments import (
    FailureMemory,
    completed_footprint,
    grasp_target,
    jaw_opening,
)
from ipbench.policies.interactive import InteractiveConfig, InteractiveSorter
from ipbench.policies.perceiver import Detection

CLASSES = ("juice_bottle", "milk_carton", "bowl", "mug", "juice_box")


@pytest.mark.parametrize(
    "name",
    [
        "ipbench.policies",
        "ipbench.policies.base",
        "ipbench.policies.fusion",
        "ipbench.policies.grasping",
        "ipbench.policies.grasping.boxes",
        "ipbench.policies.grasping.free",
        "ipbench.policies.grasping.segments",
        "ipbench.policies.interactive",
        "ipbench.policies.kinematics",
        "ipbench.policies.oracle",
        "ipbench.policies.perceiver",
        "ipbench.policies.random_sorting",
        "ipbench.policies.scripted",
        "ipbench.policies.threshold",
    ],
)
def test_export_lists_are_complete(name: str) -> None:
    module = importlib.import_module(name)
    for symbol in module.__all__:
        assert hasattr(module, symbol), f"{name}.__all__ names missing {symbol}"


def test_majority_vote_breaks_ties_by_the_highest_probability() -> None:
    views = np.array(
        [[0.6, 0.4, 0.0, 0.0, 0.0], [0.1, 0.9, 0.0, 0.0, 0.0], [0.5, 0.2, 0.3, 0.0, 0.0]]
    )
    assert majority_vote(views)[0] == 0  # two votes for class 0
    label, conf = majority_vote(views[:2])  # one vote each: 0.9 beats 0.6
    assert label == 1 and conf == pytest.approx(0.65)


def test_bayes_fusion_is_the_normalised_product() -> None:
    views = np.array([[0.6, 0.3, 0.1], [0.5, 0.4, 0.1]])
    expected = views.prod(axis=0) / views.prod(axis=0).sum()
    np.testing.assert_allclose(bayes_fusion(views), expected)
    label, conf = fuse(views, "bayes")
    assert label == 0 and conf == pytest.approx(expected[0])
    with pytest.raises(FusionError, match="majority, bayes"):
        fuse(views, "average")


def _segment(center, extent, yaw=0.0, top=0.95, height=0.2) -> Segment:
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    pts = np.asarray(center, float) + np.random.default_rng(0).uniform(-0.01, 0.01, (50, 3))
    return Segment(
        pts, np.arange(50), pts.mean(0), np.asarray(center, float), rot, np.asarray(extent, float),
        height, top,
    )  # fmt: skip


def test_footprint_is_completed_away_from_the_camera() -> None:
    """A cylinder of 8 cm seen from -x shows only its front 4 cm: the centre moves back."""
    seg = _segment([1.0, 0.0, 0.85], [0.08, 0.04, 0.2], yaw=np.pi / 2)  # x axis along world y
    centre, ext = completed_footprint(seg, np.array([0.5, 0.0, 1.3]))
    np.testing.assert_allclose(centre, [1.02, 0.0], atol=1e-9)  # 2 cm further from the camera
    np.testing.assert_allclose(np.sort(ext), [0.08, 0.08])
    target = grasp_target(seg, [], 0, np.array([0.5, 0.0, 1.3]))
    assert target.position[2] == pytest.approx(0.95 - 0.1)  # tall: the middle of its height
    turned = grasp_target(seg, [], 1, np.array([0.5, 0.0, 1.3]))
    assert (
        abs(abs(turned.yaw - target.yaw) - np.pi / 2) < 1e-6
        or abs(abs(turned.yaw - target.yaw) - 3 * np.pi / 2) < 1e-6
    )


def test_a_short_object_is_held_by_the_pads_just_under_its_top() -> None:
    """A 9 cm bowl: the skill takes the TCP (the pads' centre) ``grasp_depth`` below the
    position, so the position is raised by as much and the pads close TOP_MARGIN under the
    rim, not 2 cm lower on the sloping wall."""
    seg = _segment([1.0, 0.0, 0.80], [0.17, 0.17, 0.09], top=0.85, height=0.09)
    target = grasp_target(seg, [])
    tcp = target.position[2] - SkillConfig().grasp_depth
    assert tcp == pytest.approx(0.85 - TOP_MARGIN)


def test_jaws_open_to_the_width_across_them() -> None:
    """A 6 x 12 cm box closes across its 6 cm side, or its 12 cm side when turned; a wide
    blob is capped at the gripper's full opening."""
    seg = _segment([1.0, 0.0, 0.85], [0.06, 0.12, 0.2], yaw=0.3)
    narrow = grasp_target(seg, [])
    assert narrow.opening == pytest.approx(0.06 + OPENING_MARGIN)
    assert abs(np.cos(narrow.yaw - 0.3)) == pytest.approx(1.0)  # closes along the box x
    wide = grasp_target(seg, [], turn=1)
    assert wide.opening == pytest.approx(0.12 + OPENING_MARGIN)
    assert jaw_opening(seg, np.array([0.06, 0.12]), 0.3 + np.pi / 4) == pytest.approx(
        (0.06 + 0.12) / np.sqrt(2) + OPENING_MARGIN
    )
    blob = _segment([1.0, 0.0, 0.85], [0.3, 0.4, 0.2])
    assert grasp_target(blob, []).opening == MAX_JAW_OPENING
    action = place_action(narrow, "mug")
    assert action["opening"].shape == (1,) and action["opening"][0] == pytest.approx(0.11)


def test_failure_memory_groups_nearby_attempts() -> None:
    memory = FailureMemory(radius=0.04)
    memory.record(np.array([1.0, 0.0, 0.8]))
    memory.record(np.array([1.02, 0.01, 0.8]))
    assert memory.count(np.array([1.01, 0.0])) == 2
    assert memory.count(np.array([1.2, 0.0])) == 0


class _FakeKinematics:
    def __init__(self) -> None:
        self.opening = 0.07

    def jaw_opening(self, qpos) -> float:
        return self.opening


class _FakePerceiver:
    """Scene detections with given confidences; in-hand views from a queue."""

    classes = CLASSES

    def __init__(self, scene_probs, hand_probs) -> None:
        self.scene_probs = [np.asarray(p, float) for p in scene_probs]
        self.hand_probs = [np.asarray(p, float) for p in hand_probs]
        self.kinematics = _FakeKinematics()
        self.hand_calls = 0

    def _det(self, probs, x, inspected=False) -> Detection:
        seg = _segment([x, 0.0, 0.85], [0.08, 0.06, 0.2])
        return Detection(seg, probs, CLASSES, np.array([0.5, 0.0, 1.3]), inspected)

    def scene(self, observation):
        return [self._det(p, 0.8 + 0.15 * i) for i, p in enumerate(self.scene_probs)]

    def in_hand(self, observation):
        self.hand_calls += 1
        return self._det(self.hand_probs.pop(0), 0.6, inspected=True)


def test_gp_ipm_sorts_a_confident_object_at_once() -> None:
    perceiver = _FakePerceiver([[0.1, 0.1, 0.1, 0.6, 0.1], [0.9, 0.05, 0.05, 0, 0]], [])
    policy = InteractiveSorter(perceiver, InteractiveConfig(threshold=0.8))
    policy.reset(0)
    action = policy.act({"qpos": None})
    assert action["command"] == 0 and action["bin"] == 0  # the most confident, its bin
    assert policy.decisions[0].kind == "place" and policy.decisions[0].views == 0
    assert perceiver.hand_calls == 0


def test_gp_ipm_inspects_an_unsure_object_then_sorts_the_fused_label() -> None:
    unsure = [0.1, 0.1, 0.1, 0.6, 0.1]  # says mug, below the threshold
    views = [[0, 0.1, 0.8, 0.1, 0], [0, 0.1, 0.7, 0.2, 0], [0, 0.1, 0.2, 0.7, 0]]
    perceiver = _FakePerceiver([unsure], views)
    policy = InteractiveSorter(perceiver, InteractiveConfig(threshold=0.8, n_views=3))
    policy.reset(0)
    commands = [policy.act({"qpos": None})["command"] for _ in range(3)]
    assert commands == [2, 2, 2]  # pick into the hand, then two turns
    final = policy.act({"qpos": None})
    assert final["command"] == 0 and final["bin"] == CLASSES.index("bowl")  # 2 of 3 views
    d = policy.decisions[0]
    assert (d.kind, d.first_label, d.label, d.views) == ("inspect", "mug", "bowl", 3)
    assert perceiver.hand_calls == 3


def test_gp_ipm_gives_up_inspecting_when_the_hand_is_empty() -> None:
    perceiver = _FakePerceiver([[0.1, 0.1, 0.1, 0.6, 0.1]], [])
    policy = InteractiveSorter(perceiver, InteractiveConfig(threshold=0.8))
    policy.reset(0)
    assert policy.act({"qpos": None})["command"] == 2
    perceiver.kinematics.opening = 0.0  # the grasp failed
    action = policy.act({"qpos": None})  # looks at the table again, tries once more
    assert action["command"] == 2 and perceiver.hand_calls == 0
    assert policy.failures.count(np.array([0.8, 0.0])) == 1


class _AreaPerceiver(_FakePerceiver):
    """The object in the inspection area, seen where it lies there (x = 0.3 m)."""

    def in_area(self, observation):
        self.hand_calls += 1
        return self._det(self.hand_probs.pop(0), 0.3, inspected=True)


def test_gp_ipm_area_aims_at_the_object_in_the_area_not_its_old_table_place() -> None:
    """After the first command (pick from the table at x = 0.8), every command aims at the
    object in the area: when a re-pick from the area fails, the env grasps at ``position``,
    and the old table place may hold a neighbour by then."""
    unsure = [0.1, 0.1, 0.1, 0.6, 0.1]
    views = [[0, 0.1, 0.8, 0.1, 0], [0, 0.1, 0.7, 0.2, 0], [0, 0.1, 0.2, 0.7, 0]]
    perceiver = _AreaPerceiver([unsure], views)
    policy = InteractiveSorter(perceiver, InteractiveConfig(threshold=0.8, inspection="area"))
    policy.reset(0)
    first = policy.act({"qpos": None})
    assert first["command"] == 1 and first["position"][0] == pytest.approx(0.8, abs=0.03)
    turns = [policy.act({"qpos": None}) for _ in range(2)]
    final = policy.act({"qpos": None})
    seen = perceiver._det(unsure, 0.3)
    area_grasp = grasp_target(seen.segment, np.zeros((0, 3)), 0, seen.viewpoint)
    for action in (*turns, final):
        np.testing.assert_allclose(action["position"], area_grasp.position, atol=1e-6)
        assert action["opening"][0] == pytest.approx(area_grasp.opening, abs=1e-6)
    assert [a["command"] for a in turns] == [1, 1] and final["command"] == 0
    assert turns[0]["yaw"][0] == pytest.approx(np.radians(30.0), abs=1e-6)  # the turn
    assert final["yaw"][0] == pytest.approx(area_grasp.yaw, abs=1e-6)
    assert final["bin"] == CLASSES.index("bowl") and perceiver.hand_calls == 3


def test_unknown_policy_and_bad_settings_list_the_valid_options() -> None:
    with pytest.raises(PolicyError, match=", ".join(POLICIES)):
        make_policy("greedy", None)  # type: ignore[arg-type]
    with pytest.raises(PolicyError, match="hand, area"):
        InteractiveConfig(inspection="shelf")
    with pytest.raises(PolicyError, match=r"\[0, 1\]"):
        InteractiveConfig(threshold=1.5)


def test_an_object_is_given_up_after_repeated_failed_grasps() -> None:
    from ipbench.policies import NothingToSort

    perceiver = _FakePerceiver([[0.9, 0.05, 0.05, 0, 0]], [])
    policy = InteractiveSorter(perceiver, InteractiveConfig(threshold=0.5))
    policy.reset(0)
    yaws = []
    for _ in range(policy.max_attempts):  # the object stays where it was: each grasp failed
        yaws.append(float(policy.act({"qpos": None})["yaw"][0]))
    assert len({round(y, 3) for y in yaws[:2]}) == 2  # the retry turned the jaws
    with pytest.raises(NothingToSort, match="failed grasps"):
        policy.act({"qpos": None})


class _FixedClassifier:
    """Always says class ``k`` with probability 0.8."""

    def __init__(self, k: int) -> None:
        self.k = k

    def predict_proba(self, x: np.ndarray) -> np.ndarray:
        p = np.full((len(x), len(CLASSES)), 0.05)
        p[:, self.k] = 0.8
        return p


def test_in_hand_views_are_classified_by_the_in_hand_model(monkeypatch) -> None:
    from types import SimpleNamespace

    import ipbench.policies.perceiver as perceiver_module
    from ipbench.envs.sorting import ROBOT_JOINTS
    from ipbench.perception.cloud import PerceptionError
    from ipbench.perception.features import Codebook
    from ipbench.perception.model import PerceptionModel
    from ipbench.policies import PolicyModels
    from ipbench.policies.perceiver import Perceiver

    codebook = Codebook(np.random.default_rng(0).random((4, 33)))
    table = PerceptionModel(CLASSES, codebook, _FixedClassifier(0), "table")
    hand = PerceptionModel(CLASSES, codebook, _FixedClassifier(3), "hand")
    # a cube of points stands in for the segmentation (tested in test_segmentation)
    grid = np.stack(np.meshgrid(*[np.linspace(0, 0.06, 7)] * 3), -1).reshape(-1, 3)
    seg = Segment(grid, np.arange(len(grid)), grid.mean(0), grid.mean(0), np.eye(3),
                  np.full(3, 0.06), 0.06, 0.06)  # fmt: skip
    monkeypatch.setattr(perceiver_module, "depth_to_points", lambda *a: None)
    monkeypatch.setattr(perceiver_module, "segment_in_hand", lambda *a, **k: seg)
    monkeypatch.setattr(
        perceiver_module,
        "segment_scene",
        lambda *a, **k: SimpleNamespace(
            segments=(seg,), plane=(np.array([0.0, 0, 1]), -0.7), oversized=()
        ),
    )
    obs = {"wrist_depth": None, "wrist_K": None, "wrist_pose": np.eye(4)}
    obs["qpos"] = np.zeros(len(ROBOT_JOINTS))
    models = PolicyModels(gp=table, gp_hand=hand, inspection_area=(0, 0, 0), thresholds={"gp": 0.5})
    perceiver = make_policy("gp-ipm", models).perceiver
    assert perceiver.scene(obs)[0].label == "juice_bottle"  # the table model
    assert perceiver.in_hand(obs).label == "mug"  # the in-hand model
    without = Perceiver(table, np.zeros(3))
    assert without.in_hand(obs).label == "juice_bottle"  # no in-hand model: the table's
    other = PerceptionModel(CLASSES[:3], codebook, _FixedClassifier(0), "three")
    with pytest.raises(PerceptionError, match="train both for the same classes"):
        Perceiver(table, np.zeros(3), hand_model=other)


def _truth(categories: list[str]) -> dict:
    """``info`` of a scene whose object k covers the pixels of the k-th fake detection."""
    mask = np.full(1000, -1)
    for k in range(len(categories)):
        mask[100 * k : 100 * k + 50] = k
    return {"wrist_mask": mask, "objects": {k: {"category": c} for k, c in enumerate(categories)}}


class _TruthPerceiver(_FakePerceiver):
    """The fake scene with each detection on pixels of its own (100 k .. 100 k + 49)."""

    def scene(self, observation):
        out = []
        for k, d in enumerate(super().scene(observation)):
            seg = dataclasses.replace(d.segment, pixels=np.arange(50) + 100 * k)
            out.append(Detection(seg, d.probs, d.classes, d.viewpoint, d.inspected))
        return out


@pytest.mark.parametrize(
    ("truth", "inspected"), [(["mug", "bowl"], False), (["juice_box", "bowl"], True)]
)
def test_oracle_inspect_inspects_exactly_the_objects_whose_first_label_is_wrong(
    truth, inspected
) -> None:
    confident_mug = [0.02, 0.02, 0.02, 0.92, 0.02]  # the first chosen, whatever its truth
    unsure_bowl = [0.2, 0.2, 0.3, 0.1, 0.2]
    perceiver = _TruthPerceiver([confident_mug, unsure_bowl], [[0, 0, 0, 0, 1.0]] * 3)
    policy = make_reference("oracle-inspect", perceiver)
    policy.reset(0)
    action = policy.act({"qpos": None}, _truth(truth))
    assert (action["command"] == 2) is inspected
    assert policy.decisions[0].kind == ("inspect" if inspected else "place")
    with pytest.raises(PolicyError, match="ground truth"):
        make_reference("oracle-inspect", perceiver).act({"qpos": None}, None)


def make_reference(name: str, perceiver, fraction: float = 0.5):
    from ipbench.policies.inspection_references import OracleInspectSorter, RandomInspectSorter

    if name == "oracle-inspect":
        return OracleInspectSorter(perceiver)
    return RandomInspectSorter(perceiver, fraction)


@pytest.mark.parametrize("fraction", [0.0, 0.3, 1.0])
def test_random_inspect_inspects_about_its_fraction_and_is_seeded(fraction) -> None:
    perceiver = _FakePerceiver([[0.9, 0.05, 0.05, 0, 0]], [])
    policy = make_reference("random-inspect", perceiver, fraction)
    det = perceiver.scene(None)[0]  # a confident object: confidence plays no part

    def draws(seed: int) -> np.ndarray:
        policy.reset(seed)
        return np.array([policy.inspects(det, None) for _ in range(2000)])

    first = draws(7)
    assert first.mean() == pytest.approx(fraction, abs=0.03)
    np.testing.assert_array_equal(draws(7), first)
    if 0 < fraction < 1:
        assert not np.array_equal(draws(8), first)
    with pytest.raises(PolicyError, match=r"in \[0, 1\]"):
        make_reference("random-inspect", perceiver, 1.5)


@pytest.mark.parametrize(("threshold", "inspects"), [(0.0, False), (0.95, True), (1.0, True)])
def test_the_threshold_decides_which_objects_are_inspected(threshold, inspects) -> None:
    perceiver = _FakePerceiver([[0.9, 0.05, 0.05, 0, 0]], [])
    policy = InteractiveSorter(perceiver, InteractiveConfig(threshold=threshold))
    policy.reset(0)
    assert (policy.act({"qpos": None})["command"] == 2) is inspects


def test_policy_names_carry_thresholds_and_fractions() -> None:
    from ipbench.policies import policy_classifier, split_policy_name

    assert split_policy_name("gp-ipm@0.85") == ("gp-ipm", 0.85)
    assert split_policy_name("random-inspect@0.3") == ("random-inspect", 0.3)
    assert split_policy_name("oracle-inspect") == ("oracle-inspect", None)
    assert policy_classifier("svm-ipm@0.5") == ("svm", "hand")
    assert policy_classifier("random") is None
    for bad, message in [
        ("random-inspect", "needs the fraction"),
        ("oracle@0.5", "takes no @value"),
        ("gp-ipm@high", r"number in \[0, 1\]"),
        ("gp-ipm@1.5", r"number in \[0, 1\]"),
        ("greedy@0.5", "unknown policy"),
    ]:
        with pytest.raises(PolicyError, match=message):
            split_policy_name(bad)
