"""Classifier interface, metrics against hand-computed values, synthetic data, public API."""

from __future__ import annotations
import __future__

import inspect
import math
import pickle
from types import ModuleType

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from ipbench.perception import classifiers, gpc, metrics, synthetic
from ipbench.perception.classifiers import (
    CLASSIFIERS,
    Classifier,
    ClassifierError,
    GPClassifier,
    make_classifier,
)
from ipbench.perception.synthetic import SyntheticBoW, SyntheticConfig, make_split


@pytest.fixture(autouse=True, scope="module")
def _one_blas_thread():
    """One BLAS thread: on a shared machine OpenBLAS threads busy-wait and run 100x slower."""
    with threadpool_limits(limits=1):
        yield


def public_names(module: ModuleType) -> set[str]:
    """Names a module defines itself (classes, functions, constants), without a leading _."""
    names = set()
    for name, value in vars(module).items():
        if name.startswith("_") or inspect.ismodule(value):
            continue
        if isinstance(value, __future__._Feature):
            continue
        if inspect.isclass(value) or inspect.isfunction(value):
            if value.__module__ != module.__name__:
                continue
        names.add(name)
    return names


@pytest.mark.parametrize("module", [gpc, classifiers, metrics, synthetic])
def test_all_lists_exactly_the_public_names(module: ModuleType) -> None:
    assert sorted(module.__all__) == sorted(public_names(module))


@pytest.fixture(scope="module")
def data() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    return make_split(250, 200, seed=1)


@pytest.mark.parametrize("name", CLASSIFIERS)
def test_classifier_learns_synthetic_data(name: str, data) -> None:
    X, y, Xt, yt = data
    clf = make_classifier(name, n_classes=5, seed=0)
    assert isinstance(clf, Classifier) and clf.name == name
    with pytest.raises((ClassifierError, gpc.GPCError), match="not fitted"):
        clf.predict_proba(Xt)
    assert clf.fit(X, y) is clf
    P = clf.predict_proba(Xt)
    assert P.shape == (Xt.shape[0], 5)
    assert np.all(P >= 0.0) and np.all(P <= 1.0)
    np.testing.assert_allclose(P.sum(axis=1), 1.0, atol=1e-9)
    np.testing.assert_array_equal(clf.predict(Xt), P.argmax(axis=1))
    assert metrics.accuracy(yt, clf.predict(Xt)) > 0.2 + 0.4  # chance is 0.2


def test_sklearn_based_classifiers_keep_all_columns_and_pickle(data) -> None:
    X, y, Xt, _ = data
    keep = y != 3  # class 3 never seen in training
    clf = make_classifier("svm", n_classes=5).fit(X[keep], y[keep])
    P = clf.predict_proba(Xt)
    assert P.shape == (Xt.shape[0], 5) and np.all(P[:, 3] == 0.0)
    np.testing.assert_array_equal(pickle.loads(pickle.dumps(clf)).predict_proba(Xt), P)


def test_sklearn_gp_tunes_its_kernel(data) -> None:
    X, y, _, _ = data
    clf = make_classifier("sklearn_gp", n_classes=5).fit(X, y)
    initial = clf.estimator_.kernel.theta  # log (amplitude^2, length scale) before fitting
    binaries = clf.estimator_.base_estimator_.estimators_  # one-vs-rest: one per class
    assert len(binaries) == 5
    for binary in binaries:
        assert np.all(np.abs(binary.kernel_.theta - initial) > 1e-3)


def test_gp_classifier_state_round_trip(data) -> None:
    X, y, Xt, _ = data
    clf = make_classifier("gp", n_classes=5, seed=3).fit(X[:100], y[:100])
    clone = GPClassifier.from_state(clf.get_state())
    assert clone.n_classes == 5 and clone.seed == 3
    np.testing.assert_array_equal(clone.predict_proba(Xt), clf.predict_proba(Xt))


def test_unknown_classifier_lists_valid_names() -> None:
    with pytest.raises(ClassifierError, match="gp, gp_mode, svm, sklearn_gp"):
        make_classifier("random_forest", n_classes=5)
    with pytest.raises(ClassifierError, match=">= 2"):
        make_classifier("gp", n_classes=1)
    assert issubclass(ClassifierError, ValueError)


def test_svm_says_when_a_class_has_too_few_views_for_platt_calibration(data) -> None:
    X, y, _, _ = data
    few = np.concatenate([np.flatnonzero(y != 2), np.flatnonzero(y == 2)[:3]])
    with pytest.raises(ClassifierError, match=r"at least 5 training views"):
        make_classifier("svm", n_classes=5).fit(X[few], y[few])
    absent = np.flatnonzero(y != 2)  # a class missing altogether is allowed
    probs = make_classifier("svm", n_classes=5).fit(X[absent], y[absent]).predict_proba(X[:4])
    assert probs.shape == (4, 5) and np.allclose(probs[:, 2], 0.0)


# ----------------------------------------------------------------------------- metrics
PROBS = np.array([[0.9, 0.1], [0.6, 0.4], [0.3, 0.7], [0.2, 0.8]])
LABELS = np.array([0, 1, 1, 1])


def test_accuracy_and_log_loss_by_hand() -> None:
    assert metrics.accuracy(LABELS, PROBS.argmax(axis=1)) == 0.75
    expected = -(math.log(0.9) + math.log(0.4) + math.log(0.7) + math.log(0.8)) / 4
    assert metrics.log_loss(PROBS, LABELS) == pytest.approx(expected, abs=1e-12)
    # A confident mistake is clipped at eps, not infinite.
    assert metrics.log_loss(np.array([[1.0, 0.0]]), np.array([1]), eps=1e-6) == pytest.approx(
        -math.log(1e-6)
    )


