"""Private: analytic gradient of the multi-class Laplace ``log q(y|X, theta)``.

``log q = Psi(f_hat) - 1/2 log|B|`` with ``B = I_Cn + K W`` (GPML eq. 3.44). Because
``f_hat`` moves with ``theta``, the total derivative has two parts (the multi-class
version of GPML eqs. 5.22-5.23):

* explicit, ``f_hat`` held fixed::

      1/2 a^T dK a - 1/2 tr(R dK),    R = W (I + K W)^-1 = E - E R_n (sum_c E_c)^-1 R_n^T E

* implicit, through the mode (``dPsi/df = 0`` there, only ``log|B|`` contributes)::

      s^T df_hat,   df_hat = (I + K W)^-1 dK (y - pi),   s = -1/2 d log|B| / d f_hat

  ``d log|B| / d f = tr(Sigma dW/df)`` with ``Sigma = (K^-1 + W)^-1``; ``W`` couples the
  ``C`` classes of one point only, so only the per-point ``C x C`` blocks ``V_i`` of
  ``Sigma`` are needed. With ``W_i = diag(pi_i) - pi_i pi_i^T`` (third derivatives of the
  softmax log-likelihood)::

      s_ik = -1/2 pi_ik [V_i,kk - sum_c pi_ic V_i,cc - 2 (V_i pi_i)_k + 2 pi_i^T V_i pi_i]

  and ``V_i = K_ii I - diag_c((K E_c K)_ii) + [(E_c K)_:i^T (sum E)^-1 (E_c' K)_:i]_cc'``.

Cost per class: one triangular solve, one ``syrk`` and one ``gemm`` of size ``n``.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import blas, solve_triangular

from ipbench.perception._gpc_laplace import (
    LaplaceFactor,
    Mode,
    apply_inv_I_plus_KW,
    find_mode,
    psi,
    se_kernel,
)

__all__ = ["LaplaceObjective", "kernel_derivatives", "lml_gradient"]


def kernel_derivatives(K: np.ndarray, sqd: np.ndarray, log_theta: np.ndarray) -> list[np.ndarray]:
    """``[dK/d log sigma, dK/d log ell]`` of the SE kernel, each ``(n, n)``."""
    return [2.0 * K, K * (sqd * np.exp(-2.0 * float(log_theta[1])))]


def _sym_trace(A_lower: np.ndarray, B: np.ndarray) -> float:
    """``tr(A B)`` for symmetric ``A`` given by its lower triangle (upper zero), symmetric ``B``."""
    return float(2.0 * np.sum(A_lower * B) - np.sum(np.diag(A_lower) * np.diag(B)))


def lml_gradient(
    K: np.ndarray,
    dKs: list[np.ndarray],
    Y: np.ndarray,
    a: np.ndarray,
    Pi: np.ndarray,
    fac: LaplaceFactor,
    implicit: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Gradient of ``log q`` with respect to each ``dK`` direction, and ``d a_hat / d theta``.

    Parameters
    ----------
    K : (n, n) kernel; dKs : list of (n, n) kernel derivatives; Y, a, Pi : (n, C) one-hot
        labels, ``K^-1 f_hat`` and ``softmax(f_hat)`` at the mode; fac : factorisation there.
    implicit : bool
        Include the term through ``f_hat``. Only ``False`` in tests that show it matters.

    Returns
    -------
    grad : (len(dKs),) array
    da : (len(dKs), n, C) array
        Derivative of ``a_hat = y - pi_hat`` (used to warm-start the next mode search).
    """
    n, n_cls = Pi.shape
    E, M = fac.E, fac.M
    S = E.sum(axis=0)
    # sum_c E_c S^-1 E_c (lower triangle) and Q_c = M^-1 E_c K.
    ESE = np.zeros((n, n), order="F")
    Q = np.empty((n_cls, n, n)) if implicit else None
    for c in range(n_cls):
        X = solve_triangular(M, E[c], lower=True, check_finite=False)
        ESE = blas.dsyrk(1.0, X, beta=1.0, c=ESE, trans=1, lower=1, overwrite_c=1)
        if Q is not None:
            Q[c] = X @ K
    R_lower = np.tril(S) - ESE  # syrk leaves the upper triangle of ESE at zero
    YmP = Y - Pi
    grad = np.empty(len(dKs))
    dfs = []
    for j, dK in enumerate(dKs):
        grad[j] = 0.5 * np.sum(a * (dK @ a)) - 0.5 * _sym_trace(R_lower, dK)
        dfs.append(apply_inv_I_plus_KW(K, fac, dK @ YmP))

    if Q is not None:
        # (K E_c K)_ii = sum_j (K M)_ij Q_c[j, i]; K M by trmm (M lower triangular).
        KMt = blas.dtrmm(1.0, M, K, side=1, lower=1).T
        V = np.zeros((n, n_cls, n_cls))
        for c in range(n_cls):
            V[:, c, c] = np.diag(K) - np.einsum("ji,ji->i", KMt, Q[c])
            for d in range(c, n_cls):
                cross = np.einsum("ji,ji->i", Q[c], Q[d])
                V[:, c, d] += cross
                if d != c:
                    V[:, d, c] += cross
        dV = np.einsum("icc->ic", V)
        Vp = np.einsum("icd,id->ic", V, Pi)
        pVp = np.sum(Pi * Vp, axis=1, keepdims=True)
        s = -0.5 * Pi * (dV - np.sum(Pi * dV, axis=1, keepdims=True) - 2.0 * Vp + 2.0 * pVp)
        for j, df in enumerate(dfs):
            grad[j] += float(np.sum(s * df))

    da = np.empty((len(dKs), n, n_cls))
    for j, df in enumerate(dfs):
        Wdf = Pi * df - Pi * np.sum(Pi * df, axis=1, keepdims=True)
        da[j] = -Wdf
    return grad, da


