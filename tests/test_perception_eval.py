"""The rendered dataset, its cache, and the perception benchmark's outputs (tiny config)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from ipbench.eval.perception import PerceptionEvalConfig, run_perception_eval
from ipbench.perception.dataset import DatasetConfig, ViewSet, load_or_build

TINY = DatasetConfig(
    yaw_step_deg=60.0,
    elevations_deg=(50.0,),
    side_elevation_deg=None,
    cluttered_seeds=(10_000,),
    per_category=1,
)


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


def test_cache_is_reused_and_a_corrupt_file_is_rebuilt(cache, views, capsys):
    path = cache / f"views-{TINY.key()}.npz"
    again = load_or_build(cache, TINY, progress=False)
    np.testing.assert_array_equal(again.labels, views.labels)
    path.write_bytes(b"not a zip file")
    rebuilt = load_or_build(cache, TINY, progress=False)
    assert "unreadable" in capsys.readouterr().out
    np.testing.assert_array_equal(rebuilt.descriptors, views.descriptors)  # deterministic


def test_config_hash_changes_with_the_protocol():
    assert TINY.key() != DatasetConfig(yaw_step_deg=45.0).key()
    assert TINY.key() == DatasetConfig(**{**TINY.__dict__}).key()


def test_perception_eval_writes_the_report(cache, views, tmp_path):
    metrics = run_perception_eval(
        tmp_path,
        cache,
        PerceptionEvalConfig(dataset=TINY, codebook_size=32, segmentation_seeds=(10_100,)),
    )
    seg = json.loads((tmp_path / "segmentation.json").read_text())
    assert set(seg) == {"uncluttered", "cluttered"}
    for scene in seg.values():  # quality is tested in test_segmentation; here the wiring
        assert 0.5 <= scene["precision"] <= 1 and 0.5 <= scene["recall"] <= 1
    saved = json.loads((tmp_path / "metrics.json").read_text())
    assert saved == json.loads(json.dumps(metrics))
    for subset in ("5class", "3class"):
        for name in ("gp", "svm", "sklearn_gp"):
            m = saved[subset][name]
            for key in ("accuracy", "log_loss", "ece", "fit_s", "predict_s"):
                assert np.isfinite(m[key]), (subset, name, key)
            assert 0 <= m["accuracy"] <= 1 and 0 <= m["ece"] <= 1
            assert "cluttered" in m
    text = (tmp_path / "perception.md").read_text()
    assert "## 5class" in text and "## 3class" in text and "| cluttered |" in text
    assert (tmp_path / "confusion_5class_gp.png").stat().st_size > 1000
    assert (tmp_path / "reliability_3class.png").exists()
