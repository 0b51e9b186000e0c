"""Private core of :mod:`ipbench.perception.gpc`: SE kernel and GPML Algorithm 3.3.

Notation follows Rasmussen & Williams, *Gaussian Processes for Machine Learning* (GPML),
ch. 3, but arrays are stored point-major: latent values ``F`` and class probabilities
``Pi`` have shape ``(n, C)`` (column ``c`` is the book's ``f_c`` / ``pi_c``). All classes
share one kernel matrix ``K`` of shape ``(n, n)``.

The log-determinant
-------------------
GPML eq. 3.44 needs ``log|I_Cn + W^1/2 K W^1/2| = log|I_Cn + K W|`` with
``W = D - Pi Pi^T``. Algorithm 3.3 as printed returns only ``sum_c z_c``, i.e.
``1/2 log|I + D K|``: it drops the ``Pi Pi^T`` part. With the matrix-determinant lemma and
``sum_c D_c = I_n``,

    |I + K W| = |I + D K| * |I_n - Pi^T (I + D K)^-1 K Pi| = prod_c |B_c| * |sum_c E_c|,

so the exact value is ``2 sum_c z_c + 2 sum_i log M_ii`` with ``M = chol(sum_c E_c)``, which
Algorithm 3.3 already computes. :func:`factorize` returns this corrected value; the tests
check it against a dense ``slogdet``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_solve, lapack, solve_triangular

__all__ = [
    "LaplaceFactor",
    "Mode",
    "apply_inv_I_plus_KW",
    "factorize",
    "find_mode",
    "mc_softmax",
    "predictive_latent",
    "predictive_mean",
    "psi",
    "se_kernel",
    "softmax",
    "sq_distances",
]


def sq_distances(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Squared Euclidean distances, shape ``(len(A), len(B))``, clipped at 0."""
    d = np.einsum("ij,ij->i", A, A)[:, None] + np.einsum("ij,ij->i", B, B)[None, :]
    d -= 2.0 * (A @ B.T)
    np.maximum(d, 0.0, out=d)
    return d


def se_kernel(sqd: np.ndarray, log_theta: np.ndarray) -> np.ndarray:
    """Isotropic squared exponential ``sigma^2 exp(-d^2 / (2 ell^2))`` from squared distances.

    ``log_theta = (log sigma, log ell)``; ``sigma`` is in latent (logit) units, ``ell`` in
    input units.
    """
    log_sigma, log_ell = float(log_theta[0]), float(log_theta[1])
    return np.exp(2.0 * log_sigma - 0.5 * sqd * np.exp(-2.0 * log_ell))


def softmax(F: np.ndarray) -> np.ndarray:
    """Row-wise softmax of ``F`` (any leading shape, classes last)."""
    Z = np.exp(F - F.max(axis=-1, keepdims=True))
    return Z / Z.sum(axis=-1, keepdims=True)


def _logsumexp_rows(F: np.ndarray) -> np.ndarray:
    m = F.max(axis=1)
    return m + np.log(np.exp(F - m[:, None]).sum(axis=1))


def psi(a: np.ndarray, F: np.ndarray, Y: np.ndarray) -> float:
    """Laplace objective ``-1/2 f^T K^-1 f + log p(y|f)`` with ``a = K^-1 f`` (GPML eq. 3.32)."""
    return float(-0.5 * np.sum(a * F) + np.sum(Y * F) - np.sum(_logsumexp_rows(F)))


@dataclass(frozen=True)
class LaplaceFactor:
    """Cholesky-based factorisation at one ``pi`` (GPML Algorithm 3.3, lines 5-10).

    Attributes
    ----------
    E : (C, n, n) array
        ``E_c = D_c^1/2 (I + D_c^1/2 K D_c^1/2)^-1 D_c^1/2``, symmetric.
    M : (n, n) array
        Lower Cholesky factor of ``sum_c E_c``.
    log_det : float
        Exact ``log|I_Cn + K W|`` (corrected, see module docstring).
    log_det_book : float
        ``2 sum_c z_c = log|I + D K|``, what Algorithm 3.3 as printed uses.
    """

    E: np.ndarray
    M: np.ndarray
    log_det: float
    log_det_book: float


