"""The GP's predictive factor kept in a mapped file: the same predictions, small pickles,
reuse only by the model that wrote it, and a fallback when the file is missing or wrong."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

import ipbench.perception.gpc as gpc_module
from ipbench.perception._gpc_posterior import factor_file
from ipbench.perception.features import Codebook
from ipbench.perception.gpc import GPCConfig, MulticlassLaplaceGPC
from ipbench.perception.model import PerceptionModel, posterior_prefix


@pytest.fixture(autouse=True, scope="module")
def _one_blas_thread():
    with threadpool_limits(limits=1):
        yield


def _data(seed: int, n_per: int = 60):
    rng = np.random.default_rng(seed)
    centres = rng.normal(scale=2.0, size=(3, 8))
    X = np.vstack([rng.normal(c, 1.0, size=(n_per, 8)) for c in centres])
    return X, np.repeat(np.arange(3), n_per), rng.normal(scale=2.0, size=(9, 8))


@pytest.fixture(scope="module")
def fitted():
    X, y, Xt = _data(0)
    return MulticlassLaplaceGPC(GPCConfig(n_samples=300, max_iter=15)).fit(X, y), Xt


def _no_factorize(*_args, **_kwargs):
    raise AssertionError("the factor was computed although its file was there")


def _predictions(model: MulticlassLaplaceGPC, Xt: np.ndarray):
    mean, cov = model.predict_latent(Xt)
    return mean, cov, model.predict_proba(Xt)


def _assert_same(a, b) -> None:
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


def test_mapped_model_predicts_bit_identically_and_pickles_small(fitted, tmp_path):
    model, Xt = fitted
    state = model.get_state()
    plain = MulticlassLaplaceGPC.from_state(state)
    expected = _predictions(plain, Xt)
    mapped = MulticlassLaplaceGPC.from_state(state, posterior=tmp_path / "gp")
    path = mapped.posterior_file
    assert path is not None and path.exists() and path.parent == tmp_path
    assert isinstance(mapped._fac.E, np.memmap) or isinstance(mapped._fac.E.base, np.memmap)
    _assert_same(_predictions(mapped, Xt), expected)

    n = state["X"].shape[0]
    big, small = pickle.dumps(plain), pickle.dumps(mapped)
    assert len(big) > 4 * 8 * n * n  # the C = 3 factor matrices and M travel in full
    assert len(small) < 8 * n * n  # less than one n x n matrix: the file carries them
    clone = pickle.loads(small)
    assert clone.posterior_file == path
    _assert_same(_predictions(clone, Xt), expected)
    assert clone.log_marginal_likelihood() == pytest.approx(plain.log_marginal_likelihood())


def test_an_existing_file_is_read_not_recomputed(fitted, tmp_path, monkeypatch):
    model, Xt = fitted
    first = MulticlassLaplaceGPC.from_state(model.get_state(), posterior=tmp_path / "gp")
    monkeypatch.setattr(gpc_module, "factorize", _no_factorize)
    again = MulticlassLaplaceGPC.from_state(model.get_state(), posterior=tmp_path / "gp")
    assert again.posterior_file == first.posterior_file
    _assert_same(_predictions(again, Xt), _predictions(first, Xt))


def test_another_predictive_predicts_from_the_same_file(fitted, tmp_path, monkeypatch):
    model, Xt = fitted
    mapped = MulticlassLaplaceGPC.from_state(model.get_state(), posterior=tmp_path / "gp")
    monkeypatch.setattr(gpc_module, "factorize", _no_factorize)
    mode = mapped.with_predictive("mode")
    assert mode.posterior_file == mapped.posterior_file
    mean, cov = mapped.predict_latent(Xt)
    _assert_same(mode.predict_latent(Xt), (mean, cov))
    clone = pickle.loads(pickle.dumps(mode))  # small: the file still carries the factor
    assert clone.config.predictive == "mode" and clone.posterior_file == mapped.posterior_file
    _assert_same(_predictions(clone, Xt), _predictions(mode, Xt))


def test_another_model_never_reads_the_file(fitted, tmp_path):
    model, Xt = fitted
    X, y, _ = _data(1)
    other = MulticlassLaplaceGPC(GPCConfig(n_samples=300, max_iter=15)).fit(X, y)
    a = model.map_posterior(tmp_path / "gp")
    b = other.map_posterior(tmp_path / "gp")
    assert a != b and a.exists() and b.exists()  # the digest of each state names its file
    reloaded = MulticlassLaplaceGPC.from_state(other.get_state(), posterior=tmp_path / "gp")
    assert reloaded.posterior_file == b
    _assert_same(_predictions(reloaded, Xt), _predictions(other, Xt))


def test_a_wrong_file_is_replaced_and_a_missing_one_recomputed(fitted, tmp_path):
    model, Xt = fitted
    expected = _predictions(MulticlassLaplaceGPC.from_state(model.get_state()), Xt)
    path = factor_file(tmp_path / "gp", model._digest())
    np.save(path, np.zeros(17))  # truncated: not a factor of this size
    mapped = MulticlassLaplaceGPC.from_state(model.get_state(), posterior=tmp_path / "gp")
    assert mapped.posterior_file == path and np.load(path, mmap_mode="r").size > 17
    _assert_same(_predictions(mapped, Xt), expected)

    blob = pickle.dumps(mapped)
    path.unlink()  # e.g. unpickled on another machine
    clone = pickle.loads(blob)
    assert clone.posterior_file is None
    _assert_same(_predictions(clone, Xt), expected)


def test_an_unwritable_folder_still_gives_a_working_model(fitted, tmp_path, monkeypatch):
    model, Xt = fitted

    def refuse(*_args, **_kwargs):
        raise PermissionError("read-only folder")

    monkeypatch.setattr(gpc_module, "write_factor", refuse)
    loaded = MulticlassLaplaceGPC.from_state(model.get_state(), posterior=tmp_path / "gp")
    assert loaded.posterior_file is None
    _assert_same(_predictions(loaded, Xt), _predictions(model, Xt))


def test_saved_model_keeps_one_factor_file_beside_it(tmp_path, monkeypatch):
    rng = np.random.default_rng(0)
    views = [rng.normal(loc=3 * (i % 3), size=(30, 33)) for i in range(18)]
    codebook = Codebook.fit(np.concatenate(views), k=8, seed=0)
    x = np.stack([codebook.encode(v) for v in views])
    labels = np.arange(18) % 3
    models = [
        PerceptionModel(
            ("a", "b", "c"),
            codebook,
            MulticlassLaplaceGPC(GPCConfig(n_samples=100, max_iter=5, seed=s)).fit(x, labels),
            "k",
        )
        for s in (0, 1)
    ]
    models[1].classifier.fit(x[::-1], labels[::-1])  # another state: another digest
    path = tmp_path / "m.npz"
    models[0].save(path)
    first = sorted(tmp_path.glob(f"{posterior_prefix(path).name}-*.npy"))
    assert len(first) == 1
    models[1].save(path)  # retrained at the same place: the old factor goes
    second = sorted(tmp_path.glob(f"{posterior_prefix(path).name}-*.npy"))
    assert len(second) == 1 and second != first
    monkeypatch.setattr(gpc_module, "factorize", _no_factorize)
    loaded = PerceptionModel.load(path, "k")  # the trainer's file: nothing recomputed
    assert loaded.classifier.posterior_file == second[0]
    np.testing.assert_array_equal(loaded.probabilities(views), models[1].probabilities(views))
