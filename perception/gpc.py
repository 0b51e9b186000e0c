"""Multi-class Gaussian-process classification with the Laplace approximation.

Rasmussen & Williams, *Gaussian Processes for Machine Learning* (GPML), ch. 3: softmax
likelihood, ``C`` latent functions with one shared isotropic squared-exponential kernel
``k(x, x') = sigma^2 exp(-|x - x'|^2 / (2 ell^2))``; mode finding by Algorithm 3.3,
predictions by Algorithm 3.4 with Monte-Carlo class probabilities (both in
:mod:`._gpc_laplace`), and ``theta = (log sigma, log ell)`` fitted by L-BFGS-B on the
approximate log marginal likelihood ``log q`` with its analytic gradient, including the
implicit term through the mode (:mod:`._gpc_grad`). The determinant in ``log q`` is the
exact ``log|I + K W|``; Algorithm 3.3 as printed omits a term (see :mod:`._gpc_laplace`).

A test point far from all training data gets ``mu* = 0`` and ``Sigma* = sigma^2 I``, so its
class probabilities are close to uniform: the prior.

Two predictive distributions (``GPCConfig.predictive``): ``"mc"`` is Algorithm 3.4, the
expectation of the softmax under the Laplace posterior ``N(mu*, Sigma*)``; ``"mode"`` is the
softmax of the predictive mean ``mu*`` (the plug-in predictive, ``Sigma*`` ignored). On nearly
separable data the mode sits where the likelihood saturates, so ``W`` is small and the
Laplace ``Sigma*`` stays close to the prior's: the Gaussian puts much mass on the wrong side of
the decision boundary and ``"mc"`` is systematically under-confident. That is a known
property of the Laplace approximation for GP classification (Kuss & Rasmussen, JMLR 6, 2005;
Nickisch & Rasmussen, JMLR 9, 2008), not of the model; both predictives share the fit.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from ipbench.perception._gpc_grad import LaplaceObjective
from ipbench.perception._gpc_laplace import (
    factorize,
    mc_softmax,
    predictive_latent,
    predictive_mean,
    se_kernel,
    softmax,
    sq_distances,
)
from ipbench.perception._gpc_posterior import factor_file, read_factor, state_digest, write_factor

__all__ = ["GPCConfig", "GPCError", "MulticlassLaplaceGPC", "PREDICTIVES"]

PREDICTIVES: tuple[str, ...] = ("mc", "mode")
"""Valid ``GPCConfig.predictive`` values (see the module docstring)."""

_CHUNK = 512  # test points per block in predict_latent (memory ~ C * n * 512 floats)
# L-BFGS-B stops when an iteration changes log q by less than _FTOL * |log q| (0.01 nat at
# log q = -1000; differences that small are meaningless for model choice) or when every
# |d log q / d log theta| / n is below _GTOL.
_FTOL, _GTOL = 1e-5, 1e-4


class GPCError(ValueError):
    """Bad input to :class:`MulticlassLaplaceGPC` (shapes, labels, use before ``fit``)."""


@dataclass(frozen=True)
class GPCConfig:
    """Settings of :class:`MulticlassLaplaceGPC`.

    Attributes
    ----------
    amplitude : float or None
        Initial ``sigma`` (latent units). None: 2.0 (prior latent values of about +-4,
        i.e. softmax outputs anywhere from uniform to ~0.99 confident).
    length_scale : float or None
        Initial ``ell`` (input units). None: median pairwise training distance.
    optimize : bool
        Fit ``theta`` by L-BFGS-B; otherwise keep the initial values.
    max_iter : int
        L-BFGS-B iterations (per stage, see ``init_subset``).
    newton_tol : float
        Newton stops when ``max |f_new - f_old|`` falls below this (latent units).
    newton_max_iter : int
        Newton iterations per mode search.
    n_samples : int
        Monte-Carlo samples of the latent Gaussian per test point.
    seed : int
        Seed of the default generator of ``predict_proba`` and of the ``init_subset`` draw.
    bounds : ((float, float), (float, float))
        ``(low, high)`` of ``log sigma`` and of ``log ell`` for L-BFGS-B.
    predictive : str
        ``"mc"``: Monte-Carlo class probabilities (Algorithm 3.4, ``n_samples`` draws);
        ``"mode"``: softmax of the latent predictive mean (see the module docstring).
    init_subset : int or None
        With more than twice this many training points, ``theta`` is first fitted on a
        stratified random subset of this size (cheap), then refined on all data, which then
        needs only a few expensive L-BFGS steps. None: fit on all data from the start.
    """

    amplitude: float | None = None
    length_scale: float | None = None
    optimize: bool = True
    max_iter: int = 100
    newton_tol: float = 1e-6
    newton_max_iter: int = 100
    n_samples: int = 2000
    seed: int = 0
    bounds: tuple[tuple[float, float], tuple[float, float]] = ((-3.0, 5.0), (-7.0, 7.0))
    init_subset: int | None = 400
    predictive: str = "mc"

    def __post_init__(self) -> None:
        if self.predictive not in PREDICTIVES:
            raise GPCError(
                f"predictive must be one of {', '.join(PREDICTIVES)}, got {self.predictive!r}"
            )
        for name in ("amplitude", "length_scale"):
            v = getattr(self, name)
            if v is not None and not (np.isfinite(v) and v > 0):
                raise GPCError(f"{name} must be a positive finite number or None, got {v!r}")
        for name in ("max_iter", "newton_max_iter", "n_samples"):
            if int(getattr(self, name)) < 1:
                raise GPCError(f"{name} must be >= 1, got {getattr(self, name)!r}")
        if self.init_subset is not None and int(self.init_subset) < 10:
            raise GPCError(f"init_subset must be >= 10 or None, got {self.init_subset!r}")
        if not self.newton_tol > 0:
            raise GPCError(f"newton_tol must be > 0, got {self.newton_tol!r}")
        b = np.asarray(self.bounds, dtype=float)
        if b.shape != (2, 2) or not np.all(b[:, 0] < b[:, 1]):
            raise GPCError(f"bounds must be ((lo, hi), (lo, hi)) with lo < hi, got {self.bounds!r}")


def _as_inputs(X: np.ndarray, what: str, n_features: int | None = None) -> np.ndarray:
    X = np.asarray(X, dtype=float)
    if X.ndim != 2 or X.shape[0] == 0:
        raise GPCError(f"{what} must be a non-empty 2-D array (n, d), got shape {X.shape}")
    if not np.all(np.isfinite(X)):
        raise GPCError(f"{what} contains NaN or inf; all features must be finite")
    if n_features is not None and X.shape[1] != n_features:
        raise GPCError(f"{what} has {X.shape[1]} features; the model was fitted with {n_features}")
    return X


def _as_labels(y: np.ndarray, n: int, n_classes: int | None) -> tuple[np.ndarray, int]:
    y = np.asarray(y)
    if y.ndim != 1 or y.shape[0] != n:
        raise GPCError(f"y must have shape ({n},) to match X, got {y.shape}")
    if not np.issubdtype(y.dtype, np.integer) and not (
        np.issubdtype(y.dtype, np.floating) and np.all(y == np.round(y))
    ):
        raise GPCError(f"y must hold integer class labels, got dtype {y.dtype}")
    y = y.astype(np.int64)
    n_cls = max(int(y.max()) + 1, 2) if n_classes is None else int(n_classes)
    if n_cls < 2:
        raise GPCError(f"n_classes must be >= 2, got {n_classes}")
    if y.min() < 0 or y.max() >= n_cls:
        raise GPCError(
            f"labels must lie in 0..{n_cls - 1} (n_classes={n_cls}), "
            f"got values in {int(y.min())}..{int(y.max())}"
        )
    return y, n_cls


class MulticlassLaplaceGPC:
    """Multi-class Laplace GP classifier (GPML Algorithms 3.3 and 3.4), shared SE kernel.

    Fitted attributes: ``theta_`` (``(sigma, ell)``), ``log_theta_`` and
    ``initial_log_theta_`` (``(2,)`` arrays of ``(log sigma, log ell)``),
    ``log_marginal_likelihood_value_`` (``log q`` at ``theta_``), ``n_classes_``,
    ``n_lbfgs_evals_`` (``log q`` + gradient evaluations, both stages).
    """

    def __init__(self, config: GPCConfig = GPCConfig()) -> None:
        self.config = config
        self._X: np.ndarray | None = None
        self._posterior_file: Path | None = None

    def _require_fit(self) -> None:
        if self._X is None:
            raise GPCError("this MulticlassLaplaceGPC is not fitted yet: call fit(X, y) first")

    def _set_data(self, X: np.ndarray, y: np.ndarray, n_classes: int) -> None:
        self._Xt, self._y, self.n_classes_ = X, y, n_classes
        self._Y = np.eye(n_classes)[y]
        self._sqd = sq_distances(X, X)
        self._objective = LaplaceObjective(
            self._sqd, self._Y, self.config.newton_tol, self.config.newton_max_iter
        )

    def fit(
        self, X: np.ndarray, y: np.ndarray, n_classes: int | None = None
    ) -> MulticlassLaplaceGPC:
        """Fit ``theta`` (if ``config.optimize``) and the Laplace posterior.

        Parameters
        ----------
        X : (n, d) array of training inputs.
        y : (n,) integer labels in ``0 .. n_classes - 1``.
        n_classes : int or None
            Number of classes ``C >= 2``; None: ``max(y) + 1`` (at least 2).
        """
        self._X = None
        X = _as_inputs(X, "training X")
        y, n_cls = _as_labels(y, X.shape[0], n_classes)
        self._set_data(X, y, n_cls)
        log_theta = self.initial_log_theta_ = self._initial_log_theta()
        self.n_lbfgs_evals_ = 0
        sub = self._init_subset()
        if self.config.optimize and sub is not None:
            cfg = self.config
            obj = LaplaceObjective(
                self._sqd[np.ix_(sub, sub)], self._Y[sub], cfg.newton_tol, cfg.newton_max_iter
            )
            log_theta = self._lbfgs(obj, log_theta)
            # Warm start: f0 = K[:, sub] a_sub is the subset posterior mean at every point.
            self._objective.a[sub] = obj.a
        if self.config.optimize:
            log_theta = self._lbfgs(self._objective, log_theta)
        _, mode = self._objective.mode(log_theta)
        self.log_marginal_likelihood_value_ = mode.log_q
        self._set_posterior(log_theta, mode.a)
        return self

    def _initial_log_theta(self) -> np.ndarray:
        cfg = self.config
        sigma = 2.0 if cfg.amplitude is None else cfg.amplitude
        ell = cfg.length_scale
        if ell is None:
            iu = np.triu_indices(self._sqd.shape[0], 1)
            med = float(np.sqrt(np.median(self._sqd[iu]))) if iu[0].size else 0.0
            ell = med if med > 0 else 1.0
        b = np.asarray(cfg.bounds)
        return np.clip(np.log([sigma, ell]), b[:, 0], b[:, 1])

    def _init_subset(self) -> np.ndarray | None:
        """Stratified random subset for the coarse first fit of ``theta`` (None: not used)."""
        m, n = self.config.init_subset, self._y.shape[0]
        if m is None or n <= 2 * m:
            return None
        rng = np.random.default_rng(self.config.seed)
        picks = []
        for c in range(self.n_classes_):
            members = np.flatnonzero(self._y == c)
            k = min(members.size, round(m * members.size / n))
            picks.append(rng.choice(members, size=k, replace=False))
        return np.sort(np.concatenate(picks))

    def _lbfgs(self, obj: LaplaceObjective, log_theta: np.ndarray) -> np.ndarray:
        n = obj.Y.shape[0]

        def fun(lt: np.ndarray) -> tuple[float, np.ndarray]:
            lq, g = obj(lt)
            return -lq / n, -np.asarray(g) / n

        res = minimize(
            fun,
            log_theta,
            jac=True,
            method="L-BFGS-B",
            bounds=self.config.bounds,
            options={"maxiter": self.config.max_iter, "ftol": _FTOL, "gtol": _GTOL},
        )
        self.n_lbfgs_evals_ += obj.n_evals
        self.optimizer_result_ = res
        return np.asarray(res.x, dtype=float)

    def log_marginal_likelihood(
        self, log_theta: np.ndarray | None = None, return_grad: bool = False
    ) -> float | tuple[float, np.ndarray]:
        """``log q(y|X, theta)`` (GPML eq. 3.44, exact determinant) on the training data.

        Parameters
        ----------
        log_theta : (2,) array or None
            ``(log sigma, log ell)``; None: the fitted values. The mode is re-found.
        return_grad : bool
            Also return the gradient with respect to ``log_theta``, shape ``(2,)``.
        """
        self._require_fit()
        lt = self.log_theta_ if log_theta is None else np.asarray(log_theta, dtype=float)
        if lt.shape != (2,) or not np.all(np.isfinite(lt)):
            raise GPCError(f"log_theta must be 2 finite numbers (log sigma, log ell), got {lt!r}")
        lq, g = self._objective(lt, grad=return_grad)
        return (lq, g) if return_grad else lq

    def _set_posterior(
        self, log_theta: np.ndarray, a: np.ndarray, posterior: str | Path | None = None
    ) -> None:
        """Predictive quantities at the mode ``f = K a`` (shared by ``fit`` and ``from_state``);
        ``posterior``: a file prefix of :meth:`map_posterior`, read instead of computing the
        factor when this model's file is there (else computed, then written there)."""
        self.log_theta_ = np.asarray(log_theta, dtype=float)
        self.theta_ = (float(np.exp(self.log_theta_[0])), float(np.exp(self.log_theta_[1])))
        K = se_kernel(self._sqd, self.log_theta_)
        self._a = a
        self._Pi = softmax(K @ a)
        self._posterior_file = None
        self._X = self._Xt
        if posterior is not None:
            path = factor_file(posterior, self._digest())
            fac = read_factor(path, *self._Y.shape)
            if fac is not None:
                self._fac, self._posterior_file = fac, path
                return
        self._fac = factorize(K, self._Pi)
        if posterior is not None:
            try:
                self.map_posterior(posterior)
            except OSError:  # a read-only or full folder: predict from memory instead
                pass

    def _digest(self) -> str:
        return state_digest(self._Xt, self._y, np.array(self.n_classes_), self._a, self.log_theta_)

    def map_posterior(self, prefix: str | Path) -> Path:
        """Keep the predictive factor (``C + 1`` matrices of n x n floats) in a file and
        predict from it mapped read-only; returns the file, ``PREFIX-DIGEST.npy``.

        ``DIGEST`` identifies this model's state, so a file already there holds exactly this
        model's factor and is reused; otherwise it is written (atomically). Processes that
        map one file share its pages, and a pickle of this model carries the path instead of
        the matrices (unpickled where the file is missing, the factor is computed again).
        Predictions are bit-identical to those of the unmapped model.
        """
        self._require_fit()
        path = factor_file(prefix, self._digest())
        n, n_cls = self._Y.shape
        fac = read_factor(path, n, n_cls)
        if fac is None:
            write_factor(path, self._fac)
            fac = read_factor(path, n, n_cls)
            if fac is None:
                raise GPCError(f"the posterior file {path} cannot be read back after writing")
        self._fac, self._posterior_file = fac, path
        return path

    @property
    def posterior_file(self) -> Path | None:
        """The file the factor is mapped from (:meth:`map_posterior`), or None."""
        return self._posterior_file

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        if state.get("_posterior_file") is not None:  # the file carries the large arrays
            for key in ("_fac", "_sqd", "_objective"):
                state.pop(key, None)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.__dict__.setdefault("_posterior_file", None)
        if "_fac" in state or self._X is None:
            return
        self._set_data(self._Xt, self._y, self.n_classes_)
        self._objective.a = self._a
        n, n_cls = self._Y.shape
        fac = read_factor(self._posterior_file, n, n_cls)
        if fac is None:  # the file is not here (another machine): compute the factor again
            self._posterior_file = None
            fac = factorize(se_kernel(self._sqd, self.log_theta_), self._Pi)
        self._fac = fac

    def predict_latent(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Latent predictive mean ``(m, C)`` and covariance ``(m, C, C)`` (Algorithm 3.4).

        ``mu*_c = k*^T (y_c - pi_c)``, ``Sigma* = sigma^2 I - Q*^T (K + W^-1)^-1 Q*``; latent
        (logit) units.
        """
        self._require_fit()
        X = _as_inputs(X, "X", self._X.shape[1])
        kss = float(np.exp(2.0 * self.log_theta_[0]))
        parts = [
            predictive_latent(
                se_kernel(sq_distances(self._X, X[s : s + _CHUNK]), self.log_theta_),
                kss,
                self._Y - self._Pi,
                self._fac,
            )
            for s in range(0, X.shape[0], _CHUNK)
        ]
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])

    def _predict_mean(self, X: np.ndarray) -> np.ndarray:
        """The mean of :meth:`predict_latent` alone (bit-identical: the same blocks, the same
        products), ``O(n m C)`` instead of the covariance's ``O(n^2 m C)``."""
        self._require_fit()
        X = _as_inputs(X, "X", self._X.shape[1])
        return np.concatenate(
            [
                predictive_mean(
                    se_kernel(sq_distances(self._X, X[s : s + _CHUNK]), self.log_theta_),
                    self._Y - self._Pi,
                )
                for s in range(0, X.shape[0], _CHUNK)
            ]
        )

    def predict_proba(self, X: np.ndarray, rng: np.random.Generator | None = None) -> np.ndarray:
        """Class probabilities ``(m, C)``: by Monte Carlo through the softmax (Algorithm 3.4)
        or, with ``config.predictive == "mode"``, the softmax of the latent mean.

        Parameters
        ----------
        X : (m, d) array.
        rng : numpy Generator or None
            Source of the ``config.n_samples`` latent samples per point; None: a fresh
            ``np.random.default_rng(config.seed)``, so repeated calls give equal results.
        """
        if self.config.predictive == "mode":  # Sigma* unused: only the mean is computed
            return softmax(self._predict_mean(X))
        mean, cov = self.predict_latent(X)
        rng = np.random.default_rng(self.config.seed) if rng is None else rng
        return mc_softmax(mean, cov, self.config.n_samples, rng)

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Most probable class under :meth:`predict_proba`, shape ``(m,)``."""
        return np.argmax(self.predict_proba(X), axis=1)

    def with_predictive(self, predictive: str) -> MulticlassLaplaceGPC:
        """The same fitted model (no refit) predicting with ``predictive`` (see PREDICTIVES):
        what :meth:`from_state` of this model's state with that predictive gives, sharing this
        model's arrays and predictive factor (mapped file included) instead of factorising
        again (``C`` Choleskys and inverses of n x n)."""
        self._require_fit()
        model = object.__new__(type(self))  # a shallow copy (not through __getstate__)
        model.__dict__.update(self.__dict__)
        model.config = replace(self.config, predictive=predictive)  # validates
        model._objective = LaplaceObjective(
            self._sqd, self._Y, self.config.newton_tol, self.config.newton_max_iter
        )
        model._objective.a = self._a.copy()
        model.n_lbfgs_evals_ = 0
        model.__dict__.pop("optimizer_result_", None)
        return model

    def get_state(self) -> dict[str, np.ndarray]:
        """Arrays that fully define the fitted model (e.g. for ``np.savez``)."""
        self._require_fit()
        return {
            "X": self._X.copy(),
            "y": self._y.copy(),
            "n_classes": np.array(self.n_classes_),
            "log_theta": self.log_theta_.copy(),
            "initial_log_theta": self.initial_log_theta_.copy(),
            "a": self._a.copy(),
            "log_q": np.array(self.log_marginal_likelihood_value_),
            "config_json": np.array(json.dumps(asdict(self.config))),
        }

    @classmethod
    def from_state(
        cls, state: dict[str, np.ndarray], posterior: str | Path | None = None
    ) -> MulticlassLaplaceGPC:
        """Rebuild a fitted model from :meth:`get_state` (or ``np.load`` of a saved one);
        ``posterior``: a file prefix for :meth:`map_posterior` (the factor is read from
        there instead of computed when that file exists, else computed and written)."""
        missing = {"X", "y", "n_classes", "log_theta", "a", "config_json"} - set(state)
        if missing:
            raise GPCError(f"state is missing keys {sorted(missing)}; pass get_state() output")
        cfg = json.loads(str(np.asarray(state["config_json"])))
        cfg["bounds"] = tuple(tuple(b) for b in cfg["bounds"])
        model = cls(GPCConfig(**cfg))
        X = _as_inputs(state["X"], "state X")
        y, n_cls = _as_labels(state["y"], X.shape[0], int(state["n_classes"]))
        model._set_data(X, y, n_cls)
        a = np.asarray(state["a"], dtype=float)
        if a.shape != (X.shape[0], n_cls):
            raise GPCError(f"state 'a' must have shape {(X.shape[0], n_cls)}, got {a.shape}")
        model._objective.a = a
        lt = np.asarray(state["log_theta"], dtype=float)
        model.initial_log_theta_ = np.asarray(state.get("initial_log_theta", lt), dtype=float)
        model.log_marginal_likelihood_value_ = float(state.get("log_q", np.nan))
        model.n_lbfgs_evals_ = 0
        model._set_posterior(lt, a, posterior)
        return model