def factorize(K: np.ndarray, Pi: np.ndarray) -> LaplaceFactor:
    """Per-class Choleskys, ``E_c``, ``M`` and the log-determinant at class probabilities ``Pi``.

    Parameters
    ----------
    K : (n, n) array
        Kernel matrix shared by all classes.
    Pi : (n, C) array
        Class probabilities (rows on the simplex).
    """
    n, n_cls = Pi.shape
    E = np.empty((n_cls, n, n))
    half_book = 0.0
    diag = np.arange(n)
    for c in range(n_cls):
        sd = np.sqrt(Pi[:, c])
        B = K * np.outer(sd, sd)
        B[diag, diag] += 1.0
        L, info = lapack.dpotrf(B, lower=1, clean=1, overwrite_a=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"Cholesky of I + D^1/2 K D^1/2 failed (info={info})")
        half_book += float(np.sum(np.log(np.diag(L))))
        Binv, info = lapack.dpotri(L, lower=1, overwrite_c=1)
        if info != 0:
            raise np.linalg.LinAlgError(f"inverse from Cholesky failed (info={info})")
        Binv = np.tril(Binv)
        Binv += Binv.T
        Binv[diag, diag] *= 0.5
        Binv *= sd[:, None]
        Binv *= sd[None, :]
        E[c] = Binv
    M, info = lapack.dpotrf(E.sum(axis=0), lower=1, clean=1, overwrite_a=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"Cholesky of sum_c E_c failed (info={info})")
    log_det_m = 2.0 * float(np.sum(np.log(np.diag(M))))
    return LaplaceFactor(
        E=E, M=M, log_det=2.0 * half_book + log_det_m, log_det_book=2.0 * half_book
    )


def _apply_E(E: np.ndarray, V: np.ndarray) -> np.ndarray:
    """``out[:, c] = E_c @ V[:, c]`` for ``V`` of shape ``(n, C)``."""
    out = np.empty_like(V)
    for c in range(V.shape[1]):
        out[:, c] = E[c] @ V[:, c]
    return out


def _apply_R(fac: LaplaceFactor, V: np.ndarray) -> np.ndarray:
    """``(E - E R (sum_c E_c)^-1 R^T E) V = W (I + K W)^-1 V`` (block columns of ``V``)."""
    U = _apply_E(fac.E, V)
    t = cho_solve((fac.M, True), U.sum(axis=1), check_finite=False)
    return U - _apply_E(fac.E, np.repeat(t[:, None], V.shape[1], axis=1))


def apply_inv_I_plus_KW(K: np.ndarray, fac: LaplaceFactor, V: np.ndarray) -> np.ndarray:
    """``(I_Cn + K W)^-1 V = V - K W (I + K W)^-1 V`` for ``V`` of shape ``(n, C)``."""
    return V - K @ _apply_R(fac, V)


@dataclass(frozen=True)
class Mode:
    """Result of :func:`find_mode`: the posterior mode and ``log q(y|X, theta)``.

    ``a = K^-1 f`` (equal to ``y - pi`` at the mode), ``F = K a``, ``Pi = softmax(F)``, all
    ``(n, C)``; ``factor`` was computed at the start of the last Newton step, i.e. within
    ``newton_tol`` of ``F``; ``log_q`` is GPML eq. 3.44 with the exact determinant.
    """

    a: np.ndarray
    F: np.ndarray
    Pi: np.ndarray
    factor: LaplaceFactor
    log_q: float
    n_iter: int
    converged: bool


def find_mode(K: np.ndarray, Y: np.ndarray, a0: np.ndarray, tol: float, max_iter: int) -> Mode:
    """Newton's method for the Laplace mode (GPML Algorithm 3.3), warm-started at ``a0``.

    Each step is lines 4-15 of Algorithm 3.3 (``b = W f + y - pi``, ``c = E K b``,
    ``a = b - c + E R M^-T M^-1 R^T c``, ``f = K a``), halved while it lowers ``Psi``.
    Stops when the largest change of ``f`` is below ``tol`` (latent units).

    Parameters
    ----------
    K : (n, n) kernel matrix; Y : (n, C) one-hot labels; a0 : (n, C) start (``f = K a0``).
    """
    a = a0
    F = K @ a
    obj = psi(a, F, Y)
    converged = False
    it = 0
    while it < max_iter:
        it += 1
        Pi = softmax(F)
        fac = factorize(K, Pi)
        PF = Pi * F
        b = PF - Pi * PF.sum(axis=1, keepdims=True) + Y - Pi
        cvec = _apply_E(fac.E, K @ b)
        t = cho_solve((fac.M, True), cvec.sum(axis=1), check_finite=False)
        a_new = b - cvec + _apply_E(fac.E, np.repeat(t[:, None], b.shape[1], axis=1))
        F_new = K @ a_new
        obj_new = psi(a_new, F_new, Y)
        for _ in range(30):  # step halving; Psi is concave so this terminates
            if obj_new >= obj - 1e-12 * abs(obj):
                break
            a_new, F_new = 0.5 * (a + a_new), 0.5 * (F + F_new)
            obj_new = psi(a_new, F_new, Y)
        step = float(np.max(np.abs(F_new - F)))
        a, F, obj = a_new, F_new, obj_new
        if step < tol:
            converged = True
            break
    if not converged:
        warnings.warn(
            f"Laplace mode search stopped after {max_iter} Newton iterations with a last "
            f"step of {step:.3g} (newton_tol={tol:g}); log q and predictions are approximate",
            RuntimeWarning,
            stacklevel=3,
        )
    log_q = obj - 0.5 * fac.log_det
    return Mode(a=a, F=F, Pi=softmax(F), factor=fac, log_q=log_q, n_iter=it, converged=converged)


