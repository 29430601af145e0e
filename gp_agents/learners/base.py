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
from typing import Any

import casadi as ca
import numpy as np

from ._validation import NotFittedError, check_inputs
from .casadi_export import ParamLayout, sym_standardize
from .hyperparameters import GPHyperparameters
from .standardization import Standardizer

__all__ = ["BaseGPLearner"]


class BaseGPLearner(ABC):
    """Shared prediction / export logic. Fitted attributes end with an underscore."""

    standardizer_: Standardizer | None = None
    hyperparameters_: GPHyperparameters | None = None
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
    def _casadi_blocks(self) -> list[tuple[str, np.ndarray]]:
        """Learner-specific ``(name, value)`` blocks of the CasADi parameter vector."""

    def _casadi_block_shapes(self) -> list[tuple[str, tuple[int, ...]]]:
        """Shapes of :meth:`_casadi_blocks` (override when the values are costly)."""
        return [(name, np.shape(v)) for name, v in self._casadi_blocks()]

    @abstractmethod
    def _sym_mean_var(
        self, zs: ca.SX | ca.MX, theta: ca.SX | ca.MX, j: int, variance: bool
    ) -> tuple[ca.SX | ca.MX, ca.SX | ca.MX | None]:
        """Standardized mean and (optionally) variance of output ``j`` as CasADi scalars."""

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

    def _standardizer_blocks(self) -> list[tuple[str, np.ndarray]]:
        s = self.standardizer_
        assert s is not None
        return [("z_mean", s.z_mean), ("z_std", s.z_std), ("y_mean", s.y_mean), ("y_std", s.y_std)]

    def _reset_layout(self) -> None:
        self._layout_cache = None

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
        return G * s.y_std[None, :, None] / s.z_std[None, None, :]

    def casadi_param_size(self) -> int:
        """Length ``P`` of the CasADi parameter vector (fixed once fitted)."""
        self._check_fitted()
        return self._layout().size

    def casadi_param_values(self) -> np.ndarray:
        """(P,) current numeric value of the CasADi parameter vector."""
        self._check_fitted()
        return self._layout().pack(dict(self._standardizer_blocks() + self._casadi_blocks()))

    def _sym_outputs(self, z: ca.SX | ca.MX, theta: ca.SX | ca.MX, variance: bool) -> ca.SX | ca.MX:
        self._check_fitted()
        layout = self._layout()
        zs = sym_standardize(z, layout.unpack(theta, "z_mean"), layout.unpack(theta, "z_std"))
        y_mean = layout.unpack(theta, "y_mean")
        y_std = layout.unpack(theta, "y_std")
        rows = []
        for j in range(self.n_outputs_):
            m, v = self._sym_mean_var(zs, theta, j, variance)
            rows.append(y_std[j] ** 2 * v if variance else y_mean[j] + y_std[j] * m)
        return ca.vertcat(*rows)

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
