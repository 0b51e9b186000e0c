"""Views and models prepared in one pool: the right order, and the same models as one stage
after the other (ipbench.eval.perception.prepare)."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from ipbench.assets.objects import CATEGORIES
from ipbench.eval.capture.dataset import DatasetConfig, ViewSet
from ipbench.eval.perception import prepare
from ipbench.eval.perception.evaluate import (
    PerceptionEvalConfig,
    model_key,
    model_path,
    trained_models,
)

TINY = DatasetConfig(
    yaw_step_deg=90.0,
    elevations_deg=(50.0,),
    side_elevation_deg=None,
    cluttered_seeds=(10_000,),
    per_category=1,
    in_hand_views=2,
    in_hand_placements=1,
)
CONFIG = PerceptionEvalConfig(dataset=TINY, codebook_size=16, codebook_samples=2_000)


def _fake_work(monkeypatch) -> list[str]:
    """Renders and trainings that only record what ran (in this process: ``workers=1``)."""
    ran: list[str] = []
    views = ViewSet.from_views([np.zeros((3, 33), np.float32)], [0], ["x"], [True], "isolated")

    def fake_render(kind, inst, config):
        ran.append(kind)
        return "part", views

    def fake_train(cache, config, classifiers, condition):
        ran.append(f"train {condition}")
        return "model", None

    monkeypatch.setattr(prepare, "_render", fake_render)
    monkeypatch.setattr(prepare, "_train", fake_train)
    return ran


def test_tables_top_models_train_before_the_in_hand_views_render(tmp_path, monkeypatch):
    ran = _fake_work(monkeypatch)
    prepare.prepare_perception(
        tmp_path, CONFIG, (("scene", ("gp",)), ("in_hand", ("gp",))), workers=1
    )
    n = sum(i.known for i in TINY.chosen_instances())
    assert ran == ["isolated"] * n + ["train scene"] + ["in_hand"] * n + ["train in_hand"]
    # the parts were saved where the dataset looks for them: nothing is left to render
    assert not prepare.missing_parts(tmp_path, TINY)
    # a run without in-hand models renders no in-hand views; cached models are not retrained
    ran.clear()
    shutil.rmtree(next(tmp_path.glob("parts-*")))
    prepare.prepare_perception(tmp_path, CONFIG, (("scene", ("gp",)), ("in_hand", ())), 1)
    assert ran == ["isolated"] * n + ["train scene"]
    key = model_key(CONFIG, CATEGORIES, "gp", "scene")
    model_path(tmp_path, key).write_bytes(b"cached")
    ran.clear()
    prepare.prepare_perception(tmp_path, CONFIG, (("scene", ("gp",)),), 1)
    assert ran == []


def test_follow_up_tasks_run_after_the_table_top_models_and_return_in_order(tmp_path, monkeypatch):
    ran = _fake_work(monkeypatch)

    def episode(name):
        ran.append(name)
        return name.upper()

    wanted = (("scene", ("gp",)), ("in_hand", ("gp",)))
    out = prepare.prepare_perception(
        tmp_path, CONFIG, wanted, workers=1, then=[(episode, "a"), (episode, "b")]
    )
    n = sum(i.known for i in TINY.chosen_instances())
    # last in priority: in one process after everything (in a pool, while in-hand trains)
    assert ran == (
        ["isolated"] * n + ["train scene"] + ["in_hand"] * n + ["train in_hand"] + ["a", "b"]
    )
    assert out == ["A", "B"]
    ran.clear()  # everything cached: the follow-ups still run, and alone
    for condition in ("scene", "in_hand"):
        model_path(tmp_path, model_key(CONFIG, CATEGORIES, "gp", condition)).write_bytes(b"x")
    assert prepare.prepare_perception(tmp_path, CONFIG, wanted, 1, then=[(episode, "c")]) == ["C"]
    assert ran == ["c"]
    assert prepare.prepare_perception(tmp_path, CONFIG, wanted, 1) == []


def scene_model_saved(cache, key: str) -> bool:
    """A follow-up task (module level: it runs in a spawned worker)."""
    return model_path(cache, key).exists()


def test_an_unknown_condition_is_a_clear_error(tmp_path):
    with pytest.raises(ValueError, match="valid: scene, in_hand"):
        prepare.prepare_perception(tmp_path, CONFIG, (("table", ("gp",)),), 1)


def test_models_prepared_in_one_pool_equal_those_of_one_stage_after_the_other(tmp_path):
    pooled, staged = tmp_path / "pooled", tmp_path / "staged"
    wanted = (("scene", ("gp",)), ("in_hand", ("gp",)))
    key = model_key(CONFIG, CATEGORIES, "gp", "scene")
    # a follow-up task sees the table-top model it depends on, even in another worker
    then = [(scene_model_saved, pooled, key)] * 2
    assert prepare.prepare_perception(pooled, CONFIG, wanted, workers=2, then=then) == [True] * 2
    parts = next(pooled.glob("parts-*"))
    shutil.copytree(parts, staged / parts.name)  # the same views, then the models in turn
    for condition, classifiers in wanted:
        trained_models(staged, CONFIG, CATEGORIES, classifiers, condition, workers=1)
    for condition, _ in wanted:
        name = model_path(pooled, model_key(CONFIG, CATEGORIES, "gp", condition)).name
        with np.load(pooled / name) as a, np.load(staged / name) as b:
            assert sorted(a.files) == sorted(b.files)
            for k in a.files:
                np.testing.assert_array_equal(a[k], b[k], err_msg=f"{condition}: {k}")


def test_validation_views_in_the_pool_give_the_evidence_of_a_pool_of_their_own(
    tmp_path, monkeypatch
):
    """From an empty cache the threshold's validation views are taken in the preparation pool
    (:func:`ipbench.eval.sorting.evaluate._validation_scene`); the evidence is what the separate
    validation pool gathers with the same model."""
    import json

    from ipbench.envs.sorting_scenes import SCENES
    from ipbench.eval.sorting import evaluate as sorting

    monkeypatch.setattr(sorting, "SCENES", {"uncluttered": SCENES["uncluttered"]})
    config = sorting.SortingEvalConfig(
        scenes=("uncluttered",),
        policies=("random", "gp-ipm"),
        seeds=(0,),
        validation_seeds=(1000,),
        steps_per_object=1,
        perception=CONFIG,
    )
    separate = sorting._validation_evidence

    def refuse(*args, **kwargs):
        raise AssertionError("the validation views were taken in a pool of their own")

    monkeypatch.setattr(sorting, "_validation_evidence", refuse)
    models, choices = sorting.prepare_models(tmp_path, config)
    (evidence,) = tmp_path.glob("evidence-gp-*.json")
    pooled = json.loads(evidence.read_text())
    conf, correct = separate(models.gp, config)
    assert len(conf) > 0
    assert pooled == {"confidence": conf.tolist(), "correct": correct.tolist()}
    assert choices["gp"].n == len(conf)