def predictive_latent(
    Ks: np.ndarray, kss: float, YmP: np.ndarray, fac: LaplaceFactor
) -> tuple[np.ndarray, np.ndarray]:
    """Latent predictive mean and covariance (GPML Algorithm 3.4, lines 2-12).

    Parameters
    ----------
    Ks : (n, m) cross-covariances ``k(x_i, x*_j)``; kss : prior variance ``k(x*, x*)``;
    YmP : (n, C) ``y - pi`` at the mode; fac : :func:`factorize` at the mode.

    Returns
    -------
    mean : (m, C) ``mu*_c = k*^T (y_c - pi_c)``.
    cov : (m, C, C) ``Sigma* = kss I - Q*^T (K + W^-1)^-1 Q*``, i.e.
        ``Sigma*_cc' = delta_cc' (kss - k*^T E_c k*) + (E_c k*)^T (sum E)^-1 (E_c' k*)``.
    """
    n_cls, m = YmP.shape[1], Ks.shape[1]
    cov = np.zeros((m, n_cls, n_cls))
    T = np.empty((n_cls, Ks.shape[0], m))
    for c in range(n_cls):
        B = fac.E[c] @ Ks
        cov[:, c, c] = kss - np.einsum("ji,ji->i", B, Ks)
        T[c] = solve_triangular(fac.M, B, lower=True, check_finite=False)
    for c in range(n_cls):
        for d in range(c, n_cls):
            x = np.einsum("ji,ji->i", T[c], T[d])
            cov[:, c, d] += x
            if d != c:
                cov[:, d, c] += x
    return predictive_mean(Ks, YmP), cov


def predictive_mean(Ks: np.ndarray, YmP: np.ndarray) -> np.ndarray:
    """Latent predictive mean ``(m, C)``, ``mu*_c = k*^T (y_c - pi_c)`` (GPML Algorithm 3.4,
    line 4), from the cross-covariances ``Ks`` (n, m) and ``YmP`` (n, C): what
    :func:`predictive_latent` returns as its mean, without the covariance's ``C`` products
    with the factor."""
    return Ks.T @ YmP


def mc_softmax(
    mean: np.ndarray, cov: np.ndarray, n_samples: int, rng: np.random.Generator
) -> np.ndarray:
    """``E[softmax(f)]`` for ``f ~ N(mean_i, cov_i)`` by Monte Carlo (Algorithm 3.4, 13-17).

    ``mean`` is ``(m, C)``, ``cov`` ``(m, C, C)``; returns ``(m, C)``. The symmetric square
    root of ``cov`` (negative round-off eigenvalues clipped) maps standard normal draws.
    """
    m, n_cls = mean.shape
    w, U = np.linalg.eigh(0.5 * (cov + np.swapaxes(cov, 1, 2)))
    root = U * np.sqrt(np.maximum(w, 0.0))[:, None, :]
    out = np.empty_like(mean)
    step = max(1, 400_000 // (n_samples * n_cls))
    for s in range(0, m, step):
        z = rng.standard_normal((min(step, m - s), n_samples, n_cls))
        f = mean[s : s + step, None, :] + np.einsum("mcd,msd->msc", root[s : s + step], z)
        out[s : s + step] = softmax(f).mean(axis=1)
    return out / out.sum(axis=1, keepdims=True)
