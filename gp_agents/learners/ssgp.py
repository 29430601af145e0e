"""Sparse Spectrum Gaussian Process regression (paper, Section "Sparse Spectrum Gaussian
Processes"; Lazaro-Gredilla et al. 2010).

Per output ``j`` (standardized units), with ``r`` frequencies and ``D = 2r`` features::

    phi(z) = sigma_s / sqrt(r) [cos(Omega^T z); sin(Omega^T z)],   Omega ~ N(0, W^{-1})
    A = Phi Phi^T + sigma_n^2 Sigma_p^{-1},  Sigma_p = I,      A = R^T R (R upper)
    b = Phi y,   w = A^{-1} b = R^{-1} (R^{-T} b)
    mean(z*) = w^T phi(z*),   var(z*) = sigma_n^2 (1 + phi(z*)^T A^{-1} phi(z*))

``Phi = [phi(z_1), ..., phi(z_N)]`` is (D, N). Hyperparameters are either taken from an exact GP
(``hyperparameters="exact"`` or a fitted :class:`ExactGP`) or maximize the SSGP's own marginal
likelihood with the base frequency draws held fixed (``hyperparameters="ssgp"``)::

    -log p(y) = 1/(2 sigma_n^2) (y^T y - b^T w) + 1/2 log|A| + (N - D)/2 log sigma_n^2
                + N/2 log(2 pi)

(the Woodbury / determinant-lemma form of ``N(y; 0, Phi^T Phi + sigma_n^2 I)``), computed from
the Cholesky factor of ``A`` in ``O(N D^2 + D^3)``.

*Linear features* (``linear_features=True``): ``phi(z)`` is extended by ``sigma_l z`` (``d_in``
more features, ``D = 2r + d_in``), i.e. the kernel becomes ``k_SE + sigma_l^2 z^T z'``: Bayesian
linear regression on the inputs plus the SE residual around it. A residual that is linear in
some inputs (damping: linear in the velocities) then extrapolates linearly outside the data
instead of decaying back to the prior mean (or, with huge ``sigma_s`` and length scales at their
bound, of the SE part imitating a polynomial). ``sigma_l`` is one more hyperparameter of the
marginal likelihood (bounds :attr:`HyperparameterBounds.linear_std`).

``linear_features`` may also name input columns (a sequence of indices, negative ones counting
from the end): only those get a linear feature, the others' entries of the block are zero (their
weights stay exactly zero). With the parameter sensitivities as the last inputs
(:mod:`gp_agents.residual`) that is the residual's parametric part alone, ``dp' S(x, u)``,
without linear terms in the raw states and controls: those are nearly collinear with the
sensitivities on data from a narrow region and extrapolate as an offset that the physics
does not have (a drift of a vehicle at rest).

*No Fourier features* (``n_frequencies=0``, only with linear features): ``phi(z) = sigma_l z``
alone, Bayesian linear regression on the linear-feature columns (``sigma_n`` and ``sigma_l``
from the same marginal likelihood, in which the length scales and ``sigma_s`` then do not
enter). With the parameter sensitivities as those columns that is the grey-box
re-identification of the nominal model's parameters, ``y = dp' S(x, u)``; with
:class:`~gp_agents.learners.IncrementalSSGP`'s forgetting, recursive least squares with a
forgetting factor and a prior that keeps the first fits well posed.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import casadi as ca
import numpy as np
from scipy.linalg import LinAlgError, cho_solve, cholesky, solve_triangular

from ._optimize import minimize_multistart
from ._validation import NotFittedError, check_training_data
from .base import BaseGPLearner
from .casadi_export import sym_fourier_features
from .cholesky_update import positive_diagonal, solve_upper
from .exact_gp import ExactGP
from .features import (
    draw_base_frequencies,
    fourier_features,
    fourier_mean_grad,
    scale_frequencies,
)
from .hyperparameters import GPHyperparameters, HyperparameterBounds
from .standardization import Standardizer, check_input_saturation

__all__ = ["SSGP", "linear_mask", "ssgp_nlml"]

_LOG_2PI = float(np.log(2.0 * np.pi))

HyperparameterSource = str | ExactGP | GPHyperparameters


def ssgp_nlml(
    theta: np.ndarray, Z: np.ndarray, y: np.ndarray, base: np.ndarray,
    linear: bool | np.ndarray = False
) -> tuple[float, np.ndarray]:
    """SSGP negative log marginal likelihood of one output and its analytic gradient.

    With ``F = Phi^T`` (N, D), residual ``e = y - F w`` and
    ``G = F A^{-1} - e w^T / sigma_n^2`` (N, D), a change ``dF`` changes the NLML by
    ``sum(G * dF)``; this gives the length-scale, ``sigma_s`` and ``sigma_l`` terms. The noise
    term is ``-q / sigma_n^2 + w^T w + sigma_n^2 tr(A^{-1}) + N - D`` with
    ``q = y^T y - b^T w``.

    Args:
        theta: (d + 2,) ``[log ell, log sigma_s, log sigma_n]``, or (d + 3,) with
            ``log sigma_l`` appended when ``linear``.
        Z: (N, d) standardized inputs.
        y: (N,) standardized targets.
        base: (d, r) fixed standard-normal base frequencies.
        linear: the features end with the linear block ``sigma_l z`` (see :class:`SSGP`);
            a (d,) 0/1 array: ``sigma_l z * mask``, linear features of the masked columns only.

    Returns:
        ``(nlml, gradient (d + 2,) or (d + 3,))``.
    """
    n, d = Z.shape
    r = base.shape[1]
    ell = np.exp(theta[:d])
    sf = float(np.exp(theta[d]))
    s = float(np.exp(2.0 * theta[d + 1]))
    omega = scale_frequencies(base, ell)
    U = Z @ omega
    c = sf / np.sqrt(max(r, 1))  # r = 0: no Fourier features
    cosU, sinU = np.cos(U), np.sin(U)
    blocks = [c * cosU, c * sinU]
    mask = linear_mask(linear, d)
    if mask is not None:
        blocks.append(float(np.exp(theta[d + 2])) * (Z * mask))
    F = np.concatenate(blocks, axis=1)
    D = F.shape[1]
    A = F.T @ F
    A[np.diag_indices(D)] += s
    R = cholesky(A, lower=False, check_finite=False)
    b = F.T @ y
    w = cho_solve((R, False), b, check_finite=False)
    q = float(y @ y - b @ w)
    logdet = 2.0 * float(np.log(np.diag(R)).sum())
    nlml = 0.5 * (q / s + logdet + (n - D) * np.log(s) + n * _LOG_2PI)
    Rinv = solve_triangular(R, np.eye(D), lower=False, check_finite=False)
    FAinv = (F @ Rinv) @ Rinv.T
    e = y - F @ w
    G = FAinv - np.outer(e, w) / s
    grad_sf = float(np.sum(G[:, : 2 * r] * F[:, : 2 * r]))
    H = c * (G[:, r : 2 * r] * cosU - G[:, :r] * sinU)  # (N, r): d nlml / d U
    grad_ell = -np.sum(Z * (H @ omega.T), axis=0)
    grad_sn = -q / s + float(w @ w) + s * float(np.sum(Rinv * Rinv)) + (n - D)
    grad = np.r_[grad_ell, grad_sf, grad_sn]
    if mask is not None:
        grad = np.r_[grad, float(np.sum(G[:, 2 * r :] * F[:, 2 * r :]))]
    return float(nlml), grad


def linear_mask(linear_features: bool | np.ndarray | Sequence[int] | None, d_in: int
                ) -> np.ndarray | None:
    """The (d_in,) 0/1 mask of the input columns with a linear feature, or None (no linear
    features): ``True`` -> every column, a sequence of column indices (negative ones counting
    from the end) -> those, a (d_in,) float array -> itself (a mask already).

    Raises:
        ValueError: an empty selection, an index out of range or given twice.
    """
    if linear_features is None or isinstance(linear_features, bool | np.bool_):
        return np.ones(d_in) if linear_features else None
    if isinstance(linear_features, str):
        raise ValueError(f"linear_features={linear_features!r} names the MPC's parameter-"
                         f"sensitivity columns, which the MPC fills in when the learner is "
                         f"given to it (PseudospectralMPC with Residual(sensitivities=True)); "
                         f"to fit the learner alone, pass the column indices")
    if isinstance(linear_features, np.ndarray) and linear_features.dtype.kind == "f":
        if linear_features.shape != (d_in,):
            raise ValueError(f"a linear-feature mask must have shape ({d_in},), got "
                             f"{linear_features.shape}")
        return linear_features
    cols = [int(c) for c in linear_features]
    if not cols or any(not -d_in <= c < d_in for c in cols):
        raise ValueError(f"linear_features must be a bool or non-empty input column indices in "
                         f"[-{d_in}, {d_in}), got {linear_features!r}")
    positive = [c % d_in for c in cols]
    if len(set(positive)) != len(positive):
        raise ValueError(f"linear_features names a column twice: {linear_features!r}")
    mask = np.zeros(d_in)
    mask[positive] = 1.0
    return mask


def _selection_or_all(linear_features: Any) -> Any:
    """``linear_features`` as :func:`linear_mask` reads it, ``True`` (all) when it is off
    (linear features then come from copied hyperparameters)."""
    if linear_features is None or isinstance(linear_features, bool | np.bool_):
        return True
    return linear_features


class SSGP(BaseGPLearner):
    """Batch Sparse Spectrum GP, one independent SSGP per output.

    Args:
        n_frequencies: ``r`` (the model has ``2r`` features per output); 0 only with
            ``linear_features``: the linear features alone (module docstring).
        hyperparameters: ``"ssgp"`` (maximize the SSGP marginal likelihood), ``"exact"`` (fit an
            :class:`ExactGP` on the same data and copy its hyperparameters and standardization),
            a fitted :class:`ExactGP` (copy its hyperparameters and standardization), or a
            :class:`GPHyperparameters` in standardized units (used as given).
        bounds: optimizer box bounds (standardized units).
        n_restarts: random restarts in addition to the default start.
        max_iter: L-BFGS-B iterations per run.
        max_optimization_samples: optimize on at most this many random points (``None``: all).
        normalize: standardize inputs and outputs (ignored when copying from an ExactGP).
        random_state: seed of the frequency draws, restarts and subset.
        linear_features: append the linear features ``sigma_l z`` (module docstring): ``True``
            for every input column, or a sequence of column indices (negative ones from the
            end) for those only.
        linear_std: ``sigma_l`` when the hyperparameters are not optimized here (``"exact"``,
            an ExactGP or given :class:`GPHyperparameters`); with ``"ssgp"`` it is the
            marginal likelihood's.
        input_saturation: ``s``: the standardized inputs are saturated as ``s tanh(z_s / s)``
            (:class:`Standardizer`) before the features, so that queries far outside the data
            are treated as at ``s`` standard deviations; ``None``: no saturation. Not with
            hyperparameters copied from an :class:`ExactGP` (whose inputs are not saturated).

    Fitted attributes:
        ``hyperparameters_``, ``standardizer_``, ``base_frequencies_`` (d_out, d_in, r),
        ``omega_`` (d_out, d_in, r), ``cholesky_factor_`` (d_out, 2r, 2r) upper ``R`` with
        ``A = R^T R``, ``b_`` (d_out, 2r), ``weights_`` (d_out, 2r), ``n_features_in_``,
        ``n_outputs_``, ``n_samples_seen_``, ``linear_std_`` (d_out,) ``sigma_l`` or None
        (``2r`` reads ``2r + d_in`` with linear features), ``linear_mask_`` (d_in,) 0/1 mask of
        the columns with a linear feature or None.
    """

    _variance_blocks = ("Rinv_",)

    def __init__(
        self,
        n_frequencies: int = 100,
        *,
        hyperparameters: HyperparameterSource = "ssgp",
        bounds: HyperparameterBounds | None = None,
        n_restarts: int = 2,
        max_iter: int = 200,
        max_optimization_samples: int | None = 2000,
        normalize: bool = True,
        random_state: int | None = 0,
        linear_features: bool | Sequence[int] | str = False,
        linear_std: float = 1.0,
        input_saturation: float | None = None,
    ) -> None:
        self.n_frequencies = n_frequencies
        self.input_saturation = input_saturation
        self.linear_features = linear_features
        self.linear_std = linear_std
        self.hyperparameters = hyperparameters
        self.bounds = bounds
        self.n_restarts = n_restarts
        self.max_iter = max_iter
        self.max_optimization_samples = max_optimization_samples
        self.normalize = normalize
        self.random_state = random_state

    # ------------------------------------------------------------------ fitting
    def fit(self, Z: np.ndarray, Y: np.ndarray) -> SSGP:
        """Fit on ``Z`` (N, d_in), ``Y`` (N, d_out). Returns ``self``."""
        Z, Y = check_training_data(Z, Y)
        r = int(self.n_frequencies)
        if r < 0 or (r == 0 and (self.linear_features is None or self.linear_features is False)):
            raise ValueError("n_frequencies must be >= 1, or 0 with linear features (Bayesian "
                             "linear regression on them alone)")
        std, hyp, base, lin = self._resolve_hyperparameters(Z, Y)
        Zs, Ys = std.transform_inputs(Z), std.transform_outputs(Y)
        self._install(std, hyp, base, lin)
        chol, b = [], []
        for j in range(Y.shape[1]):
            F = self._features(Zs, j)
            Rj, bj = self._batch_state(F, Ys[:, j], float(hyp.noise_std[j]))
            chol.append(Rj)
            b.append(bj)
        self._set_state(chol, np.array(b), Z.shape[0])
        return self

    def _resolve_hyperparameters(
        self, Z: np.ndarray, Y: np.ndarray
    ) -> tuple[Standardizer, GPHyperparameters, np.ndarray, np.ndarray | None]:
        d_in, d_out = Z.shape[1], Y.shape[1]
        mask = linear_mask(self.linear_features, d_in)
        linear = mask is not None
        fixed_lin = np.full(d_out, float(self.linear_std)) if linear else None
        if linear and not (np.isfinite(self.linear_std) and self.linear_std > 0):
            raise ValueError("linear_std must be finite and positive")
        r = int(self.n_frequencies)
        saturation = check_input_saturation(self.input_saturation)
        base = draw_base_frequencies(d_out, d_in, r, self.random_state)
        src = self.hyperparameters
        if np.isfinite(saturation) and (isinstance(src, ExactGP) or (isinstance(src, str)
                                                                     and src == "exact")):
            raise ValueError("input_saturation cannot be combined with hyperparameters from an "
                             "ExactGP (its inputs are not saturated); use 'ssgp' or "
                             "GPHyperparameters")
        if isinstance(src, str) and src == "exact":
            src = ExactGP(
                bounds=self.bounds,
                n_restarts=self.n_restarts,
                max_iter=self.max_iter,
                max_optimization_samples=self.max_optimization_samples,
                normalize=self.normalize,
                random_state=self.random_state,
            ).fit(Z, Y)
        if isinstance(src, ExactGP):
            if src.standardizer_ is None or src.hyperparameters_ is None:
                raise NotFittedError("the ExactGP passed as hyperparameters is not fitted")
            if src.n_features_in_ != d_in or src.n_outputs_ != d_out:
                raise ValueError("the ExactGP's dimensions do not match the data")
            return src.standardizer_, src.hyperparameters_, base, fixed_lin
        std = Standardizer.fit(Z, Y, self.normalize, saturation)
        if isinstance(src, GPHyperparameters):
            if src.d_in != d_in or src.d_out != d_out:
                raise ValueError("hyperparameters do not match the data dimensions")
            return std, src, base, fixed_lin
        if not (isinstance(src, str) and src == "ssgp"):
            raise ValueError(
                "hyperparameters must be 'ssgp', 'exact', a fitted ExactGP or GPHyperparameters,"
                f" got {src!r}"
            )
        Zs, Ys = std.transform_inputs(Z), std.transform_outputs(Y)
        rng = np.random.default_rng(self.random_state)
        bounds = self.bounds or HyperparameterBounds()
        n = Z.shape[0]
        idx = np.arange(n)
        if self.max_optimization_samples is not None and n > self.max_optimization_samples:
            idx = np.sort(rng.choice(n, self.max_optimization_samples, replace=False))
        rows = []
        guesses = bounds.initial_guesses(d_in, self.n_restarts, rng)
        log_bounds = bounds.log_bounds(d_in)
        if linear:
            guesses, log_bounds = bounds.with_linear(guesses, log_bounds, rng)
        for j in range(d_out):
            Zo, yo, bj = Zs[idx], Ys[idx, j], base[j]
            theta, _ = minimize_multistart(
                lambda t, Zo=Zo, yo=yo, bj=bj: ssgp_nlml(t, Zo, yo, bj, mask if linear else False),
                guesses,
                log_bounds,
                self.max_iter,
            )
            rows.append(theta)
        lin = np.exp([t[d_in + 2] for t in rows]) if linear else None
        return (std, GPHyperparameters.from_log_params([t[: d_in + 2] for t in rows]), base,
                lin)

    def _install(self, std: Standardizer, hyp: GPHyperparameters, base: np.ndarray,
                 linear_std: np.ndarray | None = None) -> None:
        """Set the data-independent fitted attributes."""
        if linear_std is not None:
            linear_std = np.asarray(linear_std, dtype=float).reshape(hyp.d_out)
            if not (np.all(np.isfinite(linear_std)) and np.all(linear_std > 0)):
                raise ValueError("linear_std must be finite and positive")
        self.linear_std_ = linear_std
        self.linear_mask_ = (None if linear_std is None
                             else linear_mask(_selection_or_all(self.linear_features),
                                              hyp.d_in))
        self.standardizer_ = std
        self.hyperparameters_ = hyp
        self.base_frequencies_ = base
        self.omega_ = np.stack(
            [scale_frequencies(base[j], hyp.length_scales[j]) for j in range(hyp.d_out)]
        )
        self.n_features_in_ = hyp.d_in
        self.n_outputs_ = hyp.d_out
        self._reset_layout()

    def _features(self, Zs: np.ndarray, j: int) -> np.ndarray:
        """(N, D) feature rows of output ``j``: the Fourier features, then ``sigma_l z`` if
        the model has linear features."""
        hyp = self.hyperparameters_
        assert hyp is not None
        F = fourier_features(Zs, self.omega_[j], float(hyp.signal_std[j]))
        lin = getattr(self, "linear_std_", None)
        if lin is None:
            return F
        return np.concatenate([F, lin[j] * (Zs * self.linear_mask_)], axis=1)

    def _batch_state(
        self, F: np.ndarray, y: np.ndarray, noise_std: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Upper factor of ``A = F^T F + sigma_n^2 I`` and ``b = F^T y`` for one output."""
        A = F.T @ F
        A[np.diag_indices(A.shape[0])] += noise_std**2
        try:
            R = cholesky(A, lower=False, check_finite=False)
        except LinAlgError as exc:  # A >= sigma_n^2 I, so only on overflow
            raise RuntimeError("SSGP precision matrix is not positive definite") from exc
        return np.asfortranarray(R), F.T @ y

    def _set_state(self, chol: list[np.ndarray], b: np.ndarray, n_seen: int) -> None:
        self._chol = chol
        self.b_ = b
        self.n_samples_seen_ = n_seen
        self._weights_cache: np.ndarray | None = None
        self._rinv_cache: list[np.ndarray] | None = None

    # ------------------------------------------------------------------ state access
    @property
    def cholesky_factor_(self) -> np.ndarray:
        """(d_out, 2r, 2r) upper-triangular ``R`` with ``A = R^T R`` and a positive diagonal."""
        self._check_fitted()
        return np.stack([positive_diagonal(R) for R in self._chol])

    @property
    def weights_(self) -> np.ndarray:
        """(d_out, 2r) ``w = A^{-1} b`` by two triangular solves (cached until the next update)."""
        self._check_fitted()
        if self._weights_cache is None:
            self._weights_cache = np.stack(
                [solve_upper(R, solve_upper(R, bj, transpose=True))
                 for R, bj in zip(self._chol, self.b_, strict=True)])
        return self._weights_cache

    def _rinv(self) -> list[np.ndarray]:
        if self._rinv_cache is None:
            eye = np.eye(self._chol[0].shape[0])
            self._rinv_cache = [
                solve_triangular(positive_diagonal(R), eye, check_finite=False) for R in self._chol
            ]
        return self._rinv_cache

    # ------------------------------------------------------------------ prediction
    def _predict_std(self, Zs: np.ndarray, return_var: bool) -> tuple[np.ndarray, Any]:
        hyp = self.hyperparameters_
        assert hyp is not None
        W = self.weights_
        mean = np.empty((Zs.shape[0], self.n_outputs_))
        var = np.empty_like(mean) if return_var else None
        for j in range(self.n_outputs_):
            F = self._features(Zs, j)
            mean[:, j] = F @ W[j]
            if var is not None:
                V = solve_triangular(self._chol[j], F.T, trans="T", check_finite=False)
                var[:, j] = hyp.noise_std[j] ** 2 * (1.0 + np.einsum("ij,ij->j", V, V))
        return mean, var

    def _gradient_std(self, Zs: np.ndarray) -> np.ndarray:
        hyp = self.hyperparameters_
        assert hyp is not None
        W = self.weights_
        D = 2 * self.omega_.shape[2]
        lin = self.linear_std_
        grads = []
        for j in range(self.n_outputs_):
            g = fourier_mean_grad(Zs, self.omega_[j], float(hyp.signal_std[j]), W[j][:D])
            if lin is not None:
                g = g + lin[j] * (W[j][D:] * self.linear_mask_)[None, :]
            grads.append(g)
        return np.stack(grads, axis=1)

    # ------------------------------------------------------------------ CasADi export
    def _casadi_block_shapes(self) -> list[tuple[str, tuple[int, ...]]]:
        d, r = self.omega_.shape[1:]
        lin = self.linear_std_ is not None
        D = 2 * r + (d if lin else 0)
        shapes: list[tuple[str, tuple[int, ...]]] = []
        for j in range(self.n_outputs_):
            shapes += [
                (f"omega_{j}", (d, r)),
                (f"sf_{j}", (1,)),
                (f"sn_{j}", (1,)),
                *([(f"sl_{j}", (1,))] if lin else []),
                (f"w_{j}", (D,)),
                (f"Rinv_{j}", (D, D)),
            ]
        return shapes

    def _casadi_blocks(self, variance: bool = True) -> list[tuple[str, np.ndarray]]:
        """Per output: frequencies, sigma_s, sigma_n, (sigma_l,) weights, and ``R^{-1}`` (for
        the variance ``sigma_n^2 (1 + |R^{-T} phi|^2)``; only with ``variance``)."""
        hyp = self.hyperparameters_
        assert hyp is not None
        W = self.weights_
        Rinv = self._rinv() if variance else None
        blocks: list[tuple[str, np.ndarray]] = []
        for j in range(self.n_outputs_):
            blocks += [
                (f"omega_{j}", self.omega_[j]),
                (f"sf_{j}", hyp.signal_std[j : j + 1]),
                (f"sn_{j}", hyp.noise_std[j : j + 1]),
                *([(f"sl_{j}", self.linear_std_[j : j + 1])]
                  if self.linear_std_ is not None else []),
                (f"w_{j}", W[j]),
                *([(f"Rinv_{j}", Rinv[j])] if Rinv is not None else []),
            ]
        return blocks

    def _sym_masked(self, Zs: ca.SX | ca.MX) -> ca.SX | ca.MX:
        """Standardized inputs (d_in, M) with the rows without a linear feature zeroed
        (``Zs`` itself when every column has one)."""
        mask = self.linear_mask_
        if mask is None or np.all(mask == 1.0):
            return Zs
        return ca.diag(ca.DM(mask)) @ Zs

    def _sym_mean_var_batch(
        self, Zs: ca.MX, theta: ca.MX, j: int, variance: bool
    ) -> tuple[ca.MX, ca.MX | None]:
        lay = self._layout_for(theta)
        omega = lay.unpack(theta, f"omega_{j}")
        arg = ca.mtimes(omega.T, Zs)  # (r, M)
        phi = (lay.unpack(theta, f"sf_{j}") / np.sqrt(max(omega.shape[1], 1))) * ca.vertcat(
            ca.cos(arg), ca.sin(arg))
        if self.linear_std_ is not None:
            phi = ca.vertcat(phi, lay.unpack(theta, f"sl_{j}") * self._sym_masked(Zs))
        mean = ca.mtimes(lay.unpack(theta, f"w_{j}").T, phi)
        if not variance:
            return mean, None
        v = ca.mtimes(lay.unpack(theta, f"Rinv_{j}").T, phi)
        return mean, lay.unpack(theta, f"sn_{j}") ** 2 * (1.0 + ca.sum1(v**2))

    def _sym_mean_grad_batch(self, Zs: ca.MX, theta: ca.MX, j: int) -> tuple[ca.MX, ca.MX]:
        """The mean of :meth:`_sym_mean_var_batch` (the same operations) and its analytic
        gradient in the standardized inputs: with ``U = Omega' Zs`` and ``c = sigma_s /
        sqrt(r)``, ``d mean / d Zs = Omega (c (w_s o cos U - w_c o sin U))`` (+ ``sigma_l``
        times the linear weights on the masked columns)."""
        lay = self._layout_for(theta)
        omega = lay.unpack(theta, f"omega_{j}")
        r, M = omega.shape[1], Zs.shape[1]
        arg = ca.mtimes(omega.T, Zs)  # (r, M)
        cos, sin = ca.cos(arg), ca.sin(arg)
        c = lay.unpack(theta, f"sf_{j}") / np.sqrt(max(r, 1))
        phi = c * ca.vertcat(cos, sin)
        w = lay.unpack(theta, f"w_{j}")
        if self.linear_std_ is not None:
            phi = ca.vertcat(phi, lay.unpack(theta, f"sl_{j}") * self._sym_masked(Zs))
        mean = ca.mtimes(w.T, phi)
        H = c * (ca.repmat(w[r:2 * r], 1, M) * cos - ca.repmat(w[:r], 1, M) * sin)
        grad = ca.mtimes(omega, H)  # (d_in, M)
        if self.linear_std_ is not None:
            slope = lay.unpack(theta, f"sl_{j}") * w[2 * r:]
            if not np.all(self.linear_mask_ == 1.0):
                slope = slope * ca.DM(self.linear_mask_)
            grad = grad + ca.repmat(slope, 1, M)
        return mean, grad

    def _sym_mean_var(
        self, zs: ca.SX | ca.MX, theta: ca.SX | ca.MX, j: int, variance: bool
    ) -> tuple[ca.SX | ca.MX, ca.SX | ca.MX | None]:
        lay = self._layout_for(theta)
        phi = sym_fourier_features(
            zs, lay.unpack(theta, f"omega_{j}"), lay.unpack(theta, f"sf_{j}")
        )
        if self.linear_std_ is not None:
            phi = ca.vertcat(phi, lay.unpack(theta, f"sl_{j}") * self._sym_masked(zs))
        mean = ca.dot(lay.unpack(theta, f"w_{j}"), phi)
        if not variance:
            return mean, None
        v = ca.mtimes(lay.unpack(theta, f"Rinv_{j}").T, phi)
        return mean, lay.unpack(theta, f"sn_{j}") ** 2 * (1.0 + ca.sumsqr(v))