class LaplaceObjective:
    """``log q`` and its gradient on one training set, with warm-started mode searches.

    Each call starts Newton from the previous mode ``a``, moved to first order in
    ``theta`` with the ``da/dtheta`` of the previous gradient when that raises ``Psi``.

    Parameters
    ----------
    sqd : (n, n) squared distances; Y : (n, C) one-hot labels.
    newton_tol, newton_max_iter : see :class:`ipbench.perception.gpc.GPCConfig`.
    """

    def __init__(self, sqd: np.ndarray, Y: np.ndarray, newton_tol: float, newton_max_iter: int):
        self.sqd, self.Y = sqd, Y
        self.tol, self.max_iter = newton_tol, newton_max_iter
        self.theta: np.ndarray | None = None
        self.a = np.zeros_like(Y)
        self.da: np.ndarray | None = None
        self.n_evals = 0
        self.last: Mode | None = None

    def mode(self, log_theta: np.ndarray) -> tuple[np.ndarray, Mode]:
        """Kernel matrix and Laplace mode at ``log_theta``; the mode is cached."""
        K = se_kernel(self.sqd, log_theta)
        if (
            self.last is not None
            and self.theta is not None
            and np.array_equal(log_theta, self.theta)
        ):
            return K, self.last
        a0 = self.a
        if self.da is not None and self.theta is not None:
            pred = a0 + np.tensordot(log_theta - self.theta, self.da, axes=1)
            if psi(pred, K @ pred, self.Y) > psi(a0, K @ a0, self.Y):
                a0 = pred
        mode = find_mode(K, self.Y, a0, self.tol, self.max_iter)
        self.theta, self.a, self.da, self.last = (
            np.array(log_theta, dtype=float),
            mode.a,
            None,
            mode,
        )
        return K, mode

    def __call__(self, log_theta: np.ndarray, grad: bool = True) -> tuple[float, np.ndarray | None]:
        """``(log q, d log q / d log_theta)`` (gradient None unless ``grad``)."""
        self.n_evals += 1
        log_theta = np.asarray(log_theta, dtype=float)
        K, mode = self.mode(log_theta)
        if not grad:
            return mode.log_q, None
        g, self.da = lml_gradient(
            K, kernel_derivatives(K, self.sqd, log_theta), self.Y, mode.a, mode.Pi, mode.factor
        )
        return mode.log_q, g
