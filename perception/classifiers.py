"""One interface, three probabilistic classifiers for the object categories.

* ``"gp"``: :class:`~ipbench.perception.gpc.MulticlassLaplaceGPC`, the joint multi-class
  Laplace GP (softmax likelihood, shared SE kernel, ML-II hyper-parameters).
* ``"gp_mode"``: the same fitted GP with the plug-in predictive (softmax of the latent
  mean; ``GPCConfig(predictive="mode")``), which is not under-confident the way the Laplace
  Monte-Carlo predictive is (see :mod:`~ipbench.perception.gpc`).
* ``"svm"``: an RBF support-vector machine with Platt-scaled probabilities. scikit-learn
  1.9 deprecates ``SVC(probability=True)``, so calibration is explicit:
  ``CalibratedClassifierCV(SVC(kernel="rbf", C=C, gamma="scale"), method="sigmoid", cv=5)``
  (one-vs-rest sigmoids, renormalised), with ``C`` chosen from ``SVM_C_GRID`` by 3-fold
  cross-validated accuracy on the training set first.
* ``"sklearn_gp"``: scikit-learn's ``GaussianProcessClassifier``: one-vs-rest binary
  Laplace GPs, no joint multi-class posterior. It is given the explicit kernel
  ``ConstantKernel * RBF`` (length scale initialised at the median pairwise distance)
  because with ``kernel=None`` scikit-learn *fixes* the hyper-parameters of its default
  ``1.0 * RBF(1.0)`` and tunes nothing.

A classifier of the user's own is named ``module:attribute`` (``mypkg.models:MyClassifier``):
built as ``MyClassifier(n_classes, seed)``, with ``fit(X, y)`` and ``predict_proba(X)`` as
below (:func:`load_classifier` checks it; ``docs/custom.md``).

All classifiers return ``(m, n_classes)`` probabilities whose columns are the classes
``0 .. n_classes - 1``, also when a class is missing from the training labels. The GP can be
saved with ``get_state`` / ``from_state``; the scikit-learn based ones are plain Python
objects that the caller can pickle.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
from sklearn.base import BaseEstimator
from sklearn.calibration import CalibratedClassifierCV
from sklearn.gaussian_process import GaussianProcessClassifier
from sklearn.gaussian_process.kernels import RBF, ConstantKernel
from sklearn.model_selection import GridSearchCV
from sklearn.svm import SVC

from ipbench.perception.gpc import GPCConfig, MulticlassLaplaceGPC
from ipbench.references import (
    Method,
    ReferenceLoadError,
    check_methods,
    is_reference,
    load_reference,
)

__all__ = [
    "CLASSIFIERS",
    "SVM_C_GRID",
    "Classifier",
    "ClassifierError",
    "GPClassifier",
    "SVMClassifier",
    "SklearnGPClassifier",
    "check_classifier_name",
    "load_classifier",
    "make_classifier",
]

CLASSIFIERS: tuple[str, ...] = ("gp", "gp_mode", "svm", "sklearn_gp")
SVM_C_GRID: tuple[float, ...] = (1.0, 10.0, 100.0)


class ClassifierError(ValueError):
    """Unknown classifier name or a classifier used before ``fit``."""


@runtime_checkable
class Classifier(Protocol):
    """A probabilistic classifier over ``n_classes`` classes.

    ``X`` is ``(n, d)`` float, ``y`` ``(n,)`` int in ``0 .. n_classes - 1``.
    """

    name: str

    def fit(self, X: np.ndarray, y: np.ndarray) -> Classifier: ...

    def predict_proba(self, X: np.ndarray) -> np.ndarray: ...

    def predict(self, X: np.ndarray) -> np.ndarray: ...


def _median_distance(X: np.ndarray, max_points: int = 1000) -> float:
    X = X[:max_points]
    sq = np.einsum("ij,ij->i", X, X)
    d2 = np.maximum(sq[:, None] + sq[None, :] - 2.0 * X @ X.T, 0.0)
    med = float(np.sqrt(np.median(d2[np.triu_indices(X.shape[0], 1)]))) if len(X) > 1 else 0.0
    return med if med > 0 else 1.0


class _SklearnBased:
    """Shared ``predict_proba`` / ``predict`` for wrappers around a scikit-learn estimator."""

    name = ""

    def __init__(self, n_classes: int, seed: int = 0) -> None:
        self.n_classes = int(n_classes)
        self.seed = seed
        self.estimator_: BaseEstimator | None = None

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """``(m, n_classes)`` class probabilities; rows sum to one."""
        if self.estimator_ is None:
            raise ClassifierError(f"classifier {self.name!r} is not fitted: call fit(X, y) first")
        p = self.estimator_.predict_proba(np.asarray(X, dtype=float))
        out = np.zeros((p.shape[0], self.n_classes))
        out[:, np.asarray(self.estimator_.classes_, dtype=np.int64)] = p
        return out / out.sum(axis=1, keepdims=True)

    def predict(self, X: np.ndarray) -> np.ndarray:
        """``(m,)`` most probable classes."""
        return np.argmax(self.predict_proba(X), axis=1)


_PLATT_FOLDS = 5


class SVMClassifier(_SklearnBased):
    """RBF SVM, ``C`` from ``SVM_C_GRID`` (3-fold CV accuracy), Platt-calibrated (5-fold)."""

    name = "svm"

    def fit(self, X: np.ndarray, y: np.ndarray) -> SVMClassifier:
        X, y = np.asarray(X, dtype=float), np.asarray(y, dtype=np.int64)
        counts = np.bincount(y, minlength=self.n_classes)
        if counts[counts > 0].min() < _PLATT_FOLDS:  # a missing class is allowed
            raise ClassifierError(
                f"the SVM's Platt calibration ({_PLATT_FOLDS}-fold) needs at least "
                f"{_PLATT_FOLDS} training views of each class it sees; got {counts.tolist()}"
            )
        search = GridSearchCV(SVC(kernel="rbf", gamma="scale"), {"C": list(SVM_C_GRID)}, cv=3)
        self.C_ = float(search.fit(X, y).best_params_["C"])
        svc = SVC(kernel="rbf", C=self.C_, gamma="scale", random_state=self.seed)
        self.estimator_ = CalibratedClassifierCV(svc, method="sigmoid", cv=_PLATT_FOLDS)
        self.estimator_.fit(X, y)
        return self


class SklearnGPClassifier(_SklearnBased):
    """scikit-learn ``GaussianProcessClassifier`` (one-vs-rest) with a tunable kernel."""

    name = "sklearn_gp"

    def fit(self, X: np.ndarray, y: np.ndarray) -> SklearnGPClassifier:
        X, y = np.asarray(X, dtype=float), np.asarray(y, dtype=np.int64)
        kernel = ConstantKernel(1.0, (1e-2, 1e4)) * RBF(_median_distance(X), (1e-3, 1e3))
        gpc = GaussianProcessClassifier(kernel=kernel, random_state=self.seed)
        self.estimator_ = gpc.fit(X, y)
        return self


class GPClassifier:
    """Our multi-class Laplace GP behind the :class:`Classifier` interface.

    Parameters
    ----------
    n_classes : int
    seed : int
        Seed of the Monte-Carlo predictions and of the hyper-parameter start subset.
    config : GPCConfig or None
        Full settings; None: defaults with ``seed``.
    """

    def __init__(self, n_classes: int, seed: int = 0, config: GPCConfig | None = None) -> None:
        self.name = "gp_mode" if config is not None and config.predictive == "mode" else "gp"
        self.n_classes = int(n_classes)
        self.seed = seed
        self.config = GPCConfig(seed=seed) if config is None else config
        self.model_: MulticlassLaplaceGPC | None = None

    def fit(self, X: np.ndarray, y: np.ndarray) -> GPClassifier:
        self.model_ = MulticlassLaplaceGPC(self.config).fit(X, y, self.n_classes)
        return self

    def _model(self) -> MulticlassLaplaceGPC:
        if self.model_ is None:
            raise ClassifierError(f"classifier {self.name!r} is not fitted: call fit(X, y) first")
        return self.model_

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """``(m, n_classes)`` class probabilities (reproducible); rows sum to one."""
        return self._model().predict_proba(X)

    def predict(self, X: np.ndarray) -> np.ndarray:
        """``(m,)`` most probable classes."""
        return self._model().predict(X)

    def get_state(self) -> dict[str, np.ndarray]:
        """Arrays for ``np.savez``; see :meth:`MulticlassLaplaceGPC.get_state`."""
        return self._model().get_state()

    @classmethod
    def from_state(cls, state: dict[str, np.ndarray]) -> GPClassifier:
        """Rebuild a fitted classifier from :meth:`get_state` output."""
        model = MulticlassLaplaceGPC.from_state(state)
        return cls.from_model(model)

    @classmethod
    def from_model(cls, model: MulticlassLaplaceGPC) -> GPClassifier:
        """Wrap an already fitted :class:`MulticlassLaplaceGPC`."""
        clf = cls(model.n_classes_, model.config.seed, model.config)
        clf.model_ = model
        return clf


_METHODS: tuple[Method, ...] = (
    Method("fit", 2, "fit(X, y)"),
    Method("predict_proba", 1, "predict_proba(X)"),
)
_NEEDS = (
    "a classifier is built as MyClassifier(n_classes, seed) and needs fit(X, y) and "
    "predict_proba(X) returning (m, n_classes) probabilities"
)


def load_classifier(ref: str):
    """The class (or factory) a ``module:attribute`` reference names, checked up front: the
    module imports, the attribute takes ``(n_classes, seed)`` and has ``fit(X, y)`` and
    ``predict_proba(X)``. Raises :class:`ClassifierError` saying what is missing."""
    try:
        return load_reference(
            ref, "classifier", ("n_classes", "seed"), _METHODS, _NEEDS, "mypkg.models:MyClassifier"
        )
    except ReferenceLoadError as err:
        raise ClassifierError(str(err)) from err


def check_classifier_name(name: str, valid: tuple[str, ...] = CLASSIFIERS) -> str:
    """``name`` if it is one of ``valid`` or a usable ``module:attribute`` reference
    (:func:`load_classifier`), else :class:`ClassifierError` listing the valid names."""
    if is_reference(name):
        load_classifier(name)
    elif name not in valid:
        raise ClassifierError(
            f"unknown classifier {name!r}; valid: {', '.join(valid)}, or a classifier of your "
            "own as module:attribute (e.g. mypkg.models:MyClassifier, see docs/custom.md)"
        )
    return name


class _Checked:
    """A classifier of the user's own, its probabilities checked for their shape."""

    def __init__(self, name: str, classifier, n_classes: int) -> None:
        self.name, self.classifier, self.n_classes = name, classifier, n_classes

    def fit(self, X: np.ndarray, y: np.ndarray) -> _Checked:
        self.classifier.fit(X, y)
        return self

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """``(m, n_classes)`` class probabilities of the wrapped classifier, checked."""
        m = len(X)
        p = np.asarray(self.classifier.predict_proba(X), dtype=float)
        if p.shape != (m, self.n_classes):
            raise ClassifierError(
                f"{self.name}.predict_proba returned shape {p.shape} for {m} rows; it must "
                f"return ({m}, {self.n_classes}): one column per class 0..{self.n_classes - 1}"
            )
        if m and (not np.isfinite(p).all() or (p < 0).any() or np.abs(p.sum(1) - 1).max() > 1e-3):
            raise ClassifierError(
                f"{self.name}.predict_proba returned rows that are not probabilities (finite, "
                "non-negative, summing to one)"
            )
        return p

    def predict(self, X: np.ndarray) -> np.ndarray:
        """``(m,)`` most probable classes."""
        return np.argmax(self.predict_proba(X), axis=1)


