"""The rendered dataset, its cache, and the perception benchmark's outputs (tiny config)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from exports import assert_exports

from ipbench.assets.objects import CATEGORIES
from ipbench.eval.capture.dataset import DatasetConfig, ViewSet, load_or_build
from ipbench.eval.perception.evaluate import (
    CONDITIONS,
    SPLIT_TESTS,
    PerceptionEvalConfig,
    run_perception_eval,
    split_tests,
    training_views,
)
from ipbench.perception.pointnet import PointNetConfig
from ipbench.perception.viewset import POINTS_PER_VIEW

TINY = DatasetConfig(
    yaw_step_deg=60.0,
    elevations_deg=(50.0,),
    side_elevation_deg=None,
    cluttered_seeds=(10_000,),
    per_category=1,
    in_hand_views=3,
    in_hand_placements=2,
)


@pytest.mark.parametrize(
    "name",
    [
        "ipbench.eval.capture.dataset",
        "ipbench.perception.viewset",
        "ipbench.eval.capture.hand_views",
        "ipbench.eval.perception.evaluate",
    ],
)
def test_export_lists_name_the_public_definitions(name):
    assert_exports(name)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("cache")


@pytest.fixture(scope="module")
def views(cache) -> ViewSet:
    return load_or_build(cache, TINY, progress=False)


def test_views_cover_known_and_unknown_instances(views):
    isolated = views.source == "isolated"
    assert isolated.sum() >= 0.9 * 10 * 6  # 10 instances x 6 yaws, a few may lose the object
    assert set(views.labels[isolated]) == set(range(5))
    assert views.known[isolated].any() and (~views.known[isolated]).any()
    assert (views.source == "cluttered").sum() >= 5
    for i in range(len(views)):
        d = views.view(i)
        assert d.ndim == 2 and d.shape[1] == 33 and len(d) > 10 and np.isfinite(d).all()
    # every view of every source keeps a sample of its points (world frame: above the table)
    assert views.points.shape == (len(views), POINTS_PER_VIEW, 3)
    assert views.points.dtype == np.float32 and np.isfinite(views.points).all()
    assert (views.points[..., 2] > 0.5).all()
    for i in np.flatnonzero(views.source == "isolated")[:5]:  # an object, not a table patch
        extent = np.ptp(views.points[i], axis=0)
        assert 0.01 < extent.max() < 0.5


def test_in_hand_views_show_each_instance_held_by_the_gripper(views):
    hand = views.subset(views.source == "in_hand")
    # 10 instances x (upright + side where it can lie) x 2 grasps x 3 views; a grasp may fail
    assert len(hand) >= 0.8 * 3 * 2 * 18
    assert set(hand.labels) == set(range(5))
    assert hand.known.any() and (~hand.known).any()
    for name, label in zip(hand.instance, hand.labels, strict=True):
        assert name.rsplit("_", 1)[0] == CATEGORIES[label]
    for i in range(len(hand)):
        d = hand.view(i)
        assert d.shape[1] == 33 and len(d) > 0 and np.isfinite(d).all()


def test_a_wide_bowl_is_captured_in_hand() -> None:
    """Dataset version 2: the capture holds a v2 noodle bowl (18 cm, in 21 cm jaws) with the
    pads under its rim; with the pads 2 cm lower (version 1) it held none, and the in-hand
    model had never seen one."""
    from ipbench.assets.objects import instances
    from ipbench.eval.capture.hand_views import render_in_hand_views

    config = DatasetConfig(env_id="ipbench/Sorting-v2", in_hand_views=2, in_hand_placements=1)
    bowl = instances(catalog="v2", family="noodle")[0]
    views = render_in_hand_views(bowl, config)
    assert len(views) == 2 and set(views.instance) == {bowl.name}


def test_each_condition_trains_on_its_own_known_views(views):
    for condition, source in CONDITIONS.items():
        train = training_views(views, condition)
        assert len(train) > 0 and train.known.all() and (train.source == source).all()
    with pytest.raises(ValueError, match="valid: scene, in_hand"):
        training_views(views, "head")


def test_in_hand_models_are_cached_apart_and_need_in_hand_views(views, tmp_path, monkeypatch):
    import ipbench.eval.perception.evaluate as perception

    config = PerceptionEvalConfig(dataset=TINY, codebook_size=16)
    monkeypatch.setattr(perception, "load_or_build", lambda cache, dataset, **_: views)
    scene = perception.trained_model(tmp_path, config)
    hand = perception.trained_models(tmp_path, config, condition="in_hand")["gp"]
    assert hand.key != scene.key and len(list(tmp_path.glob("model-*.npz"))) == 2
    # one codebook for both conditions: the one fitted on the isolated views
    np.testing.assert_array_equal(hand.codebook.centers, scene.codebook.centers)
    without = views.subset(views.source != "in_hand")
    monkeypatch.setattr(perception, "load_or_build", lambda cache, dataset, **_: without)
    with pytest.raises(ValueError, match="in_hand_views > 0"):
        perception.trained_models(tmp_path / "other", config, condition="in_hand")


def test_a_set_of_views_checks_its_source_and_lengths():
    one = np.ones((4, 33), np.float32)
    vs = ViewSet.from_views([one, one[:2]], [1, 2], ["a", "b"], [True, False], "in_hand")
    assert len(vs) == 2 and vs.view(1).shape == (2, 33) and list(vs.offsets) == [0, 4, 6]
    with pytest.raises(ValueError, match="valid: isolated, cluttered, in_hand"):
        ViewSet.from_views([one], [1], ["a"], [True], "table")
    with pytest.raises(ValueError, match="one entry per view"):
        ViewSet.from_views([one], [1, 2], ["a"], [True], "isolated")
    assert np.isnan(vs.points).all()  # stored without points
    with pytest.raises(ValueError, match="one \\(512, 3\\) sample per view"):
        ViewSet.from_views([one], [1], ["a"], [True], "isolated", [np.zeros((5, 3))])


def test_cache_is_reused_and_a_corrupt_file_is_rebuilt(cache, views, capsys):
    path = cache / f"views-{TINY.key()}.npz"
    again = load_or_build(cache, TINY, progress=False)
    np.testing.assert_array_equal(again.labels, views.labels)
    path.write_bytes(b"not a zip file")
    rebuilt = load_or_build(cache, TINY, progress=False)
    assert "unreadable" in capsys.readouterr().out
    np.testing.assert_array_equal(rebuilt.descriptors, views.descriptors)  # deterministic


def test_training_only_build_renders_just_the_known_instances(cache, views, tmp_path, monkeypatch):
    import ipbench.eval.capture.dataset as dataset

    known = views.subset(views.known & (views.source != "cluttered"))
    # from the parts of a whole build: exactly the known views of the whole set, in order
    whole_file = load_or_build(cache, TINY, progress=False, training_only=True)
    parts = tmp_path / "parts_only"
    shutil.copytree(cache, parts)
    for f in [*parts.glob("views-*.npz"), *parts.glob("parts-*/cluttered.npz")]:
        f.unlink()
    parts_only = load_or_build(parts, TINY, progress=False, training_only=True)
    for reused in (whole_file, parts_only):
        np.testing.assert_array_equal(reused.descriptors, known.descriptors)
        np.testing.assert_array_equal(reused.instance, known.instance)
        np.testing.assert_array_equal(reused.source, known.source)
    assert not list(parts.glob("views-*.npz")) and not list(parts.glob("parts-*/cluttered.npz"))
    # from nothing: no test instance and no cluttered scene is rendered, no whole file written
    rendered = []

    def fake_render(kind, inst, config):
        rendered.append((kind, inst.known))
        return known.subset(known.instance == known.instance[0])

    def no_clutter(*args, **kwargs):
        raise AssertionError("a training-only build rendered the cluttered scenes")

    monkeypatch.setattr(dataset, "render_part", fake_render)
    monkeypatch.setattr(dataset, "render_cluttered_segments", no_clutter)
    empty = tmp_path / "empty"
    load_or_build(empty, TINY, progress=False, workers=1, training_only=True)
    n_known = sum(i.known for i in TINY.chosen_instances())
    assert sorted(rendered) == sorted([("isolated", True), ("in_hand", True)] * n_known)
    assert not list(empty.glob("views-*.npz"))


def test_config_hash_changes_with_the_protocol():
    assert TINY.key() != DatasetConfig(yaw_step_deg=45.0).key()
    assert TINY.key() == DatasetConfig(**{**TINY.__dict__}).key()


def test_perception_eval_writes_the_report(cache, views, tmp_path):
    metrics = run_perception_eval(
        tmp_path,
        cache,
        PerceptionEvalConfig(
            dataset=TINY,
            codebook_size=32,
            segmentation_seeds=(10_100,),
            pointnet=PointNetConfig(members=2, n_points=64, widths=(16, 32), head=16, epochs=3),
        ),
    )
    seg = json.loads((tmp_path / "segmentation.json").read_text())
    assert set(seg) == {"uncluttered", "cluttered"}
    for scene in seg.values():  # quality is tested in test_segmentation; here the wiring
        assert 0.5 <= scene["precision"] <= 1 and 0.5 <= scene["recall"] <= 1
    saved = json.loads((tmp_path / "metrics.json").read_text())
    assert saved == json.loads(json.dumps(metrics))
    for subset in ("5class", "3class"):
        assert "pointnet_ensemble" in saved[subset]  # in the default list
        assert saved[subset]["pointnet_ensemble"]["predict_ms_per_scene"] > 0
        for name in ("gp", "svm", "sklearn_gp", "pointnet_ensemble"):
            m = saved[subset][name]
            for key in ("accuracy", "log_loss", "ece", "fit_s", "predict_s"):
                assert np.isfinite(m[key]), (subset, name, key)
            assert 0 <= m["accuracy"] <= 1 and 0 <= m["ece"] <= 1
            assert "cluttered" in m
            hand, table = m["in_hand"], m["in_hand_scene_model"]
            assert hand["n"] == table["n"] > 0
            assert 0 <= hand["accuracy"] <= 1 and 0 <= table["accuracy"] <= 1
    splits = saved["splits"]
    assert list(splits) == list(SPLIT_TESTS)
    assert splits["novel"]["gp"]["n"] == 0  # v1 has one family per category: nothing novel
    for split in ("similar", "in_hand", "clutter"):
        for name in ("gp", "svm", "pointnet_ensemble"):
            m = splits[split][name]
            assert m["n"] > 0 and 0 <= m["accuracy"] <= 1 and np.isfinite(m["log_loss"])
    assert splits["similar"]["gp"]["accuracy"] == saved["5class"]["gp"]["accuracy"]
    assert splits["in_hand"]["gp"]["accuracy"] == saved["5class"]["gp"]["in_hand"]["accuracy"]
    assert "ablation" not in saved  # v1 runs no sensor ablation
    assert "in_hand_ablation" not in saved  # nor the in-hand one
    for condition in ("in_hand", "table_top"):  # fused accuracy for 1..6 views, per classifier
        fused = saved["fusion"][condition]["gp"]
        assert len(fused["accuracy_by_views"]) == len(fused["bayes_accuracy_by_views"]) == 6
        assert fused["accuracy_by_views"][0] == pytest.approx(
            splits["in_hand" if condition == "in_hand" else "similar"]["gp"]["accuracy"]
        )
    text = (tmp_path / "perception.md").read_text()
    assert "## 5 classes on every test split" in text and "| pointnet_ensemble |" in text
    assert "## PointNet deep ensemble" in text
    assert "## Fused accuracy against the number of views" in text
    assert "## 5class" in text and "## 3class" in text and "| cluttered |" in text
    assert "In hand:" in text and "table-top model accuracy" in text
    assert (tmp_path / "confusion_5class_gp.png").stat().st_size > 1000
    assert (tmp_path / "reliability_3class.png").exists()


def test_split_tests_follow_each_instance_split():
    from ipbench.assets.objects import instances

    by_split = {}
    for inst in instances(catalog="v2"):
        by_split.setdefault(inst.split, inst)
    one = np.ones((3, 33), np.float32)
    names = [by_split[s].name for s in ("train", "similar", "novel")]
    labels = [CATEGORIES.index(by_split[s].category) for s in ("train", "similar", "novel")]
    known = [True, False, False]
    iso = ViewSet.from_views([one] * 3, labels, names, known, "isolated")
    hand = ViewSet.from_views([one] * 3, labels, names, known, "in_hand")
    clutter = ViewSet.from_views([one], labels[:1], names[:1], known[:1], "cluttered")
    sets = split_tests(ViewSet.concat([iso, hand, clutter]), "v2")
    assert list(sets) == list(SPLIT_TESTS)
    assert list(sets["similar"].instance) == [names[1]]
    assert list(sets["novel"].instance) == [names[2]]
    assert sorted(sets["in_hand"].instance) == sorted(names[1:])  # never a trained instance
    assert len(sets["clutter"]) == 1


def test_v2_dataset_uses_the_v2_objects_and_sensor():
    from ipbench.envs.sensors.depth_noise import STRUCTURED_LIGHT

    config = DatasetConfig(env_id="ipbench/Sorting-v2", per_category=1)
    assert config.sensor == STRUCTURED_LIGHT and config.catalog == "v2"
    chosen = config.chosen_instances()
    assert {(i.category, i.split) for i in chosen} == {
        (c, s) for c in CATEGORIES for s in ("train", "similar", "novel")
    }
    assert len(chosen) == 15
    assert DatasetConfig().sensor != STRUCTURED_LIGHT and DatasetConfig().catalog == "v1"
    assert config.key() != DatasetConfig(per_category=1).key()
    with pytest.raises(ValueError, match="valid: ipbench/Sorting-v0"):
        DatasetConfig(env_id="ipbench/Sorting-v9")


def test_sensor_ablation_switches_each_effect_off_in_turn(tmp_path, monkeypatch):
    import ipbench.eval.perception.evaluate as perception

    seen = []

    def fake_build(cache, dataset, **_):  # records what would be captured; tiny separable data
        seen.append(dataset)
        rng = np.random.default_rng(len(seen))
        views = []
        for inst in dataset.chosen_instances():
            label = CATEGORIES.index(inst.category)
            for _ in range(3):  # views per instance
                desc = rng.normal(label, 0.1, (20, 33)).astype(np.float32)
                one = ViewSet.from_views([desc], [label], [inst.name], [inst.known], "isolated")
                views.append(one)
        return ViewSet.concat(views)

    monkeypatch.setattr(perception, "load_or_build", fake_build)
    config = PerceptionEvalConfig.for_env(
        "ipbench/Sorting-v2", codebook_size=8, classifiers=("svm",)
    )
    assert config.ablation
    result = perception.sensor_ablation(tmp_path, config)
    assert list(result)[0] == "none" and len(result) >= 2
    sensors = [d.sensor for d in seen]
    assert len(set(map(repr, sensors))) == len(sensors)  # each run captured another sensor
    for effect, dataset in zip(result, seen, strict=True):
        assert dataset.yaw_step_deg == perception.ABLATION_PROTOCOL["yaw_step_deg"]
        assert result[effect]["svm"]["n"] > 0
