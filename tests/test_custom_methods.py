"""Methods of the user's own (``module:attribute``) through the real ``ipbench`` command: the
example policy and classifier of ``examples/``, and the messages for broken references."""

from __future__ import annotations

import json
import os
import sys
import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from exports import assert_exports
from small_models import small_models

import ipbench.eval.perception.evaluate as perception
import ipbench.eval.sorting.evaluate as sorting
from ipbench.assets.objects import CATEGORIES
from ipbench.eval.cli import main
from ipbench.eval.workers import run_tasks
from ipbench.perception.classifiers import ClassifierError, check_classifier_name, make_classifier
from ipbench.perception.viewset import ViewSet
from ipbench.policies import PolicyError, check_policy_name, split_policy_name
from ipbench.policies.custom import check_policy_reference
from ipbench.policies.threshold import choose_threshold
from ipbench.references import ReferenceLoadError, load_reference

ROOT = Path(__file__).resolve().parents[1]
POLICY = "examples.my_policy:LargestFirst"
CLASSIFIER = "examples.my_classifier:LogisticClassifier"


@pytest.mark.parametrize("name", ["ipbench.references", "ipbench.policies.custom"])
def test_export_lists_name_the_public_definitions(name):
    assert_exports(name)


@pytest.fixture
def here(monkeypatch):
    """Run as the ``ipbench`` command does (its folder, not the current one, on sys.path), and
    undo what loading a reference adds to sys.path and PYTHONPATH."""
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", str(ROOT))])
    monkeypatch.setenv("PYTHONPATH", os.environ.get("PYTHONPATH", ""))

    def chdir(folder: Path) -> Path:
        monkeypatch.chdir(folder)
        return folder

    return chdir


@pytest.fixture
def user_module(tmp_path, here):
    """A module ``user_methods`` in the current folder with good and broken methods."""
    (tmp_path / "user_methods.py").write_text(
        textwrap.dedent(
            """
            import numpy as np
            from ipbench.policies.base import SceneSorter

            class NoAct(SceneSorter):
                def __init__(self, perceiver, name):
                    super().__init__(perceiver)

            class ActWithoutInfo(SceneSorter):
                def __init__(self, perceiver, name):
                    super().__init__(perceiver)

                def act(self, observation):
                    return {}

            class NoArguments:
                def reset(self, seed):
                    pass

                def act(self, observation, info):
                    return {}

            class NoPredictProba:
                def __init__(self, n_classes, seed):
                    pass

                def fit(self, X, y):
                    return self

            class WrongShape(NoPredictProba):
                def predict_proba(self, X):
                    return np.full((len(X), 2), 0.5)

            NOT_A_CLASS = 3
            """
        )
    )
    sys.modules.pop("user_methods", None)
    yield here(tmp_path)
    sys.modules.pop("user_methods", None)


# -- the examples through the command ------------------------------------------------------------
@pytest.fixture(scope="module")
def models():
    return small_models((500, 501, 502), 32, 0.5)


def test_the_example_policy_runs_beside_random_through_the_command(tmp_path, models, monkeypatch):
    monkeypatch.chdir(ROOT)  # where the docs run it from
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", str(ROOT))])
    monkeypatch.setenv("PYTHONPATH", "")
    choice = choose_threshold(np.array([0.4, 0.6, 0.9]), np.array([False, True, True]), 0.95)
    asked = []

    def prepare(cache, config, **_):
        asked.append(config.policies)
        return models, {"gp": choice}

    monkeypatch.setattr(sorting, "prepare_models", prepare)
    out = tmp_path / "run"
    code = main(
        ["eval", "sorting", "--env", "ipbench/Sorting-v1", "--scenes", "uncluttered"]
        + ["--policies", f"random,{POLICY}", "--seeds", "0", "--workers", "1"]
        + ["--out", str(out), "--cache", str(tmp_path / "cache")]
    )
    assert code == 0 and asked == [("random", POLICY)]
    records = [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]
    by_policy = {r["policy"]: r for r in records}
    assert len(records) == 2 and set(by_policy) == {"random", POLICY}
    custom = by_policy[POLICY]
    assert custom["steps"] >= 1 and custom["inspections"] == 0 and custom["threshold"] is None
    assert len(custom["decisions"]) >= 1 and custom["skills"].get("pick", 0) >= 1
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["uncluttered"]) == {"random", POLICY}
    assert f"| {POLICY} |" in (out / "sorting.md").read_text()
    curve = json.loads((out / "curve.json").read_text())
    assert POLICY not in curve.get("uncluttered", {})  # not a confidence family: not on the curve


