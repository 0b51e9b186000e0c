"""The sorting evaluation: policies on real episodes, records, resume, executors, report."""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import imageio.v2 as imageio
import numpy as np
import pytest
from small_models import small_models

import ipbench.envs  # noqa: F401
import ipbench.eval.sorting.evaluate as sorting
from ipbench.envs.sorting_scenes import SCENES, STANDARD_SCENES
from ipbench.eval.capture.dataset import DATASET_VERSION
from ipbench.eval.sorting.evaluate import (
    SortingEvalConfig,
    SortingEvalError,
    Task,
    run_sorting_eval,
)
from ipbench.policies import POLICIES, PolicyModels
from ipbench.policies.threshold import choose_threshold

RUNNABLE = [p if p != "random-inspect" else "random-inspect@0.5" for p in POLICIES] + ["gp-ipm@1.0"]
"""Every policy, the one that needs its fraction with one, and a policy at a threshold."""
FAST = SortingEvalConfig(scenes=("uncluttered",), seeds=(0,), steps_per_object=1)
"""Step limit = objects + 10: short episodes that still sort most of a scene."""


@pytest.fixture(scope="module")
def models() -> PolicyModels:
    """A small real model: codebook and classifiers from the segments of a few wrist views
    (labelled by the ground-truth masks), instead of the full rendered dataset."""
    return small_models((500, 501, 502), 32, 0.5)


@pytest.fixture
def prepared(models, monkeypatch):
    choice = choose_threshold(np.array([0.4, 0.6, 0.9]), np.array([False, True, True]), 0.95)
    monkeypatch.setattr(
        sorting, "prepare_models", lambda cache, config, **kw: (models, {"gp": choice})
    )
    return models


RECORD_KEYS = {
    "scene", "policy", "seed", "objects", "correct", "accuracy", "per_category", "wrong_bin",
    "left", "dropped", "losses", "inspections", "grasp_failures", "physics_undone", "steps",
    "skills", "sim_time_s",
    "wall_time_s", "truncated", "stopped", "threshold", "decisions", "video",
}  # fmt: skip


@pytest.mark.parametrize("policy", RUNNABLE)
def test_every_policy_runs_an_episode_to_its_end(policy: str, models) -> None:
    record = sorting.run_episode(Task("uncluttered", policy, 1), models, FAST)
    assert set(record) == RECORD_KEYS
    assert record["steps"] >= 1 and record["objects"] == 10
    assert record["truncated"] or record["stopped"] or record["left"] == 0
    assert sum(c["total"] for c in record["per_category"].values()) == record["objects"]
    assert record["correct"] == sum(c["correct"] for c in record["per_category"].values())
    assert len(record["decisions"]) >= 1
    assert record["skills"].get("pick", 0) >= 1
    json.dumps(record)  # JSON-ready
    if policy == "oracle":  # true labels: every object that reached a bin is right
        assert record["wrong_bin"] == 0


def test_longest_episodes_are_scheduled_first_in_a_fixed_order() -> None:
    tasks = [Task(scene, policy, s) for scene in SCENES for policy in RUNNABLE for s in (0, 1)]
    order = sorting._longest_first(tasks)
    assert order == sorting._longest_first(list(tasks)) and set(order) == set(tasks)
    first, last = order[0], order[-1]
    assert SCENES[first.scene].n_objects > SCENES[last.scene].n_objects


def test_serial_process_and_ray_runs_give_identical_episodes(models) -> None:
    pytest.importorskip("ray")
    tasks = [Task("uncluttered", "random", s) for s in (2, 3)]
    runs = {}
    for name, config in {
        "serial": FAST,
        "process": replace(FAST, workers=2),
        "ray": replace(FAST, workers=2, backend="ray"),
    }.items():
        records = list(sorting._executor(config)(tasks, models, config))
        runs[name] = {
            r["seed"]: {k: v for k, v in r.items() if k != "wall_time_s"} for r in records
        }
    assert runs["serial"] == runs["process"] == runs["ray"]


