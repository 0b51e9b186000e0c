"""A saved perception model round-trips; stale and corrupt files are detected and rebuilt."""

from __future__ import annotations

import numpy as np
import pytest

from ipbench.perception.features import Codebook
from ipbench.perception.gpc import GPCConfig, MulticlassLaplaceGPC
from ipbench.perception.model import ModelFileError, PerceptionModel, load_or_train


def _train(key: str = "k1") -> PerceptionModel:
    rng = np.random.default_rng(0)
    centers = [rng.normal(size=33) * 3 for _ in range(3)]
    views = [c + rng.normal(size=(40, 33)) for c in centers for _ in range(6)]
    labels = np.repeat(np.arange(3), 6)
    codebook = Codebook.fit(np.concatenate(views), k=16, seed=0)
    x = np.stack([codebook.encode(v) for v in views])
    gp = MulticlassLaplaceGPC(GPCConfig(n_samples=200, max_iter=20)).fit(x, labels)
    return PerceptionModel(("a", "b", "c"), codebook, gp, key), views


def test_round_trip_gives_identical_probabilities(tmp_path):
    model, views = _train()
    path = model.save(tmp_path / "m.npz")
    again = PerceptionModel.load(path, "k1")
    np.testing.assert_array_equal(again.probabilities(views), model.probabilities(views))
    assert again.classes == ("a", "b", "c")


def test_stale_and_corrupt_files_are_detected_and_rebuilt(tmp_path):
    model, _ = _train()
    path = model.save(tmp_path / "m.npz")
    with pytest.raises(ModelFileError, match="stale"):
        PerceptionModel.load(path, "another-key")
    messages, calls = [], []

    def train():
        calls.append(1)
        return _train("k2")[0]

    load_or_train(path, "k2", train, log=messages.append)
    assert calls and "stale" in messages[0]
    path.write_bytes(b"garbage")
    with pytest.raises(ModelFileError, match="unreadable"):
        PerceptionModel.load(path, "k2")
    load_or_train(path, "k2", train, log=messages.append)
    assert len(calls) == 2 and "unreadable" in messages[1]
    assert PerceptionModel.load(path, "k2").key == "k2"  # the rebuilt file is good
    load_or_train(path, "k2", train, log=messages.append)
    assert len(calls) == 2  # a good file is reused, not retrained


def test_package_exports_are_current():
    import ipbench.perception as perception

    for name in perception.__all__:
        assert hasattr(perception, name), name
    assert "ipbench.eval.capture.dataset" not in perception.__dict__  # no simulator import