def make_classifier(name: str, n_classes: int, seed: int = 0) -> Classifier:
    """Build an unfitted classifier by name (one of :data:`CLASSIFIERS`, or a ``module:attribute``
    reference: :func:`load_classifier`, built as ``attribute(n_classes, seed)``).

    Raises
    ------
    ClassifierError
        For an unknown name (the message lists the valid ones) or ``n_classes < 2``.
    """
    if int(n_classes) < 2:
        raise ClassifierError(f"n_classes must be >= 2, got {n_classes}")
    if name == "gp":
        return GPClassifier(n_classes, seed)
    if name == "gp_mode":
        return GPClassifier(n_classes, seed, GPCConfig(seed=seed, predictive="mode"))
    if name == "svm":
        return SVMClassifier(n_classes, seed)
    if name == "sklearn_gp":
        return SklearnGPClassifier(n_classes, seed)
    if is_reference(name):
        built = load_classifier(name)(int(n_classes), seed)
        try:
            check_methods(built, name, "classifier", _METHODS, _NEEDS)
        except ReferenceLoadError as err:
            raise ClassifierError(str(err)) from err
        return _Checked(name, built, int(n_classes))
    raise ClassifierError(f"unknown classifier {name!r}; valid names: {', '.join(CLASSIFIERS)}")