def test_an_interrupted_evaluation_resumes_without_repeating(tmp_path, prepared, monkeypatch):
    calls = []

    def fake_episode(task, models, config):
        calls.append(task.key)
        return {
            "scene": task.scene, "policy": task.policy, "seed": task.seed, "objects": 2,
            "correct": task.seed % 2 + 1, "accuracy": (task.seed % 2 + 1) / 2,
            "per_category": {"mug": {"total": 2, "correct": task.seed % 2 + 1}},
            "inspections": 0, "grasp_failures": 0, "wall_time_s": 1.0, "sim_time_s": 5.0,
            "decisions": [],
        }  # fmt: skip

    monkeypatch.setattr(sorting, "run_episode", fake_episode)
    config = replace(FAST, policies=("random", "gp-ipm"), seeds=(0, 1))
    run_sorting_eval(tmp_path, tmp_path / "cache", config, progress=False)
    assert len(calls) == 4
    log = tmp_path / "episodes.jsonl"
    lines = log.read_text().splitlines()
    # kill mid-write: the last record half written, the one before it lost
    log.write_text("\n".join(lines[:2]) + "\n" + lines[2][:25])
    calls.clear()
    summary = run_sorting_eval(tmp_path, tmp_path / "cache", config, progress=False)
    assert len(calls) == 2 and set(calls).isdisjoint(
        {
            (json.loads(x)["scene"], json.loads(x)["policy"], json.loads(x)["seed"])
            for x in lines[:2]
        }
    )
    keys = [
        (e["scene"], e["policy"], e["seed"]) for e in map(json.loads, log.read_text().splitlines())
    ]
    assert keys == sorted(keys) and len(keys) == 4  # the finished log, in canonical order
    assert summary["uncluttered"]["random"]["n"] == 2
    assert {"accuracy_mean", "ci_low", "ci_high", "n"} <= set(summary["uncluttered"]["gp-ipm"])
    tables = (tmp_path / "sorting.md").read_text().split("## Accuracy against")[0]
    assert tables.count("| random |") == 1  # one row of the scene's table
    calls.clear()
    run_sorting_eval(tmp_path, tmp_path / "cache", config, progress=False)
    assert calls == []  # all done: nothing runs again
    with pytest.raises(SortingEvalError, match="another configuration"):
        run_sorting_eval(tmp_path, tmp_path / "cache", replace(config, n_views=5), progress=False)


def test_evaluation_with_video_writes_a_decodable_mp4(tmp_path, prepared) -> None:
    config = replace(FAST, policies=("gp-ipm",), video=True)
    run_sorting_eval(tmp_path, tmp_path / "cache", config, progress=False)
    record = json.loads((tmp_path / "episodes.jsonl").read_text().splitlines()[0])
    video = Path(record["video"])
    reader = imageio.get_reader(video)
    frames = [f for _, f in zip(range(5), reader.iter_data(), strict=False)]
    reader.close()
    assert len(frames) == 5 and frames[0].shape == (480, 640, 3)
    assert (tmp_path / "summary.json").exists() and (tmp_path / "threshold_sweep.png").exists()


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"policies": ("greedy",)}, "unknown policy 'greedy'; valid: random, gp-ipm"),
        ({"scenes": ("kitchen",)}, "unknown scene 'kitchen'; valid: uncluttered, cluttered"),
        ({"seeds": (1000,)}, "overlap the test seeds"),
        ({"seeds": (-1,)}, "non-negative"),
        ({"backend": "dask"}, "valid: process, ray"),
        ({"seeds": (3, 3, 4)}, r"seeds repeat: 3 given more than once.*--seeds 3,4$"),
        ({"seeds": (5, 3, 5, 3, 4)}, r"seeds repeat: 3, 5 .*--seeds 5,3,4$"),
        ({"validation_seeds": (1000, 1001, 1000)}, r"validation_seeds repeat: 1000 "),
        ({"ray_address": "auto"}, "ray backend only.*add --backend ray, or drop --ray-address"),
        ({"extrinsics": "exact"}, "unknown extrinsics 'exact'; valid: 'true', 'nominal'"),
        ({"extrinsics": "calibrated"}, "needs calibration=FILE"),
        ({"extrinsics": "calibrated", "calibration": "/no/such.json"}, "does not exist"),
        ({"robot_seed": 2}, "drop --robot-seed or add --extrinsics nominal|calibrated"),
    ],
)
def test_bad_settings_say_what_is_valid(changes, message) -> None:
    with pytest.raises(SortingEvalError, match=message):
        SortingEvalConfig(**changes)


