"""Exact (full) Gaussian-process regression with an SE-ARD kernel.

Paper, Section "Gaussian Processes" (the offline "GP" variant of the results); Rasmussen &
Williams 2006, Algorithm 2.1 and Eq. 5.9. For each output ``j`` (standardized units)::

    K_y = K(Z, Z) + sigma_n^2 I = L L^T,      alpha = K_y^{-1} y
    mean(z*) = k*^T alpha
    var(z*)  = sigma_n^2 + sigma_s^2 - |L^{-1} k*|^2      (noisy-observation variance)

Hyperparameters maximize the log marginal likelihood

    log p(y | Z) = -1/2 y^T alpha - sum_i log L_ii - N/2 log(2 pi)

with the analytic gradient ``d/dtheta = 1/2 tr((alpha alpha^T - K_y^{-1}) dK_y/dtheta)``.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from scipy.linalg import LinAlgError, cho_solve, cholesky, solve_triangular

from ._optimize import minimize_multistart
from ._validation import check_training_data
from .base import BaseGPLearner
from .casadi_export import sym_se_ard_mean_var
from .hyperparameters import GPHyperparameters, HyperparameterBounds
from .kernels import scaled_sq_dist, se_ard_kernel, se_ard_kernel_input_grad
from .standardization import Standardizer

__all__ = ["ExactGP", "exact_gp_nlml"]

_LOG_2PI = float(np.log(2.0 * np.pi))
_JITTERS = (0.0, 1e-10, 1e-8, 1e-6)


def _chol_with_jitter(K: np.ndarray, noise_var: float) -> tuple[np.ndarray, float]:
    """Lower Cholesky factor of ``K + (noise_var + jitter) I`` with the smallest jitter that
    works (relative to the mean diagonal). Returns ``(L, noise_var + jitter)``."""
    scale = float(np.mean(np.diag(K))) + noise_var
    n = K.shape[0]
    for jit in _JITTERS:
        nv = noise_var + jit * scale
        Ky = K.copy()
        Ky[np.diag_indices(n)] += nv
        try:
            return cholesky(Ky, lower=True, check_finite=False), nv
        except LinAlgError:
            continue
    raise LinAlgError("kernel matrix is not positive definite even with jitter")


def exact_gp_nlml(theta: np.ndarray, Z: np.ndarray, y: np.ndarray) -> tuple[float, np.ndarray]:
    """Negative log marginal likelihood of one output and its gradient.

    Args:
        theta: (d + 2,) ``[log ell, log sigma_s, log sigma_n]``.
        Z: (N, d) standardized inputs.
        y: (N,) standardized targets.

    Returns:
        ``(nlml, d nlml / d theta)`` with the gradient of shape (d + 2,).
    """
    d = Z.shape[1]
    ell = np.exp(theta[:d])
    sf2 = float(np.exp(2.0 * theta[d]))
    sn2 = float(np.exp(2.0 * theta[d + 1]))
    n = Z.shape[0]
    K = sf2 * np.exp(-0.5 * scaled_sq_dist(Z, Z, ell))
    L, _ = _chol_with_jitter(K, sn2)
    alpha = cho_solve((L, True), y, check_finite=False)
    nlml = 0.5 * float(y @ alpha) + float(np.log(np.diag(L)).sum()) + 0.5 * n * _LOG_2PI
    W = np.outer(alpha, alpha) - cho_solve((L, True), np.eye(n), check_finite=False)
    WK = W * K
    A = Z / ell
    # sum_ij WK_ij (a_i - a_j)^2 = 2 sum_i a_i^2 rowsum_i - 2 a^T WK a   (WK symmetric)
    grad_ell = -(WK.sum(1) @ (A * A)) + np.sum(A * (WK @ A), axis=0)
    grad_sf = -float(WK.sum())
    grad_sn = -sn2 * float(np.trace(W))
    return nlml, np.r_[grad_ell, grad_sf, grad_sn]


class ExactGP(BaseGPLearner):
    """Exact GP regression, one independent SE-ARD GP per output.

    Args:
        optimize: maximize the log marginal likelihood; otherwise use ``hyperparameters``.
        hyperparameters: fixed hyperparameters (standardized units) when ``optimize=False``;
            an extra start point when ``optimize=True``.
        bounds: box bounds for the optimizer (standardized units).
        n_restarts: random restarts in addition to the default start (seeded).
        max_iter: L-BFGS-B iteration cap per run.
        max_optimization_samples: optimize on a random subset of at most this many points
            (``None``: all); the final model always conditions on all data.
        normalize: standardize inputs and outputs.
        random_state: seed of the restarts and of the subset.

    Fitted attributes:
        ``hyperparameters_``, ``standardizer_``, ``X_train_`` (N, d_in, standardized),
        ``alpha_`` (d_out, N), ``L_`` (d_out, N, N) lower Cholesky factors of K_y,
        ``log_marginal_likelihood_`` (d_out,), ``n_features_in_``, ``n_outputs_``,
        ``n_samples_seen_``.
    """

    _variance_blocks = ("Linv_",)

    def __init__(
        self,
        *,
        optimize: bool = True,
        hyperparameters: GPHyperparameters | None = None,
        bounds: HyperparameterBounds | None = None,
        n_restarts: int = 2,
        max_iter: int = 200,
        max_optimization_samples: int | None = 1000,
        normalize: bool = True,
        random_state: int | None = 0,
    ) -> None:
        self.optimize = optimize
        self.hyperparameters = hyperparameters
        self.bounds = bounds
        self.n_restarts = n_restarts
        self.max_iter = max_iter
        self.max_optimization_samples = max_optimization_samples
        self.normalize = normalize
        self.random_state = random_state

    # ------------------------------------------------------------------ fitting
    def fit(self, Z: np.ndarray, Y: np.ndarray) -> ExactGP:
        """Fit on ``Z`` (N, d_in), ``Y`` (N, d_out). Returns ``self``."""
        Z, Y = check_training_data(Z, Y)
        if not self.optimize and self.hyperparameters is None:
            raise ValueError("optimize=False requires hyperparameters")
        if self.hyperparameters is not None and (
            self.hyperparameters.d_in != Z.shape[1] or self.hyperparameters.d_out != Y.shape[1]
        ):
            raise ValueError("hyperparameters do not match the data dimensions")
        std = Standardizer.fit(Z, Y, self.normalize)
        Zs, Ys = std.transform_inputs(Z), std.transform_outputs(Y)
        hyp = self._optimize(Zs, Ys) if self.optimize else self.hyperparameters
        assert hyp is not None
        self._condition(Zs, Ys, hyp)
        self.standardizer_ = std
        self.hyperparameters_ = hyp
        return self

    def _optimize(self, Zs: np.ndarray, Ys: np.ndarray) -> GPHyperparameters:
        rng = np.random.default_rng(self.random_state)
        bounds = self.bounds or HyperparameterBounds()
        n, d = Zs.shape
        idx = np.arange(n)
        if self.max_optimization_samples is not None and n > self.max_optimization_samples:
            idx = np.sort(rng.choice(n, self.max_optimization_samples, replace=False))
        rows = []
        for j in range(Ys.shape[1]):
            starts = bounds.initial_guesses(d, self.n_restarts, rng)
            if self.hyperparameters is not None:
                starts.insert(0, self.hyperparameters.log_params(j))
            Zo, yo = Zs[idx], Ys[idx, j]
            theta, _ = minimize_multistart(
                lambda t, Zo=Zo, yo=yo: exact_gp_nlml(t, Zo, yo),
                starts,
                bounds.log_bounds(d),
                self.max_iter,
            )
            rows.append(theta)
        return GPHyperparameters.from_log_params(rows)

    def _condition(self, Zs: np.ndarray, Ys: np.ndarray, hyp: GPHyperparameters) -> None:
        n, d_out = Ys.shape
        L = np.empty((d_out, n, n))
        alpha = np.empty((d_out, n))
        noise_var = np.empty(d_out)
        lml = np.empty(d_out)
        for j in range(d_out):
            K = se_ard_kernel(Zs, Zs, hyp.length_scales[j], hyp.signal_std[j])
            L[j], noise_var[j] = _chol_with_jitter(K, float(hyp.noise_std[j]) ** 2)
            alpha[j] = cho_solve((L[j], True), Ys[:, j], check_finite=False)
            lml[j] = -(0.5 * Ys[:, j] @ alpha[j] + np.log(np.diag(L[j])).sum() + 0.5 * n * _LOG_2PI)
        self.X_train_ = Zs
        self.L_ = L
        self.alpha_ = alpha
        self.noise_var_ = noise_var
        self.log_marginal_likelihood_ = lml
        self.n_features_in_ = Zs.shape[1]
        self.n_outputs_ = d_out
        self.n_samples_seen_ = n
        self._l_inv_cache: np.ndarray | None = None
        self._reset_layout()

    # ------------------------------------------------------------------ prediction
    def _predict_std(
        self, Zs: np.ndarray, return_var: bool
    ) -> tuple[np.ndarray, np.ndarray | None]:
        hyp = self.hyperparameters_
        assert hyp is not None
        m = Zs.shape[0]
        n = self.X_train_.shape[0]
        mean = np.empty((m, self.n_outputs_))
        var = np.empty((m, self.n_outputs_)) if return_var else None
        chunk = max(1, 4_000_000 // max(n, 1))
        for s in range(0, m, chunk):
            Zc = Zs[s : s + chunk]
            for j in range(self.n_outputs_):
                Ks = se_ard_kernel(Zc, self.X_train_, hyp.length_scales[j], hyp.signal_std[j])
                mean[s : s + chunk, j] = Ks @ self.alpha_[j]
                if var is not None:
                    V = solve_triangular(self.L_[j], Ks.T, lower=True, check_finite=False)
                    latent = hyp.signal_std[j] ** 2 - np.einsum("ij,ij->j", V, V)
                    var[s : s + chunk, j] = self.noise_var_[j] + np.maximum(latent, 0.0)
        return mean, var

    def _gradient_std(self, Zs: np.ndarray) -> np.ndarray:
        hyp = self.hyperparameters_
        assert hyp is not None
        return np.stack(
            [
                se_ard_kernel_input_grad(
                    Zs, self.X_train_, self.alpha_[j], hyp.length_scales[j], hyp.signal_std[j]
                )
                for j in range(self.n_outputs_)
            ],
            axis=1,
        )

    # ------------------------------------------------------------------ CasADi export
    def _l_inv(self) -> np.ndarray:
        if self._l_inv_cache is None:
            eye = np.eye(self.X_train_.shape[0])
            self._l_inv_cache = np.stack(
                [solve_triangular(Lj, eye, lower=True, check_finite=False) for Lj in self.L_]
            )
        return self._l_inv_cache

    def _casadi_blocks(self, variance: bool = True) -> list[tuple[str, np.ndarray]]:
        """Training inputs, and per output alpha, 1/ell, sigma_s, effective sigma_n and the
        inverse Cholesky factor ``L^{-1}`` (N x N, for the variance; only with ``variance``)."""
        hyp = self.hyperparameters_
        assert hyp is not None
        Linv = self._l_inv() if variance else None
        blocks: list[tuple[str, np.ndarray]] = [("Z_train", self.X_train_)]
        for j in range(self.n_outputs_):
            blocks += [
                (f"alpha_{j}", self.alpha_[j]),
                (f"inv_ls_{j}", 1.0 / hyp.length_scales[j]),
                (f"sf_{j}", hyp.signal_std[j : j + 1]),
                (f"sn_{j}", np.sqrt(self.noise_var_[j : j + 1])),
                *([(f"Linv_{j}", Linv[j])] if Linv is not None else []),
            ]
        return blocks

    def _casadi_block_shapes(self) -> list[tuple[str, tuple[int, ...]]]:
        n, d = self.X_train_.shape
        shapes: list[tuple[str, tuple[int, ...]]] = [("Z_train", (n, d))]
        for j in range(self.n_outputs_):
            shapes += [
                (f"alpha_{j}", (n,)),
                (f"inv_ls_{j}", (d,)),
                (f"sf_{j}", (1,)),
                (f"sn_{j}", (1,)),
                (f"Linv_{j}", (n, n)),
            ]
        return shapes

    def _sym_mean_var(
        self, zs: ca.SX | ca.MX, theta: ca.SX | ca.MX, j: int, variance: bool
    ) -> tuple[ca.SX | ca.MX, ca.SX | ca.MX | None]:
        lay = self._layout_for(theta)
        return sym_se_ard_mean_var(
            zs,
            lay.unpack(theta, "Z_train"),
            lay.unpack(theta, f"alpha_{j}"),
            lay.unpack(theta, f"inv_ls_{j}"),
            lay.unpack(theta, f"sf_{j}"),
            lay.unpack(theta, f"sn_{j}"),
            lay.unpack(theta, f"Linv_{j}") if variance else None,
        )
