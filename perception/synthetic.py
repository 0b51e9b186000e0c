"""Seeded synthetic bag-of-words data shaped like max-pooled FPFH word histograms.

A class (object category) is a set of ``n_instances`` objects; object ``k`` of class ``c``
has a word distribution over a vocabulary of ``vocab_size`` words, a shared background
distribution tilted by a class factor and an object factor,
``q_ck ~ b * exp(separation * z_c + instance_spread * z_ck)`` with ``z ~ N(0, I)``.
A sample (one view of a random object of the class) is a random number ``N`` of local
descriptors, ``N = min_descriptors + Poisson(lambda)`` with ``lambda`` Gamma distributed
(views differ in how much of the object they show); each descriptor is, with probability
``distractor_rate``, a uniformly random distractor word (clutter, bad segmentation) and
otherwise a word drawn from ``q_ck``. Max pooling gives a binary presence vector, which is
L2-normalised.

``separation`` sets the difficulty; the default gives about 86 % test accuracy for a
well-tuned RBF classifier with 1,500 training samples and 5 classes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SyntheticBoW", "SyntheticConfig", "make_split"]


@dataclass(frozen=True)
class SyntheticConfig:
    """Generator parameters.

    Attributes
    ----------
    n_classes : int
        Number of classes ``C``.
    n_instances : int
        Objects per class.
    vocab_size : int
        Vocabulary (feature) dimension.
    mean_descriptors : float
        Mean number of local descriptors per sample.
    min_descriptors : int
        Minimum number of descriptors per sample.
    distractor_rate : float
        Probability that a descriptor is a uniformly random word, in ``[0, 1]``.
    count_shape : float
        Gamma shape of the descriptor-count rate (smaller: more varied views).
    separation : float
        Standard deviation of the class log-tilt of the word distribution.
    instance_spread : float
        Standard deviation of the per-object log-tilt.
    background_concentration : float
        Dirichlet concentration of the shared background distribution.
    """

    n_classes: int = 5
    n_instances: int = 3
    vocab_size: int = 256
    mean_descriptors: float = 30.0
    min_descriptors: int = 5
    distractor_rate: float = 0.3
    count_shape: float = 2.0
    separation: float = 0.8
    instance_spread: float = 0.5
    background_concentration: float = 1.0

    def __post_init__(self) -> None:
        if self.n_classes < 2 or self.vocab_size < 2:
            raise ValueError(
                f"need n_classes >= 2 and vocab_size >= 2, got {self.n_classes}, {self.vocab_size}"
            )
        if not 0.0 <= self.distractor_rate <= 1.0:
            raise ValueError(f"distractor_rate must be in [0, 1], got {self.distractor_rate}")
        if self.mean_descriptors < self.min_descriptors or self.min_descriptors < 1:
            raise ValueError("need 1 <= min_descriptors <= mean_descriptors")
        if min(self.separation, self.instance_spread) < 0 or self.n_instances < 1:
            raise ValueError("need separation >= 0, instance_spread >= 0, n_instances >= 1")
        if self.background_concentration <= 0 or self.count_shape <= 0:
            raise ValueError("background_concentration and count_shape must be > 0")


class SyntheticBoW:
    """A fixed set of class word distributions (the "world") and a sampler.

    Parameters
    ----------
    config : SyntheticConfig
    seed : int
        Seed of the class word distributions; samples use their own generator.
    """

    def __init__(self, config: SyntheticConfig = SyntheticConfig(), seed: int = 0) -> None:
        self.config = config
        rng = np.random.default_rng(seed)
        v = config.vocab_size
        background = rng.dirichlet(np.full(v, config.background_concentration))
        c, k = config.n_classes, config.n_instances
        tilt = config.separation * rng.standard_normal((c, 1, v))
        tilt = tilt + config.instance_spread * rng.standard_normal((c, k, v))
        q = background * np.exp(tilt)
        #: (C, n_instances, V) word probabilities of one descriptor (last axis sums to one).
        self.word_probs: np.ndarray = q / q.sum(axis=2, keepdims=True)

    def sample(
        self, n: int, rng: np.random.Generator, labels: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Draw ``n`` samples.

        Parameters
        ----------
        n : int
            Number of samples.
        rng : numpy Generator
        labels : (n,) int array or None
            Classes to draw; None: balanced (``i mod C``) then shuffled.

        Returns
        -------
        X : (n, vocab_size) float array, unit L2 norm rows.
        y : (n,) int64 array in ``0 .. C - 1``.
        """
        cfg = self.config
        if labels is None:
            labels = rng.permutation(np.arange(n) % cfg.n_classes)
        y = np.asarray(labels, dtype=np.int64)
        rate = (cfg.mean_descriptors - cfg.min_descriptors) / cfg.count_shape
        counts = cfg.min_descriptors + rng.poisson(rng.gamma(cfg.count_shape, rate, n))
        objects = rng.integers(0, cfg.n_instances, n)
        X = np.zeros((n, cfg.vocab_size))
        cdf = np.cumsum(self.word_probs, axis=2)
        cdf[:, :, -1] = 1.0
        for i in range(n):
            k = int(counts[i])
            distract = rng.random(k) < cfg.distractor_rate
            words = np.searchsorted(cdf[y[i], objects[i]], rng.random(k), side="right")
            words[distract] = rng.integers(0, cfg.vocab_size, int(distract.sum()))
            X[i, words] = 1.0  # max pooling of one-hot word assignments
        X /= np.linalg.norm(X, axis=1, keepdims=True)
        return X, y


def make_split(
    n_train: int,
    n_test: int,
    config: SyntheticConfig = SyntheticConfig(),
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Train and test sets from one world: ``(X_train, y_train, X_test, y_test)``.

    Shapes ``(n_train, V)``, ``(n_train,)``, ``(n_test, V)``, ``(n_test,)``; deterministic in
    ``seed``.
    """
    gen = SyntheticBoW(config, seed)
    rng = np.random.default_rng([seed, 1])
    X_tr, y_tr = gen.sample(n_train, rng)
    X_te, y_te = gen.sample(n_test, rng)
    return X_tr, y_tr, X_te, y_te
