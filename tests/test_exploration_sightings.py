"""Recognition against eccentricity: sightings of one look by hand (angles, recognised, false
candidates, foveated pixel counts), the bins, the records' optional fields and the report."""

from __future__ import annotations

import copy
from types import SimpleNamespace

import numpy as np
import pytest

from ipbench.envs.exploration_scene import DATABASE_CLASSES
from ipbench.eval.exploration.records import ExplorationReportError, check_record
from ipbench.eval.exploration.report import summarize_exploration, write_exploration_report
from ipbench.eval.exploration.sightings import (
    ECCENTRICITY_BINS_DEG,
    look_sightings,
    recognition_by_eccentricity,
)
from ipbench.policies.exploration import same_object_m

A, B = DATABASE_CLASSES[0], DATABASE_CLASSES[1]


def _scene(turn_deg: float = 0.0):
    """A camera at (0, 0, 0.5) looking along +x turned by ``turn_deg`` about z; instances of A
    at 1 m straight ahead, of B at 1 m and 10 deg to the side, a distractor and an unseen A."""
    t = np.radians(turn_deg)
    axis = np.array([np.cos(t), np.sin(t), 0.0])
    pose = np.eye(4)
    pose[:3, 2] = axis  # OpenCV camera: z is the optical axis
    pose[:3, 3] = (0.0, 0.0, 0.5)
    side = np.radians(10.0)
    objects = {
        "a": {"class": A, "position": np.array([1.0, 0.0, 0.5])},
        "b": {"class": B, "position": np.array([np.cos(side), np.sin(side), 0.5])},
        "distractor": {"class": None, "position": np.array([1.0, -0.2, 0.5])},
        "hidden": {"class": A, "position": np.array([1.0, 0.3, 0.5])},
    }
    mask = np.full((6, 8), -1, np.int32)
    mask[0, :3] = 0  # a: 3 pixels
    mask[1, :2] = 1  # b: 2 pixels
    mask[2, :5] = 2  # distractor
    return {"head_left_pose": pose}, {"objects": objects, "head_left_mask": mask}


def _look(*candidates):
    return SimpleNamespace(
        candidates=tuple(
            SimpleNamespace(label=lab, position=np.asarray(p)) for lab, p in candidates
        )
    )


def test_one_look_by_hand():
    obs, info = _scene()
    near_a = np.array([1.0, 0.0, 0.5]) + [0.5 * same_object_m(A), 0.0, 0.0]
    far_b = info["objects"]["b"]["position"] + [0.0, 2.0 * same_object_m(B), 0.0]
    wrong_class = info["objects"]["b"]["position"]  # an A where B stands
    got = look_sightings(_look((A, near_a), (B, far_b), (A, wrong_class)), obs, info)
    (ecc_a, seen_a, px_a), (ecc_b, seen_b, px_b) = got.sightings
    assert ecc_a == pytest.approx(0.0, abs=1e-6) and seen_a and px_a == 3
    assert ecc_b == pytest.approx(10.0, abs=0.01) and not seen_b and px_b == 2
    assert got.false_candidates == 2  # B far from B, A where no A stands
    # the distractor (no database class) and the unseen A are no sightings
    assert len(got.sightings) == 2
    # turning the camera 10 deg towards B swaps the angles
    obs, info = _scene(turn_deg=10.0)
    ecc = [s[0] for s in look_sightings(None, obs, info).sightings]
    assert ecc == pytest.approx([10.0, 0.0], abs=0.01)
    # no look: nothing recognised, no false candidates
    assert look_sightings(None, obs, info).false_candidates == 0
    # foveated: a mask pixel stands for f x f pixels of the render
    assert [s[2] for s in look_sightings(None, obs, info, fovea_factor=4).sightings] == [48, 32]


def test_bins_by_hand_and_bad_edges():
    bins = recognition_by_eccentricity([[0.0, True], [3.9, False], [4.0, True], [17.0, True]])
    assert [(b.low_deg, b.high_deg) for b in bins] == list(
        zip(ECCENTRICITY_BINS_DEG[:-1], ECCENTRICITY_BINS_DEG[1:], strict=True)
    )
    assert [(b.n, b.recognised) for b in bins] == [(2, 1), (1, 1), (0, 0), (0, 0), (1, 1)]
    assert bins[0].rate == 0.5 and bins[2].rate is None
    with pytest.raises(ValueError, match="increasing angles"):
        recognition_by_eccentricity([], edges=(0.0, 8.0, 4.0))


def _record(seed: int, sightings, looks: int = 2, false: int = 1) -> dict:
    return {
        "scene": "simple",
        "policy": "active-vision",
        "feature": "sift",
        "seed": seed,
        "n_database": 2,
        "true_positives": 1,
        "false_positives": 0,
        "not_found": 1,
        "performance": 0.5,
        "recovered": 0,
        "fp_reasons": {"wrong_class": 0, "already_reported": 0, "nothing_there": 0},
        "saccades": 1,
        "sim_time_s": 1.0,
        "wall_time_s": 1.0,
        "steps": 2,
        "recall_curve": [0.0, 0.5],
        "saccades_to_all": None,
        "sim_s_to_all": None,
        "refixation_rate": 0.0,
        "localisation_mm": [5.0],
        "halted": True,
        "truncated": False,
        "video": None,
        "cycle_s": 0.5,
        "sightings": sightings,
        "false_candidates": false,
        "looks": looks,
    }


def test_records_carry_all_three_fields_or_none():
    good = _record(0, [[2.0, True, 40], [9.5, False, 12]])
    check_record(good, 0)
    old = {k: v for k, v in good.items() if k not in ("sightings", "false_candidates", "looks")}
    check_record(old, 0)  # records written before sightings existed
    half = copy.deepcopy(good)
    del half["looks"]
    with pytest.raises(ExplorationReportError, match="lacks looks .all or none"):
        check_record(half, 0)
    bad = copy.deepcopy(good)
    bad["sightings"] = [[2.0, 1, 40]]
    with pytest.raises(ExplorationReportError, match="sightings must be a list of"):
        check_record(bad, 0)


def test_summary_and_markdown_pool_the_episodes_that_carry_sightings(tmp_path):
    records = [
        _record(0, [[2.0, True, 40], [9.5, False, 12]], looks=2, false=1),
        _record(1, [[1.0, True, 30], [20.0, False, 5]], looks=3, false=0),
    ]
    old = {k: v for k, v in _record(2, []).items() if k not in ("sightings", "looks")}
    del old["false_candidates"]
    cell = summarize_exploration([*records, old], budget=1)["simple"]["active-vision"]["sift"]
    e = cell["eccentricity"]
    assert (e["episodes"], e["looks"]) == (2, 5)
    assert [(b["n"], b["recognised"]) for b in e["bins"]] == [
        (2, 2),
        (0, 0),
        (1, 0),
        (0, 0),
        (1, 0),
    ]
    assert e["false_candidates_per_look"] == pytest.approx(1 / 5)
    md = write_exploration_report(records, tmp_path, 1).markdown.read_text()
    assert "## Recognition against eccentricity" in md
    assert (
        "| simple | sift | active-vision | 100 % (2) | – | 0 % (1) | – | 0 % (1) | 0.20 | 5 | 2 |"
        in md
    )
    # without sightings: no section, no key
    cell = summarize_exploration([old], budget=1)["simple"]["active-vision"]["sift"]
    assert "eccentricity" not in cell
