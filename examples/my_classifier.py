"""A classifier of your own: logistic regression on the bag-of-words vectors the GP gets.

Compare it with the GP (from the repository's root folder)::

    ipbench eval perception --classifiers gp,examples.my_classifier:LogisticClassifier

The evaluation builds it as ``LogisticClassifier(n_classes, seed)``, calls ``fit(X, y)`` on
the known instances' views and ``predict_proba(X)`` on every test set (the protocol:
``docs/custom.md``). ``X`` is ``(n, d)`` float: one bag-of-words vector a view (``d`` = the
codebook size, 256; word presence, L2-normalised); ``y`` is ``(n,)`` int in
``0 .. n_classes - 1``.
"""

from __future__ import annotations

import numpy as np
from sklearn.linear_model import LogisticRegression

__all__ = ["LogisticClassifier"]


class LogisticClassifier:
    """Multinomial logistic regression (scikit-learn), L2-regularised with strength ``1 / C``."""

    def __init__(self, n_classes: int, seed: int = 0, C: float = 10.0) -> None:
        self.n_classes = n_classes
        self.model = LogisticRegression(C=C, max_iter=2000, random_state=seed)

    def fit(self, X: np.ndarray, y: np.ndarray) -> LogisticClassifier:
        self.model.fit(X, y)
        return self

    def predict_proba(self, X: np.ndarray) -> np.ndarray:
        """``(m, n_classes)`` probabilities; a class missing from the training labels gets 0."""
        out = np.zeros((len(X), self.n_classes))
        out[:, self.model.classes_] = self.model.predict_proba(X)
        return out