def _fake_views(cache, dataset, **_):
    """Tiny separable views of every chosen instance: isolated, in hand and cluttered."""
    rng = np.random.default_rng(0)
    parts = []
    for inst in dataset.chosen_instances():
        label = CATEGORIES.index(inst.category)
        for source, n in (("isolated", 3), ("in_hand", 2), ("cluttered", 1)):
            descs = [rng.normal(label, 0.3, (20, 33)).astype(np.float32) for _ in range(n)]
            known = [inst.known and source != "cluttered"] * n
            parts.append(ViewSet.from_views(descs, [label] * n, [inst.name] * n, known, source))
    return ViewSet.concat(parts)


def test_the_example_classifier_is_compared_with_the_gp_through_the_command(tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT)
    monkeypatch.setattr(sys, "path", [p for p in sys.path if p not in ("", str(ROOT))])
    monkeypatch.setenv("PYTHONPATH", "")
    for_env = perception.PerceptionEvalConfig.for_env

    def small(env_id, **overrides):  # the benchmark's configuration on tiny views
        config = for_env(env_id, **overrides)
        dataset = replace(config.dataset, per_category=1)
        return replace(config, dataset=dataset, codebook_size=8, segmentation_seeds=())

    monkeypatch.setattr(perception.PerceptionEvalConfig, "for_env", staticmethod(small))
    monkeypatch.setattr(perception, "load_or_build", _fake_views)
    monkeypatch.setattr(perception, "segmentation_scores", lambda seeds, config: {})
    out = tmp_path / "perception"
    code = main(
        ["eval", "perception", "--env", "ipbench/Sorting-v1", "--classifiers", f"gp,{CLASSIFIER}"]
        + ["--out", str(out), "--cache", str(tmp_path / "cache")]
    )
    assert code == 0
    metrics = json.loads((out / "metrics.json").read_text())
    for subset in ("5class", "3class"):
        assert list(metrics[subset]) == ["gp", CLASSIFIER]
        m = metrics[subset][CLASSIFIER]
        assert m["n"] > 0 and m["accuracy"] > 0.9  # separable views
        assert np.isfinite(m["log_loss"]) and m["in_hand"]["n"] > 0
    assert metrics["splits"]["similar"][CLASSIFIER]["n"] > 0
    assert f"| {CLASSIFIER} |" in (out / "perception.md").read_text()


def test_the_example_classifier_keeps_a_column_for_a_class_it_never_saw(here):
    here(ROOT)
    clf = make_classifier(CLASSIFIER, 5, seed=0)
    X = np.random.default_rng(0).normal(size=(30, 4))
    y = np.arange(30) % 3  # classes 3 and 4 missing
    p = clf.fit(X, y).predict_proba(X[:4])
    assert p.shape == (4, 5) and np.allclose(p.sum(1), 1) and not p[:, 3:].any()


# -- references found in the current folder, here and in worker processes ---------------------
def test_a_reference_in_the_current_folder_is_found_here_and_in_worker_processes(user_module):
    ref = "user_methods:NoArguments"
    with pytest.raises(PolicyError):  # found, but not a policy: it takes no perceiver
        check_policy_name(ref)
    assert str(user_module) in sys.path
    assert str(user_module) in os.environ["PYTHONPATH"].split(os.pathsep)
    # spawned workers (as the evaluation's) import it by name
    found = dict(run_tasks(check_classifier_name, [("user_methods:WrongShape",)] * 2, workers=2))
    assert found == {0: "user_methods:WrongShape", 1: "user_methods:WrongShape"}


