"""Common scikit-learn-like behaviour of the residual learners.

Every learner models ``d_out`` independent scalar GPs (paper, Section "Gaussian Processes": one GP
per dimension of the residual ``y = f_true(x, u) - f_nominal(x, u)``) on standardized inputs and
outputs. Subclasses implement the standardized-space predictions and their CasADi counterparts;
this base class does validation, unit conversion and the CasADi parameter-vector contract.

Predictive variances are those of a *noisy observation* ``y*`` (they include ``sigma_n^2``), which
is the form the paper gives for the SSGP, ``sigma_n^2 (1 + phi^T A^{-1} phi)``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any

import casadi as ca
import numpy as np

from ._validation import NotFittedError, check_inputs
from .casadi_export import ParamLayout, sym_saturate, sym_standardize
from .hyperparameters import GPHyperparameters
from .standardization import Standardizer

__all__ = ["BaseGPLearner", "mean_gradient_batch"]


class BaseGPLearner(ABC):
    """Shared prediction / export logic. Fitted attributes end with an underscore."""

    standardizer_: Standardizer | None = None
    hyperparameters_: GPHyperparameters | None = None
    _variance_blocks: tuple[str, ...] = ()
    """Name prefixes of the blocks of :meth:`_casadi_blocks` that only the variance reads (left
    out of the mean-only parameter vector, :meth:`casadi_mean_param_values`)."""
    n_features_in_: int
    n_outputs_: int
    n_samples_seen_: int

    # ------------------------------------------------------------------ subclass hooks
    @abstractmethod
    def _predict_std(self, Zs: np.ndarray, return_var: bool) -> tuple[np.ndarray, Any]:
        """Standardized mean (N, d_out) and, if asked, variance (N, d_out)."""

    @abstractmethod
    def _gradient_std(self, Zs: np.ndarray) -> np.ndarray:
        """Standardized-space mean gradient (N, d_out, d_in)."""

    @abstractmethod
    def _casadi_blocks(self, variance: bool = True) -> list[tuple[str, np.ndarray]]:
        """Learner-specific ``(name, value)`` blocks of the CasADi parameter vector; without
        ``variance``, those only the variance reads may be left out (not computed)."""

    def _casadi_block_shapes(self) -> list[tuple[str, tuple[int, ...]]]:
        """Shapes of :meth:`_casadi_blocks` (override when the values are costly)."""
        return [(name, np.shape(v)) for name, v in self._casadi_blocks()]

    @abstractmethod
    def _sym_mean_var(
        self, zs: ca.SX | ca.MX, theta: ca.SX | ca.MX, j: int, variance: bool
    ) -> tuple[ca.SX | ca.MX, ca.SX | ca.MX | None]:
        """Standardized mean and (optionally) variance of output ``j`` as CasADi scalars."""

    def _sym_mean_var_batch(
        self, Zs: ca.MX, theta: ca.MX, j: int, variance: bool
    ) -> tuple[ca.MX, ca.MX | None]:
        """:meth:`_sym_mean_var` at the columns of ``Zs`` (d_in, M): (1, M) rows. This default
        builds one expression per column; learners override it with matrix operations."""
        pairs = [self._sym_mean_var(Zs[:, k], theta, j, variance) for k in range(Zs.shape[1])]
        mean = ca.horzcat(*[m for m, _ in pairs])
        return mean, (ca.horzcat(*[v for _, v in pairs]) if variance else None)

    # ------------------------------------------------------------------ helpers
    def _check_fitted(self) -> None:
        if self.standardizer_ is None or self.hyperparameters_ is None:
            raise NotFittedError(
                f"this {type(self).__name__} instance is not fitted yet; call fit(Z, Y) first"
            )

    def _layout(self) -> ParamLayout:
        layout = getattr(self, "_layout_cache", None)
        if layout is None:
            shapes = [(name, np.shape(v)) for name, v in self._standardizer_blocks()]
            layout = ParamLayout(shapes + self._casadi_block_shapes())
            self._layout_cache = layout
        return layout

    def _mean_layout(self) -> ParamLayout:
        """The layout of the mean-only parameter vector: :meth:`_layout` without the blocks
        only the variance reads (:attr:`_variance_blocks`)."""
        layout = getattr(self, "_mean_layout_cache", None)
        if layout is None:
            shapes = [(name, np.shape(v)) for name, v in self._standardizer_blocks()]
            layout = ParamLayout(shapes + [
                (name, shape) for name, shape in self._casadi_block_shapes()
                if not name.startswith(self._variance_blocks)])
            self._mean_layout_cache = layout
        return layout

    def _layout_for(self, theta: ca.SX | ca.MX) -> ParamLayout:
        """The layout ``theta`` is packed with, told by its size: :meth:`_layout` (the full
        vector) or :meth:`_mean_layout` (the mean-only one)."""
        full = self._layout()
        if theta.shape[0] == full.size:
            return full
        mean = self._mean_layout()
        if theta.shape == (mean.size, 1):
            return mean
        raise ValueError(f"theta must have shape ({full.size}, 1) (casadi_param_values) or "
                         f"({mean.size}, 1) (casadi_mean_param_values), got {theta.shape}")

    def _standardizer_blocks(self) -> list[tuple[str, np.ndarray]]:
        s = self.standardizer_
        assert s is not None
        return [("z_mean", s.z_mean), ("z_std", s.z_std), ("y_mean", s.y_mean), ("y_std", s.y_std)]

    def _reset_layout(self) -> None:
        self._layout_cache = None
        self._mean_layout_cache = None

    # ------------------------------------------------------------------ public API
    def predict(
        self, Z: np.ndarray, return_std: bool = False
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """Predictive mean (and standard deviation) of every output.

        Args:
            Z: (N, d_in) query inputs.
            return_std: also return the predictive standard deviation (noise included).

        Returns:
            mean (N, d_out), and std (N, d_out) if ``return_std``.
        """
        self._check_fitted()
        Z = check_inputs(Z, self.n_features_in_)
        s = self.standardizer_
        assert s is not None
        mean_s, var_s = self._predict_std(s.transform_inputs(Z), return_std)
        mean = s.inverse_mean(mean_s)
        if not return_std:
            return mean
        return mean, np.sqrt(var_s) * s.y_std

    def predict_gradient(self, Z: np.ndarray) -> np.ndarray:
        """Jacobian of the predictive mean with respect to the input.

        Args:
            Z: (N, d_in) query inputs.

        Returns:
            (N, d_out, d_in) array ``G[n, i, k] = d mean_i(z_n) / d z_k``.
        """
        self._check_fitted()
        Z = check_inputs(Z, self.n_features_in_)
        s = self.standardizer_
        assert s is not None
        G = self._gradient_std(s.transform_inputs(Z))
        if not s.saturates:
            return G * s.y_std[None, :, None] / s.z_std[None, None, :]
        return G * s.y_std[None, :, None] * s.input_jacobian(Z)[:, None, :]

    def casadi_param_size(self) -> int:
        """Length ``P`` of the CasADi parameter vector (fixed once fitted)."""
        self._check_fitted()
        return self._layout().size

    def casadi_param_values(self, variance: bool = True) -> np.ndarray:
        """(P,) current numeric value of the CasADi parameter vector.

        Args:
            variance: False: the blocks only :meth:`casadi_variance` reads (the inverse
                Cholesky factors, the costliest part to refresh after an update: a triangular
                inverse per output) are left zero, so the vector serves :meth:`casadi_mean`
                only. Same size either way.
        """
        self._check_fitted()
        return self._layout().pack(
            dict(self._standardizer_blocks() + self._casadi_blocks(variance)),
            fill_missing=not variance)

    def casadi_mean_param_size(self) -> int:
        """Length of the mean-only parameter vector (:meth:`casadi_mean_param_values`)."""
        self._check_fitted()
        return self._mean_layout().size

    def casadi_mean_param_values(self) -> np.ndarray:
        """The mean-only parameter vector: :meth:`casadi_param_values` without the blocks only
        the variance reads (the inverse Cholesky factors: on the quadrotor's learner 109,350
        of 120,760 numbers), for :meth:`casadi_mean` and :meth:`casadi_mean_batch`, which take
        either vector (told apart by size)."""
        self._check_fitted()
        return self._mean_layout().pack(dict(self._standardizer_blocks()
                                             + self._casadi_blocks(variance=False)))

    def _sym_outputs(self, z: ca.SX | ca.MX, theta: ca.SX | ca.MX, variance: bool) -> ca.SX | ca.MX:
        self._check_fitted()
        layout = self._layout_for(theta)
        zs = sym_standardize(z, layout.unpack(theta, "z_mean"), layout.unpack(theta, "z_std"),
                             self.standardizer_.input_saturation)
        return self._sym_rows(theta, variance,
                              lambda j: self._sym_mean_var(zs, theta, j, variance))

    def _sym_rows(self, theta: ca.SX | ca.MX, variance: bool,
                  output: Callable[[int], tuple[Any, Any]]) -> ca.SX | ca.MX:
        """Every output's mean (or variance) in the data's units, stacked: ``output(j)`` gives
        output ``j``'s standardized mean and variance."""
        layout = self._layout_for(theta)
        y_mean = layout.unpack(theta, "y_mean")
        y_std = layout.unpack(theta, "y_std")
        rows = []
        for j in range(self.n_outputs_):
            m, v = output(j)
            rows.append(y_std[j] ** 2 * v if variance else y_mean[j] + y_std[j] * m)
        return ca.vertcat(*rows)

    def casadi_mean_batch(self, Z: ca.MX, theta: ca.MX) -> ca.MX:
        """Predictive mean at every column of ``Z`` (d_in, M) as one MX expression (d_out, M),
        column k equal to ``casadi_mean(Z[:, k], theta)``: for functions evaluated at many
        points per call (a compiled MPC step), where matrix operations are much cheaper than
        one scalar expression graph per point."""
        return self._sym_outputs_batch(Z, theta, variance=False)

    def casadi_variance_batch(self, Z: ca.MX, theta: ca.MX) -> ca.MX:
        """:meth:`casadi_variance` at every column of ``Z`` (d_in, M): (d_out, M)."""
        return self._sym_outputs_batch(Z, theta, variance=True)

    def _sym_outputs_batch(self, Z: ca.MX, theta: ca.MX, variance: bool) -> ca.MX:
        self._check_fitted()
        d, M = self.n_features_in_, Z.shape[1]
        if Z.shape[0] != d:
            raise ValueError(f"Z must have {d} rows (one column per point), got {Z.shape}")
        layout = self._layout_for(theta)
        Zs = sym_saturate((Z - ca.repmat(layout.unpack(theta, "z_mean"), 1, M)) / ca.repmat(
            layout.unpack(theta, "z_std"), 1, M), self.standardizer_.input_saturation)
        return self._sym_rows(theta, variance,
                              lambda j: self._sym_mean_var_batch(Zs, theta, j, variance))

    def casadi_mean_gradient_batch(self, Z: ca.MX, theta: ca.MX) -> tuple[ca.MX, list[ca.MX]]:
        """:meth:`casadi_mean_batch` and its gradient in the inputs at every column of ``Z``
        (d_in, M), as matrix operations: the mean (d_out, M) and, per output j, the (d_in, M)
        matrix whose column k is ``d mean_j / d z`` at column k (column k of the mean depends
        on column k of ``Z`` only), equal to :meth:`predict_gradient`. Learners with an
        analytic gradient (:meth:`_sym_mean_grad_batch`) give it without automatic
        differentiation; the others by reverse-mode AD of :meth:`casadi_mean_batch`."""
        self._check_fitted()
        d, M = self.n_features_in_, Z.shape[1]
        if Z.shape[0] != d:
            raise ValueError(f"Z must have {d} rows (one column per point), got {Z.shape}")
        layout = self._layout_for(theta)
        V = (Z - ca.repmat(layout.unpack(theta, "z_mean"), 1, M)) / ca.repmat(
            layout.unpack(theta, "z_std"), 1, M)
        saturation = self.standardizer_.input_saturation
        if np.isfinite(saturation):  # Zs = s tanh(V / s), dZs/dZ = (1 - tanh^2) / z_std
            t = ca.tanh(V / saturation)
            Zs, dzs = saturation * t, (1.0 - t * t) / ca.repmat(
                layout.unpack(theta, "z_std"), 1, M)
        else:
            Zs, dzs = V, 1.0 / ca.repmat(layout.unpack(theta, "z_std"), 1, M)
        y_mean, y_std = layout.unpack(theta, "y_mean"), layout.unpack(theta, "y_std")
        rows, grads = [], []
        for j in range(self.n_outputs_):
            pair = self._sym_mean_grad_batch(Zs, theta, j)
            if pair is None:  # reverse-mode AD of the standardized mean
                Zsym, tsym = ca.MX.sym("Zs", d, M), ca.MX.sym("theta", theta.shape[0])
                m = self._sym_mean_var_batch(Zsym, tsym, j, False)[0]
                pair = tuple(ca.Function("mean_grad", [Zsym, tsym],
                                         [m, ca.gradient(ca.sum2(m), Zsym)])(Zs, theta))
            m, g = pair
            rows.append(y_mean[j] + y_std[j] * m)
            grads.append(y_std[j] * g * dzs)
        return ca.vertcat(*rows), grads

    def _sym_mean_grad_batch(self, Zs: ca.MX, theta: ca.MX, j: int
                             ) -> tuple[ca.MX, ca.MX] | None:
        """Output ``j``'s standardized mean (1, M) at the standardized columns ``Zs`` (d_in, M)
        and its analytic gradient in them (d_in, M); None (the default): not available, AD."""
        return None

    def casadi_mean(self, z: ca.SX | ca.MX, theta: ca.SX | ca.MX) -> ca.SX | ca.MX:
        """Predictive mean as a CasADi expression.

        Args:
            z: (d_in, 1) symbolic input (SX or MX).
            theta: (P, 1) symbolic parameters, numerically ``casadi_param_values()``.

        Returns:
            (d_out, 1) expression equal to ``predict(z.T)[0]``.
        """
        return self._sym_outputs(z, theta, variance=False)

    def casadi_variance(self, z: ca.SX | ca.MX, theta: ca.SX | ca.MX) -> ca.SX | ca.MX:
        """Predictive variance (noise included) as a CasADi expression.

        Args:
            z: (d_in, 1) symbolic input (SX or MX).
            theta: (P, 1) symbolic parameters, numerically ``casadi_param_values()``.

        Returns:
            (d_out, 1) expression equal to ``predict(z.T, return_std=True)[1][0] ** 2``.
        """
        return self._sym_outputs(z, theta, variance=True)


def mean_gradient_batch(learner: Any, Z: ca.MX, theta: ca.MX) -> tuple[ca.MX, list[ca.MX]]:
    """``learner.casadi_mean_gradient_batch(Z, theta)``, or for a learner without it (one with
    only ``casadi_mean_batch``) the same by reverse-mode AD: the mean (d_out, M) at the columns
    of ``Z`` (d_in, M) and per output the (d_in, M) gradients."""
    method = getattr(learner, "casadi_mean_gradient_batch", None)
    if method is not None:
        return method(Z, theta)
    Zsym, tsym = ca.MX.sym("Z", *Z.shape), ca.MX.sym("theta", theta.shape[0])
    mean = learner.casadi_mean_batch(Zsym, tsym)
    grads = [ca.gradient(ca.sum2(mean[j, :]), Zsym) for j in range(mean.shape[0])]
    out = ca.Function("mean_grad", [Zsym, tsym], [mean, *grads])(Z, theta)
    return out[0], list(out[1:])
