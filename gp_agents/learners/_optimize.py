"""Multi-start L-BFGS-B minimization of a negative log marginal likelihood."""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np
from scipy.linalg import LinAlgError
from scipy.optimize import minimize

__all__ = ["minimize_multistart"]


def minimize_multistart(
    fun: Callable[[np.ndarray], tuple[float, np.ndarray]],
    starts: list[np.ndarray],
    bounds: list[tuple[float, float]],
    max_iter: int,
) -> tuple[np.ndarray, float]:
    """Run L-BFGS-B (analytic gradient) from every start and keep the best end point.

    Args:
        fun: ``theta -> (value, gradient)``; may raise ``LinAlgError`` for a bad ``theta``.
        starts: start points, each (p,).
        bounds: p ``(low, high)`` pairs.
        max_iter: iteration cap per run.

    Returns:
        ``(theta_best, value_best)``.

    Raises:
        RuntimeError: if every run failed.
    """
    best_x: np.ndarray | None = None
    best_f = np.inf
    lo = np.array([b[0] for b in bounds])
    hi = np.array([b[1] for b in bounds])
    for x0 in starts:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                res = minimize(
                    fun,
                    np.clip(x0, lo, hi),
                    jac=True,
                    method="L-BFGS-B",
                    bounds=bounds,
                    options={"maxiter": max_iter},
                )
        except (LinAlgError, FloatingPointError, ValueError):
            continue
        if np.isfinite(res.fun) and res.fun < best_f:
            best_x, best_f = np.asarray(res.x, dtype=float), float(res.fun)
    if best_x is None:
        raise RuntimeError("hyperparameter optimization failed from every start point")
    return best_x, best_f
