"""The PointNet deep ensemble: it learns, its probabilities, its confidence away from the
training classes, its checkpoint, its reproducibility, and its place in the perception eval."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from exports import assert_exports

from ipbench.perception.model import ModelFileError
from ipbench.perception.pointnet import (
    PointNetConfig,
    PointNetEnsemble,
    load_or_train_pointnet,
)
from ipbench.perception.viewset import POINTS_PER_VIEW, ViewSet, sample_points

TINY = PointNetConfig(
    members=3, n_points=32, widths=(16, 32), head=16, epochs=40, batch_size=8, lr=1e-2
)
"""A network small enough to train in about a second."""


def _shape(kind: int, rng: np.random.Generator, n: int = 64) -> np.ndarray:
    """(n, 3) world points of a tall cylinder (0), a flat box (1) or a ball (2) on a table."""
    if kind == 0:  # radius 3 cm, 20 cm tall
        a, z = rng.uniform(0, 2 * np.pi, n), rng.uniform(0, 0.2, n)
        p = np.c_[0.03 * np.cos(a), 0.03 * np.sin(a), z]
    elif kind == 1:  # 10 x 6 x 4 cm
        p = rng.uniform([-0.05, -0.03, 0.0], [0.05, 0.03, 0.04], (n, 3))
    else:  # radius 5 cm
        v = rng.normal(size=(n, 3))
        p = 0.05 * v / np.linalg.norm(v, axis=1, keepdims=True)
    return p + rng.normal(0, 0.002, p.shape) + [0.8, rng.uniform(-0.2, 0.2), 0.75]


def _data(seed: int = 0, per_class: int = 8):
    rng = np.random.default_rng(seed)
    labels = np.repeat(np.arange(3), per_class)
    return np.stack([_shape(k, rng) for k in labels]), labels


@pytest.fixture(scope="module")
def trained():
    clouds, labels = _data()
    return PointNetEnsemble(3, TINY, ("cylinder", "box", "ball"), "k1").fit(clouds, labels)


def test_the_network_overfits_a_tiny_labelled_set(trained):
    clouds, labels = _data()
    assert (trained.predict(clouds) == labels).all()
    for losses in trained.losses:  # every member learnt
        assert losses[-1] < 0.25 * losses[0]
    assert len(trained.members) == TINY.members


def test_probabilities_are_distributions_for_clouds_of_any_size(trained):
    rng = np.random.default_rng(5)
    clouds = [_shape(0, rng, 7), _shape(1, rng, 500), _shape(2, rng, 32)]
    p = trained.predict_proba(clouds)
    assert p.shape == (3, 3) and (p >= 0).all()
    np.testing.assert_allclose(p.sum(axis=1), 1.0, atol=1e-9)
    assert trained.probabilities([]).shape == (0, 3)
    # a segment's probabilities do not depend on the other segments passed with it (up to
    # float32 rounding: the batch size changes the matrix kernels)
    np.testing.assert_allclose(trained.predict_proba(clouds[1:2])[0], p[1], rtol=1e-5, atol=1e-7)
    with pytest.raises(ValueError, match=r"cloud 0: expected a non-empty \(n, 3\)"):
        trained.predict_proba([np.zeros((5, 2))])
    with pytest.raises(ValueError, match="not fitted"):
        PointNetEnsemble(3, TINY).predict_proba(clouds)


def test_the_ensemble_is_less_confident_on_clouds_unlike_any_class(trained):
    """Random anisotropic blobs, the size of the training objects but none of their shapes:
    the mean confidence is clearly below that on the training views."""
    clouds, _ = _data()
    rng = np.random.default_rng(11)
    blobs = [
        rng.normal(0, rng.uniform(0.005, 0.06, 3), (200, 3)) + [0.8, 0, 0.75] for _ in range(30)
    ]
    on_train = trained.predict_proba(clouds).max(axis=1).mean()
    on_blobs = trained.predict_proba(blobs).max(axis=1).mean()
    assert on_blobs < on_train - 0.05, (on_blobs, on_train)


def test_the_checkpoint_round_trips_and_a_bad_one_is_retrained(trained, tmp_path):
    clouds, _ = _data(seed=3)
    path = trained.save(tmp_path / "pn.npz")
    again = PointNetEnsemble.load(path, "k1")
    np.testing.assert_array_equal(again.predict_proba(clouds), trained.predict_proba(clouds))
    assert again.classes == trained.classes and again.config == TINY
    with pytest.raises(ModelFileError, match="stale"):
        PointNetEnsemble.load(path, "k2")
    messages, calls = [], []

    def train():
        calls.append(1)
        return trained

    assert load_or_train_pointnet(path, "k1", train, log=messages.append) is not trained
    assert not calls  # a good file is reused
    path.write_bytes(b"not a zip file")
    with pytest.raises(ModelFileError, match="unreadable"):
        PointNetEnsemble.load(path, "k1")
    load_or_train_pointnet(path, "k1", train, log=messages.append)
    assert calls == [1] and "unreadable" in messages[0] and "training a new model" in messages[0]
    assert PointNetEnsemble.load(path, "k1").key == "k1"  # the rebuilt file is good
    np.savez(path, version=np.array(1), key=np.array("k1"))  # right key, no weights
    with pytest.raises(ModelFileError, match="incomplete"):
        PointNetEnsemble.load(path, "k1")


def test_training_is_reproducible_and_restores_torch_settings(trained):
    clouds, labels = _data()
    threads = torch.get_num_threads()
    again = PointNetEnsemble(3, TINY).fit(clouds, labels)
    assert torch.get_num_threads() == threads
    assert not torch.are_deterministic_algorithms_enabled()
    for a, b in zip(again.members, trained.members, strict=True):
        for (name, x), (_, y) in zip(a.state_dict().items(), b.state_dict().items(), strict=True):
            assert torch.equal(x, y), name
    other = PointNetEnsemble(3, PointNetConfig(**{**TINY.__dict__, "seed": 1}))
    other.fit(clouds, labels)
    assert not torch.equal(other.members[0].head[-1].weight, trained.members[0].head[-1].weight)


def test_temperature_is_fitted_on_held_out_instances():
    clouds, labels = _data(per_class=6)
    groups = np.array([f"{k}_{i % 3}" for i, k in enumerate(labels)])  # 3 instances per class
    config = PointNetConfig(**{**TINY.__dict__, "members": 1, "calibrate": True})
    model = PointNetEnsemble(3, config).fit(clouds, labels, groups=groups)
    assert 0.05 <= model.temperature <= 20 and model.temperature != 1.0
    with pytest.raises(ValueError, match="needs groups"):
        PointNetEnsemble(3, config).fit(clouds, labels)


def test_views_without_points_are_refused():
    clouds = np.full((3, 10, 3), np.nan)
    with pytest.raises(ValueError, match="DATASET_VERSION >= 3"):
        PointNetEnsemble(3, TINY).fit(clouds, np.arange(3))


def test_sample_points_is_seeded_and_keeps_small_segments_whole():
    rng = np.random.default_rng(0)
    big, small = rng.normal(size=(2000, 3)), rng.normal(size=(10, 3))
    a = sample_points(big, 64, np.random.default_rng(1))
    np.testing.assert_array_equal(a, sample_points(big, 64, np.random.default_rng(1)))
    assert a.dtype == np.float32 and len(np.unique(a, axis=0)) == 64  # no repeats
    b = sample_points(small, 64, np.random.default_rng(1))
    assert len(np.unique(b, axis=0)) == 10  # every point of a small segment kept
    with pytest.raises(ValueError, match=r"non-empty \(m, 3\)"):
        sample_points(np.zeros((0, 3)), 8, rng)


def _views(rng: np.random.Generator) -> ViewSet:
    """Isolated views of known instances, 4 per class, with FPFH-like descriptors and points."""
    from ipbench.assets.objects import CATEGORIES

    sets = []
    for label in range(len(CATEGORIES)):
        desc = [rng.normal(label, 0.3, (20, 33)).astype(np.float32) for _ in range(6)]
        pts = [sample_points(_shape(label % 3, rng), POINTS_PER_VIEW, rng) for _ in range(6)]
        names = [f"{CATEGORIES[label]}_{i % 2}" for i in range(6)]
        sets.append(ViewSet.from_views(desc, [label] * 6, names, [True] * 6, "isolated", pts))
    return ViewSet.concat(sets)


def test_trained_models_caches_the_ensemble_beside_the_gp(tmp_path, monkeypatch):
    import ipbench.eval.perception.evaluate as perception

    views = _views(np.random.default_rng(0))
    monkeypatch.setattr(perception, "load_or_build", lambda cache, dataset, **_: views)
    small = PointNetConfig(members=2, n_points=32, widths=(8,), head=8, epochs=2)
    config = perception.PerceptionEvalConfig(codebook_size=8, pointnet=small)
    names = ("gp", "pointnet_ensemble")
    models = perception.trained_models(tmp_path, config, classifiers=names)
    pointnet = models["pointnet_ensemble"]
    assert isinstance(pointnet, PointNetEnsemble) and pointnet.config.seed == config.seed
    assert pointnet.classes == models["gp"].classes and pointnet.key != models["gp"].key
    assert pointnet.probabilities([views.points[0]]).shape == (1, len(pointnet.classes))
    assert len(list(tmp_path.glob("model-*.npz"))) == 2
    again = perception.trained_models(tmp_path, config, classifiers=names)  # from the cache
    np.testing.assert_array_equal(
        again["pointnet_ensemble"].probabilities(list(views.points[:3])),
        pointnet.probabilities(list(views.points[:3])),
    )
    # the network's settings key the ensemble only, never the FPFH models
    other = perception.PerceptionEvalConfig(codebook_size=8, pointnet=PointNetConfig(epochs=3))
    assert perception.model_key(other, pointnet.classes, "gp") == models["gp"].key
    assert perception.model_key(other, pointnet.classes, names[1]) != pointnet.key
    with pytest.raises(ValueError, match="valid: gp, gp_mode, svm, sklearn_gp, pointnet"):
        perception.trained_models(tmp_path, config, classifiers=("pointnet",))


def test_the_pointnet_modules_export_their_public_names():
    for short in ("pointnet", "_pointnet_net", "_pointnet_config"):
        assert_exports(f"ipbench.perception.{short}")