def test_the_example_policy_is_found_from_the_repository_root(here):
    here(ROOT)
    assert check_policy_reference(POLICY) == POLICY
    assert split_policy_name(POLICY) == (POLICY, None)


# -- the messages ---------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "ref, message",
    [
        ("no_such_module_xyz:MyPolicy", r"cannot import module 'no_such_module_xyz'.*PYTHONPATH"),
        ("user_methods:MyPolicy", r"user_methods has no attribute 'MyPolicy' \(it has: .*NoAct"),
        ("user_methods:NoAct", r"has no method act\(observation, info\); a sorting policy"),
        ("user_methods:ActWithoutInfo", r"act cannot be called as act\(observation, info\)"),
        ("user_methods:NoArguments", r"cannot be called as NoArguments\(perceiver, name\)"),
        ("user_methods:NOT_A_CLASS", r"NOT_A_CLASS is not a class \(it is an int\)"),
        ("user_methods:", r"not a policy reference; write module:attribute"),
        ("user_methods:NoAct@0.5", r"takes no @value"),
    ],
)
def test_a_broken_policy_reference_says_what_is_missing(user_module, ref, message):
    with pytest.raises(PolicyError, match=message) as err:
        check_policy_name(ref)
    assert "docs/custom.md" in str(err.value) or "@value" in str(err.value)


def test_an_unknown_policy_name_mentions_references():
    with pytest.raises(PolicyError, match=r"valid: random, .*or a policy of your own"):
        split_policy_name("randon")


def test_the_command_refuses_a_broken_policy_before_any_training(user_module, monkeypatch):
    monkeypatch.setattr(sorting, "prepare_models", pytest.fail)  # never reached
    out = user_module / "run"
    with pytest.raises(SystemExit, match=r"user_methods:NoAct has no method act"):
        main(["eval", "sorting", "--policies", "random,user_methods:NoAct", "--out", str(out)])
    assert not out.exists()


@pytest.mark.parametrize(
    "ref, message",
    [
        ("no_such_module_xyz:Model", r"cannot import module 'no_such_module_xyz'"),
        ("user_methods:Model", r"has no attribute 'Model'"),
        ("user_methods:NoPredictProba", r"has no method predict_proba\(X\); a classifier is"),
        ("user_methods:NoArguments", r"cannot be called as NoArguments\(n_classes, seed\)"),
    ],
)
def test_a_broken_classifier_reference_says_what_is_missing(user_module, ref, message):
    with pytest.raises(ClassifierError, match=message):
        check_classifier_name(ref)


def test_the_command_refuses_a_broken_classifier_before_any_work(user_module):
    out = user_module / "perception"
    with pytest.raises(SystemExit, match=r"has no method predict_proba\(X\)"):
        main(["eval", "perception", "--classifiers", "gp,user_methods:NoPredictProba"])
    with pytest.raises(SystemExit, match=r"unknown classifier\(s\) forest; valid: gp, .*own"):
        main(["eval", "perception", "--classifiers", "gp,forest", "--out", str(out)])
    assert not out.exists()


def test_probabilities_of_the_wrong_shape_are_reported(user_module):
    clf = make_classifier("user_methods:WrongShape", 5)
    with pytest.raises(ClassifierError, match=r"returned shape \(3, 2\) for 3 rows; .*\(3, 5\)"):
        clf.fit(np.zeros((3, 4)), np.zeros(3, int)).predict_proba(np.zeros((3, 4)))


def test_a_module_that_fails_to_import_is_reported_with_its_error(tmp_path, here):
    here(tmp_path)
    (tmp_path / "broken_methods.py").write_text("import no_such_dependency_xyz\n")
    (tmp_path / "raising_methods.py").write_text("1 / 0\n")
    with pytest.raises(ReferenceLoadError, match="a module it imports is missing"):
        load_reference("broken_methods:X", "policy", (), (), "")
    with pytest.raises(ReferenceLoadError, match="ZeroDivisionError"):
        load_reference("raising_methods:X", "policy", (), (), "")
    for name in ("broken_methods", "raising_methods"):
        sys.modules.pop(name, None)