def test_ece_and_reliability_curve_by_hand() -> None:
    # Confidences 0.9, 0.6, 0.7, 0.8; correct: yes, no, yes, yes. With 2 bins (0, .5], (.5, 1]
    # all fall in bin 1: conf 0.75, acc 0.75 -> ECE 0.
    assert metrics.expected_calibration_error(PROBS, LABELS, n_bins=2) == pytest.approx(0.0)
    # With 5 bins: (.4,.6] holds 0.6 (wrong), (.6,.8] holds 0.7, 0.8, (.8,1] holds 0.9.
    conf, acc, count = metrics.reliability_curve(PROBS, LABELS, n_bins=5)
    np.testing.assert_array_equal(count, [0, 0, 1, 2, 1])
    np.testing.assert_allclose(conf[2:], [0.6, 0.75, 0.9])
    np.testing.assert_allclose(acc[2:], [0.0, 1.0, 1.0])
    assert np.isnan(conf[0]) and np.isnan(acc[1])
    ece = (1 * 0.6 + 2 * 0.25 + 1 * 0.1) / 4
    assert metrics.expected_calibration_error(PROBS, LABELS, n_bins=5) == pytest.approx(ece)


def test_ece_is_zero_for_perfectly_calibrated_and_large_when_overconfident() -> None:
    probs = np.tile([0.75, 0.25], (8, 1))
    labels = np.array([0, 0, 0, 1, 0, 0, 0, 1])  # 75 % correct at confidence 0.75
    assert metrics.expected_calibration_error(probs, labels) == pytest.approx(0.0)
    over = np.tile([0.99, 0.01], (4, 1))
    assert metrics.expected_calibration_error(over, np.array([0, 1, 0, 1])) == pytest.approx(0.49)


def test_confusion_precision_recall_by_hand() -> None:
    labels = np.array([0, 0, 1, 1, 1, 2])
    preds = np.array([0, 1, 1, 1, 0, 1])
    cm = metrics.confusion_matrix(labels, preds, 3)
    np.testing.assert_array_equal(cm, [[1, 1, 0], [1, 2, 0], [0, 1, 0]])
    precision, recall = metrics.per_class_precision_recall(labels, preds, 3)
    np.testing.assert_allclose(precision[:2], [1 / 2, 2 / 4])
    np.testing.assert_allclose(recall, [1 / 2, 2 / 3, 0.0])
    assert np.isnan(precision[2])  # class 2 never predicted
    with pytest.raises(ValueError, match="0..2"):
        metrics.confusion_matrix(labels, preds + 2, 3)
    with pytest.raises(ValueError):
        metrics.log_loss(PROBS, np.array([0, 1, 2, 0]))


# --------------------------------------------------------------------------- synthetic
def test_synthetic_data_shape_and_determinism() -> None:
    a = make_split(60, 40, seed=5)
    b = make_split(60, 40, seed=5)
    c = make_split(60, 40, seed=6)
    for u, v in zip(a, b, strict=True):
        np.testing.assert_array_equal(u, v)
    assert not np.array_equal(a[0], c[0])
    X, y, Xt, yt = a
    assert X.shape == (60, 256) and Xt.shape == (40, 256)
    np.testing.assert_allclose(np.linalg.norm(X, axis=1), 1.0)
    assert np.all(X >= 0.0)
    # Max pooling: every non-zero entry of a row has the same value 1 / sqrt(#words).
    row = X[0][X[0] > 0]
    np.testing.assert_allclose(row, 1.0 / np.sqrt(row.size))
    assert np.bincount(y, minlength=5).min() == 12  # balanced


def test_synthetic_difficulty_is_tunable() -> None:
    cfg = SyntheticConfig(n_classes=3, vocab_size=64)
    gen = SyntheticBoW(cfg, seed=0)
    assert gen.word_probs.shape == (3, cfg.n_instances, 64)
    np.testing.assert_allclose(gen.word_probs.sum(axis=2), 1.0)
    scores = []
    for sep in (0.0, 2.0):
        X, y, Xt, yt = make_split(150, 150, SyntheticConfig(separation=sep), seed=2)
        clf = make_classifier("svm", n_classes=5).fit(X, y)
        scores.append(metrics.accuracy(yt, clf.predict(Xt)))
    assert scores[0] < 0.4 < 0.8 < scores[1]
    with pytest.raises(ValueError):
        SyntheticConfig(distractor_rate=1.5)


def test_gp_mode_shares_the_fit_and_is_more_confident(data) -> None:
    """The plug-in predictive is the softmax of the same latent mean; MC through the Laplace
    posterior averages over the latent spread, so it is less confident on every point."""
    X, y, Xt, _ = data
    mc = make_classifier("gp", n_classes=5, seed=0).fit(X[:150], y[:150])
    mode = GPClassifier.from_model(mc.model_.with_predictive("mode"))
    assert mode.name == "gp_mode" and mc.name == "gp"
    mean, _ = mc.model_.predict_latent(Xt)
    expected = np.exp(mean - mean.max(axis=1, keepdims=True))
    np.testing.assert_allclose(mode.predict_proba(Xt), expected / expected.sum(1, keepdims=True))
    assert np.mean(mode.predict_proba(Xt).max(1)) > np.mean(mc.predict_proba(Xt).max(1))
    with pytest.raises(gpc.GPCError, match="mc, mode"):
        mc.model_.with_predictive("median")
