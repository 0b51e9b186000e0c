"""ipbench eval exploration: settings checked up front, a small run end to end, resume."""

from __future__ import annotations

import json

import pytest

from ipbench.eval.capture.exploration_database import DatabaseCaptureConfig
from ipbench.eval.exploration.evaluate import (
    ExplorationEvalConfig,
    ExplorationEvalError,
    refixation_rate,
    run_exploration_eval,
)
from ipbench.policies.exploration import EXPLORATION_POLICIES, Fixation

SIZE = (340, 512)
SMALL = ExplorationEvalConfig(
    scenes=("simple",),
    policies=("active-vision", "oracle-gaze"),
    features=("sift",),
    seeds=(3,),
    saccade_budget=3,
    head_size=SIZE,
    database=DatabaseCaptureConfig(head_size=SIZE, yaw_step_deg=90.0),
)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"scenes": ("huge",)}, "unknown scene 'huge'; valid: simple, medium, complex"),
        ({"policies": ("saccadic",)}, "valid: " + ", ".join(EXPLORATION_POLICIES)),
        ({"features": ("surf",)}, "unknown feature type 'surf'; valid: sift, kaze, akaze, orb"),
        ({"features": ("sift", "sift")}, "given twice"),
        ({"seeds": (1, 1)}, "seeds repeat: 1"),
        ({"seeds": ()}, "non-negative"),
        ({"saccade_budget": 0}, "saccade_budget must be >= 1"),
        ({"backend": "dask"}, "valid: process, ray"),
        ({"ray_address": "auto"}, "--backend ray"),
        ({"workers": 0}, "workers must be >= 1"),
    ],
)
def test_bad_settings_say_what_is_valid(kwargs, message):
    with pytest.raises(ExplorationEvalError, match=message.replace("(", r"\(")):
        ExplorationEvalConfig(**kwargs)


def test_refixation_counts_saccades_back_to_a_place_seen():
    ahead, side, new = [0.0, 0.0, 1.0], [0.6, 0.0, 0.8], [0.0, 0.6, 0.8]
    # each fixation's axis is where the head looks when it decides (after the last saccade)
    fixations = [
        Fixation("object", "a", ahead),
        Fixation("verge", "a", side),  # after the saccade to the object: a new place
        Fixation("salient", None, side),  # after a vergence: not a saccade
        Fixation("salient", None, ahead),  # back to the first place: a re-fixation
        Fixation("halt", None, new),
    ]
    assert refixation_rate(fixations) == pytest.approx(1 / 3, abs=1e-4)  # rounded to 4 places
    assert refixation_rate(fixations[:1]) == 0.0


def test_a_small_run_writes_the_report_and_resumes(tmp_path, capsys):
    out, cache = tmp_path / "out", tmp_path / "cache"
    summary = run_exploration_eval(out, cache, SMALL, progress=False)
    cell = summary["simple"]["active-vision"]["sift"]
    for key in ("performance_mean", "ci_low", "ci_high", "n", "true_positives",
                "false_positives", "not_found"):  # fmt: skip
        assert key in cell
    assert cell["n"] == 1 and cell["ci_low"] <= cell["performance_mean"] <= cell["ci_high"]
    records = [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]
    assert [(r["policy"], r["seed"]) for r in records] == [("active-vision", 3), ("oracle-gaze", 3)]
    for r in records:
        assert r["true_positives"] + r["not_found"] == r["n_database"]
        assert len(r["recall_curve"]) == r["saccades"] + 1 and r["saccades"] <= 3
        # recognition against eccentricity: one look per step, database instances in view;
        # a true positive was recognised in some look (a policy reports what it saw)
        assert r["looks"] == r["steps"] and r["sightings"]
        assert all(0 <= e <= 180 and px > 0 for e, _, px in r["sightings"])
        assert not r["true_positives"] or any(seen for _, seen, _ in r["sightings"])
        # every instance not found is put down to one cause
        assert sum(r["missed"].values()) == r["not_found"]
    assert cell["missed"]["episodes"] == 1
    bins = cell["eccentricity"]["bins"]
    assert sum(b["n"] for b in bins) == len(records[0]["sightings"])
    title = (out / "exploration.md").read_text().splitlines()[0]
    assert title.startswith("# ") and "ipbench/Exploration-v0 (" in title, title
    # resume: nothing runs again, the report is written anew
    run_exploration_eval(out, cache, SMALL, progress=False)
    assert "2 episodes already in" in capsys.readouterr().out
    assert len((out / "episodes.jsonl").read_text().splitlines()) == 2
    # another policy with the same settings adds up: the report covers the whole folder
    more = ExplorationEvalConfig(**{**SMALL.__dict__, "policies": ("random-gaze",)})
    summary = run_exploration_eval(out, cache, more, progress=False)
    assert set(summary["simple"]) == {"active-vision", "oracle-gaze", "random-gaze"}
    # another configuration into the same folder is refused
    other = ExplorationEvalConfig(**{**SMALL.__dict__, "saccade_budget": 4})
    with pytest.raises(ExplorationEvalError, match="another configuration"):
        run_exploration_eval(out, cache, other, progress=False)


def test_the_database_is_captured_at_the_episodes_head_size():
    big = ExplorationEvalConfig(head_size=(1632, 2464))
    assert big.database.head_size == (1632, 2464)
    # one cache entry per size, and runs of other sizes never mix in one folder
    assert big.database.key() != ExplorationEvalConfig().database.key()
    assert big.fingerprint() != ExplorationEvalConfig().fingerprint()
    assert ExplorationEvalConfig().database.head_size == (680, 1024)


@pytest.mark.parametrize("size", [(680,), (0, 1024), (680.0, 1024)])
def test_a_bad_head_size_says_what_is_valid(size):
    with pytest.raises(ExplorationEvalError, match=r"head_size must be \(height, width\)"):
        ExplorationEvalConfig(head_size=size)


def test_an_id_brings_its_cameras_and_prints_to_the_episodes_and_the_database():
    v0, v1 = ExplorationEvalConfig(), ExplorationEvalConfig(env_id="ipbench/Exploration-v1")
    assert (v0.head_size, v0.fovea_factor, v0.database.upright_prints) == ((680, 1024), 1, False)
    assert (v1.head_size, v1.fovea_factor) == ((3264, 4928), 4)
    assert v1.database.head_size == (3264, 4928) and v1.database.upright_prints
    # the released prints keep their cache key; the upright ones are another entry
    same_size = DatabaseCaptureConfig(head_size=(3264, 4928))
    assert DatabaseCaptureConfig(upright_prints=False).key() == DatabaseCaptureConfig().key()
    assert v1.database.key() != same_size.key()
    # v0's runs keep their fingerprint; the fovea alone makes another run
    explicit = ExplorationEvalConfig(env_id="ipbench/Exploration-v0", fovea_factor=1)
    assert explicit.fingerprint() == v0.fingerprint()
    periphery = ExplorationEvalConfig(
        env_id="ipbench/Exploration-v1", head_size=(816, 1232), fovea_factor=1
    )
    assert periphery.fingerprint() not in (v0.fingerprint(), v1.fingerprint())
    assert periphery.database.upright_prints


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"env_id": "ipbench/Exploration-v7"}, "valid: ipbench/Exploration-v0"),
        ({"env_id": "ipbench/Exploration-v1", "head_size": (600, 900)}, "factor 4"),
        ({"fovea_factor": 0}, "valid: an int >= 2"),
    ],
)
def test_bad_ids_and_foveae_say_what_is_valid(kwargs, message):
    with pytest.raises(ExplorationEvalError, match=message):
        ExplorationEvalConfig(**kwargs)
