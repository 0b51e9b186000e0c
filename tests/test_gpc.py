"""Multi-class Laplace GP classifier: exactness against brute force, and behaviour."""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from ipbench.perception._gpc_grad import kernel_derivatives, lml_gradient
from ipbench.perception._gpc_laplace import factorize, se_kernel, softmax, sq_distances
from ipbench.perception.gpc import GPCConfig, GPCError, MulticlassLaplaceGPC

EXACT = GPCConfig(optimize=False, newton_tol=1e-11)


@pytest.fixture(autouse=True, scope="module")
def _one_blas_thread():
    """One BLAS thread: on a shared machine OpenBLAS threads busy-wait and run 100x slower."""
    with threadpool_limits(limits=1):
        yield


def blobs(n_per: int, spread: float, seed: int, centres=((0, 0), (3, 0), (0, 3))):
    """Gaussian blobs in 2-D, one per class; returns ``(X, y)``."""
    rng = np.random.default_rng(seed)
    X = np.vstack([rng.normal(c, spread, size=(n_per, 2)) for c in centres])
    return X, np.repeat(np.arange(len(centres)), n_per)


def dense_W(Pi: np.ndarray) -> np.ndarray:
    """``W = diag(pi) - Pi Pi^T`` as a dense ``(Cn, Cn)`` matrix, class-major ordering."""
    n, c = Pi.shape
    big_pi = np.vstack([np.diag(Pi[:, k]) for k in range(c)])
    return np.diag(Pi.T.reshape(-1)) - big_pi @ big_pi.T


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_log_det_matches_dense_computation(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n, c = 7, 3 + seed
    X = rng.normal(size=(n, 2))
    K = se_kernel(sq_distances(X, X), np.log([1.0 + seed, 0.9]))
    Pi = softmax(3.0 * rng.normal(size=(n, c)))
    Kb, W = np.kron(np.eye(c), K), dense_W(Pi)
    w, U = np.linalg.eigh(W)  # W is positive semi-definite: W^1/2 by eigendecomposition
    W_half = (U * np.sqrt(np.clip(w, 0.0, None))) @ U.T
    sym = np.linalg.slogdet(np.eye(c * n) + W_half @ Kb @ W_half)
    nonsym = np.linalg.slogdet(np.eye(c * n) + Kb @ W)
    fac = factorize(K, Pi)
    assert sym[0] > 0 and nonsym[0] > 0
    assert abs(fac.log_det - sym[1]) < 1e-8
    assert abs(fac.log_det - nonsym[1]) < 1e-8
    # Algorithm 3.3 as printed (2 sum_c z_c = log|I + D K|) misses log|sum_c E_c|.
    assert abs(fac.log_det_book - sym[1]) > 1e-3


@pytest.mark.parametrize("log_theta", [(0.3, -0.2), (1.2, 0.4)])
def test_gradient_matches_finite_differences(log_theta: tuple[float, float]) -> None:
    X, y = blobs(10, 1.0, seed=3)
    model = MulticlassLaplaceGPC(EXACT).fit(X, y)
    lt = np.array(log_theta)
    _, grad = model.log_marginal_likelihood(lt, return_grad=True)
    h = 1e-5
    fd = np.empty(2)
    for j in range(2):
        e = np.zeros(2)
        e[j] = h  # the mode is re-found at each theta
        fd[j] = (model.log_marginal_likelihood(lt + e) - model.log_marginal_likelihood(lt - e)) / (
            2 * h
        )
    np.testing.assert_allclose(grad, fd, rtol=1e-4, atol=1e-7)

    # Without the implicit term (f_hat held fixed) the gradient is measurably wrong.
    K = se_kernel(sq_distances(X, X), lt)
    mode = model._objective.mode(lt)[1]
    explicit, _ = lml_gradient(
        K, kernel_derivatives(K, sq_distances(X, X), lt), model._Y, mode.a, mode.Pi,
        mode.factor, implicit=False,
    )  # fmt: skip
    assert np.max(np.abs(explicit - fd) / np.abs(fd)) > 1e-3


def test_mode_is_stationary() -> None:
    X, y = blobs(8, 1.0, seed=4)
    model = MulticlassLaplaceGPC(EXACT).fit(X, y)
    mode = model._objective.mode(model.log_theta_)[1]
    # At the mode, K^-1 f = y - pi (GPML eq. 3.34).
    np.testing.assert_allclose(mode.a, model._Y - mode.Pi, atol=1e-9)


def test_predictive_latent_matches_dense_formula() -> None:
    X, y = blobs(8, 1.2, seed=5)
    model = MulticlassLaplaceGPC(EXACT).fit(X, y)
    Xs = np.random.default_rng(6).normal(1.0, 2.0, size=(5, 2))
    mean, cov = model.predict_latent(Xs)
    n, c = X.shape[0], 3
    K = se_kernel(sq_distances(X, X), model.log_theta_)
    Ks = se_kernel(sq_distances(X, Xs), model.log_theta_)
    Pi = softmax(K @ model._a)
    W = dense_W(Pi)
    R = W @ np.linalg.inv(np.eye(c * n) + np.kron(np.eye(c), K) @ W)  # (K + W^-1)^-1
    for i in range(Xs.shape[0]):
        Q = np.kron(np.eye(c), Ks[:, i : i + 1])
        np.testing.assert_allclose(mean[i], Q.T @ (model._Y - Pi).T.reshape(-1), atol=1e-12)
        expected = model.theta_[0] ** 2 * np.eye(c) - Q.T @ R @ Q
        np.testing.assert_allclose(cov[i], expected, atol=1e-10)


@pytest.fixture(scope="module")
def separable() -> tuple[MulticlassLaplaceGPC, np.ndarray, np.ndarray]:
    X, y = blobs(15, 0.4, seed=7)
    Xt, yt = blobs(10, 0.4, seed=8)
    return MulticlassLaplaceGPC(GPCConfig(n_samples=1000)).fit(X, y), Xt, yt


def test_separable_problem_is_learnt(separable) -> None:
    model, Xt, yt = separable
    assert np.mean(model.predict(model._X) == model._y) == 1.0
    assert np.mean(model.predict(Xt) == yt) == 1.0


def test_probabilities_are_valid(separable) -> None:
    model, Xt, _ = separable
    P = model.predict_proba(np.vstack([Xt, [[1.5, 1.5], [50.0, -20.0]]]))
    assert P.shape == (Xt.shape[0] + 2, 3)
    assert np.all(P >= 0.0) and np.all(P <= 1.0)
    np.testing.assert_allclose(P.sum(axis=1), 1.0, atol=1e-12)


def test_far_point_falls_back_to_the_prior(separable) -> None:
    model, _, _ = separable
    far = np.array([[100.0, 100.0], [-80.0, 40.0]])
    mean, cov = model.predict_latent(far)
    np.testing.assert_allclose(mean, 0.0, atol=1e-9)
    np.testing.assert_allclose(cov, np.broadcast_to(model.theta_[0] ** 2 * np.eye(3), cov.shape))
    P = model.predict_proba(far)
    entropy = -np.sum(P * np.log(P), axis=1)
    assert np.all(P.max(axis=1) <= 1 / 3 + 0.1)
    assert np.all(entropy >= 0.95 * np.log(3))
    np.testing.assert_allclose(model.with_predictive("mode").predict_proba(far), 1 / 3)
    # ... while training points are predicted confidently.
    assert np.mean(model.predict_proba(model._X).max(axis=1)) > 0.6


def test_monte_carlo_is_reproducible(separable) -> None:
    model, Xt, _ = separable
    np.testing.assert_array_equal(model.predict_proba(Xt), model.predict_proba(Xt))
    a = model.predict_proba(Xt, rng=np.random.default_rng(11))
    b = model.predict_proba(Xt, rng=np.random.default_rng(11))
    c = model.predict_proba(Xt, rng=np.random.default_rng(12))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    np.testing.assert_allclose(a, c, atol=0.05)  # the same distribution, MC noise only


def test_state_round_trip_through_npz(separable, tmp_path) -> None:
    model, Xt, _ = separable
    np.savez(tmp_path / "gp.npz", **model.get_state())
    with np.load(tmp_path / "gp.npz") as state:
        loaded = MulticlassLaplaceGPC.from_state(state)
    np.testing.assert_array_equal(loaded.predict_proba(Xt), model.predict_proba(Xt))
    assert loaded.theta_ == model.theta_ and loaded.config == model.config


def test_mode_predictive_is_the_softmax_of_the_latent_mean(separable) -> None:
    model, Xt, _ = separable
    mode = model.with_predictive("mode")
    mean, _ = mode.predict_latent(Xt)
    assert mode.predict_proba(Xt).tobytes() == softmax(mean).tobytes()


def test_another_predictive_shares_the_fit_and_its_factor(separable, monkeypatch) -> None:
    import json

    import ipbench.perception.gpc as gpc_module

    model, Xt, _ = separable
    expected = {}
    for predictive in ("mode", "mc"):
        state = model.get_state()
        config = {**json.loads(str(state["config_json"])), "predictive": predictive}
        state["config_json"] = np.array(json.dumps(config))
        loaded = MulticlassLaplaceGPC.from_state(state)
        expected[predictive] = (*loaded.predict_latent(Xt), loaded.predict_proba(Xt), loaded)

    def no_factorize(*_args, **_kwargs):
        raise AssertionError("the factor was computed again for another predictive")

    monkeypatch.setattr(gpc_module, "factorize", no_factorize)
    mode = model.with_predictive("mode")
    back = mode.with_predictive("mc")
    for other, predictive in ((mode, "mode"), (back, "mc")):
        mean, cov, proba, loaded = expected[predictive]
        assert other.config == loaded.config and other.config.predictive == predictive
        got = (*other.predict_latent(Xt), other.predict_proba(Xt))
        for x, y in zip(got, (mean, cov, proba), strict=True):
            assert x.tobytes() == y.tobytes()
        assert other.n_lbfgs_evals_ == 0 and other.theta_ == loaded.theta_
        assert other.log_marginal_likelihood() == loaded.log_marginal_likelihood()
    assert model.config.predictive == "mc"  # the source model is unchanged
    with pytest.raises(GPCError, match="predictive must be one of mc, mode"):
        model.with_predictive("median")


def test_fitting_improves_log_marginal_likelihood() -> None:
    X, y = blobs(12, 1.0, seed=9)
    model = MulticlassLaplaceGPC(GPCConfig(newton_tol=1e-9)).fit(X, y)
    initial = model.log_marginal_likelihood(model.initial_log_theta_)
    fitted, grad = model.log_marginal_likelihood(return_grad=True)
    assert fitted > initial + 0.5
    assert fitted == pytest.approx(model.log_marginal_likelihood_value_, abs=1e-8)
    assert np.all(np.abs(grad) < 0.05 * X.shape[0])  # near a stationary point (or a bound)


def test_subset_start_reaches_the_same_optimum() -> None:
    X, y = blobs(30, 1.0, seed=10)
    direct = MulticlassLaplaceGPC(GPCConfig(init_subset=None)).fit(X, y)
    staged = MulticlassLaplaceGPC(GPCConfig(init_subset=20)).fit(X, y)
    assert staged.n_lbfgs_evals_ > 0
    assert staged.log_marginal_likelihood_value_ == pytest.approx(
        direct.log_marginal_likelihood_value_, abs=0.05
    )


def test_bad_input_raises() -> None:
    X, y = blobs(5, 0.5, seed=1)
    model = MulticlassLaplaceGPC(GPCConfig(optimize=False))
    with pytest.raises(GPCError, match="not fitted"):
        model.predict_proba(X)
    with pytest.raises(GPCError, match=r"shape \(15,\)"):
        model.fit(X, y[:-1])
    with pytest.raises(GPCError, match=r"0\.\.1"):
        model.fit(X, y, n_classes=2)
    with pytest.raises(GPCError, match=r"0\.\.2"):
        model.fit(X, np.where(y == 0, -1, y))
    with pytest.raises(GPCError, match="integer"):
        model.fit(X, y + 0.5)
    with pytest.raises(GPCError, match="2-D"):
        model.fit(X[:, 0], y)
    with pytest.raises(GPCError, match="finite"):
        model.fit(np.where(X > 1, np.nan, X), y)
    model.fit(X, y)
    with pytest.raises(GPCError, match="fitted with 2"):
        model.predict(np.zeros((3, 4)))
    with pytest.raises(GPCError, match="log_theta"):
        model.log_marginal_likelihood(np.zeros(3))
    with pytest.raises(GPCError, match="missing keys"):
        MulticlassLaplaceGPC.from_state({"X": X})
    for bad in ({"amplitude": -1.0}, {"n_samples": 0}, {"bounds": ((1.0, 0.0), (0.0, 1.0))}):
        with pytest.raises(GPCError):
            GPCConfig(**bad)
    assert issubclass(GPCError, ValueError)


def test_unconverged_mode_search_warns() -> None:
    X, y = blobs(5, 0.5, seed=1)
    with pytest.warns(RuntimeWarning, match="Newton iterations"):
        MulticlassLaplaceGPC(GPCConfig(optimize=False, newton_max_iter=1)).fit(X, y)