def test_a_ray_address_goes_with_the_ray_backend() -> None:
    assert SortingEvalConfig(backend="ray", ray_address="auto").ray_address == "auto"


def test_a_file_in_place_of_the_cache_is_reported(tmp_path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    for cache in (blocker, blocker / "sub"):
        with pytest.raises(
            SortingEvalError, match=rf"cache {re.escape(str(cache))} is not a folder"
        ):
            sorting.prepare_models(cache, FAST)


def test_an_unwritable_output_folder_is_reported(tmp_path, prepared) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(SortingEvalError, match="cannot write to the output folder"):
        run_sorting_eval(blocker / "out", tmp_path / "cache", FAST, progress=False)


def test_threshold_evidence_is_every_labelled_segment_of_the_validation_views(models, monkeypatch):
    from ipbench.envs.sorting_scenes import SCENES

    monkeypatch.setattr(sorting, "SCENES", {"uncluttered": SCENES["uncluttered"]})
    config = replace(FAST, validation_seeds=(1000,))
    from ipbench.envs.sorting import SortingEnv

    def no_step(self, action):
        raise AssertionError("a validation view takes no step: the first view, before a grasp")

    monkeypatch.setattr(SortingEnv, "step", no_step)
    conf, correct = sorting._validation_evidence(models.gp, config)
    record = sorting.validation_view(
        Task("uncluttered", "validation", 1000), sorting._under_test(models.gp, config), config
    )
    decided = [d for d in record["decisions"] if d["true_category"] is not None]
    assert len(decided) >= 5  # most of the ten objects are segments of their own
    np.testing.assert_allclose(conf, [d["first_confidence"] for d in decided])
    assert list(correct) == [d["first_label"] == d["true_category"] for d in decided]


def test_validation_evidence_is_cached_across_targets_and_rebuilt_when_corrupt(
    models, tmp_path, monkeypatch, capsys
):
    calls = []

    def evidence(model, config, progress=False):
        calls.append(config.target_precision)
        return np.array([0.3, 0.5, 0.9, 0.95]), np.array([False, True, True, True])

    monkeypatch.setattr(sorting, "_validation_evidence", evidence)
    conf, correct = evidence(None, FAST)
    calls.clear()
    strict = sorting._threshold(tmp_path, models.gp, "gp", replace(FAST, target_precision=0.95))
    loose = sorting._threshold(tmp_path, models.gp, "gp", replace(FAST, target_precision=0.6))
    want = choose_threshold(conf, correct, 0.95)
    assert strict.threshold == want.threshold and strict.fit == want.fit
    assert loose.threshold == choose_threshold(conf, correct, 0.6).threshold
    assert loose.threshold < strict.threshold and calls == [0.95]
    again = sorting._threshold(tmp_path, models.gp, "gp", replace(FAST, target_precision=0.95))
    assert (again.threshold, again.fit) == (strict.threshold, strict.fit)
    assert calls == [0.95]  # the saved threshold
    (path,) = tmp_path.glob("evidence-gp-*.json")
    path.write_text("{not json")
    sorting._threshold(tmp_path, models.gp, "gp", replace(FAST, target_precision=0.9))
    assert "corrupt" in capsys.readouterr().out and calls == [0.95, 0.9]


def test_validation_evidence_is_in_task_order_whatever_order_workers_finish(monkeypatch):
    import ipbench.eval.sorting.evaluate as sorting

    config = SortingEvalConfig(validation_seeds=(1000, 1001, 1002))

    def run_episodes(fn, tasks, context, **kwargs):  # finished last-first, as a slow worker would
        assert fn is sorting.validation_view
        for i, t in reversed(list(enumerate(tasks))):
            decision = {"true_category": "mug", "first_confidence": i, "first_label": "mug"}
            yield {"scene": t.scene, "seed": t.seed, "decisions": [decision]}

    monkeypatch.setattr(sorting, "run_episodes", run_episodes)
    conf, correct = sorting._validation_evidence(None, config)
    # the standard scenes' validation views (not the pile's)
    assert conf.tolist() == sorted(conf.tolist()) and len(conf) == 3 * len(STANDARD_SCENES)
    assert correct.all()


def test_runs_and_thresholds_of_other_policy_code_are_never_reused(monkeypatch):
    """The policy code's version is in the run fingerprint (a folder of other policy code is
    refused, not resumed) and in the cached threshold evidence's key (chosen again)."""
    import ipbench.eval.sorting.config as sorting_config
    import ipbench.eval.sorting.evaluate as sorting

    config = sorting.SortingEvalConfig()
    model = type("Model", (), {"key": "m"})()
    run, evidence = config.fingerprint("k"), sorting._validation_key(model, config)
    monkeypatch.setattr(sorting, "POLICY_VERSION", sorting.POLICY_VERSION + 1)
    monkeypatch.setattr(sorting_config, "POLICY_VERSION", sorting.POLICY_VERSION)
    assert config.fingerprint("k") != run
    assert sorting._validation_key(model, config) != evidence


@pytest.fixture(scope="module")
def wrist_calibration(tmp_path_factory) -> Path:
    """``ipbench calibrate --cameras wrist --robot-seed 3``'s routine, 8 poses (a few s)."""
    from ipbench.eval.calibration.calibrate import CalibrationCaptureConfig, calibrate_cell

    config = CalibrationCaptureConfig(cameras=("wrist",), poses_per_camera=8, robot_seed=3)
    return calibrate_cell(config).save(tmp_path_factory.mktemp("cal") / "wrist.json")


def test_the_cell_enters_the_fingerprint_by_content_and_true_adds_nothing(
    wrist_calibration, tmp_path
) -> None:
    assert FAST.env_options() == {} and FAST.cell_key() == []
    nominal = replace(FAST, extrinsics="nominal", robot_seed=3)
    assert nominal.env_options() == {"extrinsics": "nominal", "calibration": None, "robot_seed": 3}
    prints = {FAST.fingerprint("k"), nominal.fingerprint("k")}
    prints.add(replace(nominal, robot_seed=4).fingerprint("k"))
    cal = replace(nominal, extrinsics="calibrated", calibration=str(wrist_calibration))
    prints.add(cal.fingerprint("k"))
    assert len(prints) == 4
    copy = tmp_path / "same.json"  # the same calibration at another path: the same run
    copy.write_bytes(wrist_calibration.read_bytes())
    assert replace(cal, calibration=str(copy)).fingerprint("k") == cal.fingerprint("k")
    # thresholds are validated in the released cell whatever the evaluated one
    assert sorting._validation_key(sorting._Keyed("m"), cal) == sorting._validation_key(
        sorting._Keyed("m"), FAST
    )
    from dataclasses import asdict

    val, cell = asdict(cal.validation_config()), ("extrinsics", "calibration", "robot_seed")
    assert [val[k] for k in cell] == ["true", None, 0]
    assert {k: v for k, v in val.items() if k not in cell} == {
        k: v for k, v in asdict(cal).items() if k not in cell
    }


def test_an_episode_runs_in_the_calibrated_cell(models, wrist_calibration, monkeypatch) -> None:
    """The env gets the cell's options and the perceiver the calibrated lens (``wrist_dist``)."""
    import gymnasium as gym

    made, seen = [], []
    make = gym.make

    def spy(env_id, **kw):
        made.append(kw)
        return make(env_id, **kw)

    monkeypatch.setattr(sorting.gym, "make", spy)
    original = sorting.make_policy

    def policy(*args, **kw):
        p = original(*args, **kw)
        act = p.act

        def watched(obs, info=None):
            seen.append(obs.get("wrist_dist"))
            return act(obs, info)

        p.act = watched
        return p

    monkeypatch.setattr(sorting, "make_policy", policy)
    config = replace(
        FAST, extrinsics="calibrated", calibration=str(wrist_calibration), robot_seed=3
    )
    record = sorting.run_episode(Task("uncluttered", "oracle", 1), models, config)
    assert made[0]["extrinsics"] == "calibrated" and made[0]["robot_seed"] == 3
    assert record["steps"] >= 1 and record["skills"].get("pick", 0) >= 1
    assert seen and all(d is not None and np.any(d) for d in seen)


@pytest.mark.parametrize(("threshold", "kinds"), [(0.0, {"place"}), (1.0, {"inspect"})])
def test_threshold_option_sets_which_objects_are_inspected(tmp_path, prepared, threshold, kinds):
    config = replace(FAST, policies=("gp-ipm",), threshold=threshold)
    run_sorting_eval(tmp_path, tmp_path / "cache", config, progress=False)
    (record,) = map(json.loads, (tmp_path / "episodes.jsonl").read_text().splitlines())
    assert record["threshold"] == threshold
    assert {d["kind"] for d in record["decisions"]} == kinds
    run = json.loads((tmp_path / "run.json").read_text())
    assert set(run["thresholds"].values()) == {threshold}  # every classifier's
    validated = run["validated_thresholds"]["gp"]
    fixture = choose_threshold(np.array([0.4, 0.6, 0.9]), np.array([False, True, True]), 0.95)
    assert validated["threshold"] == fixture.threshold and not validated["used"]
    assert validated["rule"] == "logistic-precision" and "validation seeds" in validated["data"]
    assert run["dataset_version"] == DATASET_VERSION  # what the results pages stamp
    assert run["env_status"] == "released"  # FAST runs a released id


def test_thresholds_expand_each_confidence_driven_policy() -> None:
    policies = ("random", "gp-ipm", "oracle-inspect", "svm-ipm@0.3")
    assert sorting.expand_thresholds(policies, ()) == policies
    assert sorting.expand_thresholds(policies, (0.5, 1.0)) == (
        "random", "gp-ipm@0.5", "gp-ipm@1.0", "oracle-inspect", "svm-ipm@0.3"
    )  # fmt: skip
    with pytest.raises(SortingEvalError, match="must be in"):
        replace(FAST, threshold=1.5)
    with pytest.raises(SortingEvalError, match="needs the fraction"):
        replace(FAST, policies=("random-inspect",))


def test_a_threshold_sweep_writes_the_curve_and_its_summary_keys(tmp_path, prepared, monkeypatch):
    """The public surface of ``--thresholds``: one summary entry per policy and threshold,
    and ``curve.json`` with each family's points and score (fake episodes: only the files)."""

    def fake_episode(task, models, config):
        base, value = sorting.split_policy_name(task.policy)
        inspected = {"random": 0, "oracle-inspect": 1}.get(base, round(4 * (value or 0)))
        right = min(4, 2 + inspected + task.seed % 2)
        return {
            "scene": task.scene, "policy": task.policy, "seed": task.seed, "objects": 4,
            "correct": right, "accuracy": right / 4, "inspections": inspected,
            "per_category": {"mug": {"total": 4, "correct": right}}, "grasp_failures": 0,
            "wall_time_s": 1.0, "sim_time_s": 5.0, "decisions": [], "dropped": 0, "left": 0,
        }  # fmt: skip

    monkeypatch.setattr(sorting, "run_episode", fake_episode)
    policies = sorting.expand_thresholds(
        ("random", "oracle-inspect", "random-inspect@0.5", "gp-ipm"), (0.0, 0.5, 1.0)
    )
    config = replace(FAST, policies=policies, seeds=(0, 1, 2))
    summary = run_sorting_eval(tmp_path, tmp_path / "cache", config, progress=False)["uncluttered"]
    assert {"gp-ipm@0.0", "gp-ipm@0.5", "gp-ipm@1.0", "oracle-inspect", "random"} <= set(summary)
    keys = {"accuracy_mean", "ci_low", "ci_high", "n", "grasp_failures_mean", "dropped_fraction"}
    assert keys | {"inspections_per_object"} <= set(summary["gp-ipm@0.5"])
    assert summary["gp-ipm@0.5"]["inspections_per_object"] == 0.5
    curve = json.loads((tmp_path / "curve.json").read_text())["uncluttered"]
    points = curve["gp-ipm"]["points"]
    assert [p["threshold"] for p in points] == [0.0, 0.5, 1.0]
    assert set(points[0]) >= {"threshold", "inspections_per_object", "accuracy_mean", "ci_low"}
    assert set(curve["gp-ipm"]["score"]) >= {"mean", "ci_low", "ci_high"}
    assert (tmp_path / "curve.png").exists()
    assert "Accuracy against inspection effort" in (tmp_path / "sorting.md").read_text()
