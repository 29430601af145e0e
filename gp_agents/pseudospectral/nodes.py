"""Legendre-Gauss nodes, quadrature weights, barycentric interpolation and differentiation.

Paper section "Gauss Pseudospectral Optimal Control" (subsections "Collocation Point Search",
"State, Control, and Costate Approximation", "Integral Approximation via Gauss Quadrature" and
"Algebraic Representation of Dynamics"). The printed formulas have typos (e.g. the sum index of the
differentiation equation, see reference errata note 5); this module follows the standard LG
method of Benson et al. (2006) and Garg et al. (2010):

* the K collocation nodes ``tau_1 < ... < tau_K`` are the roots of the Legendre polynomial P_K;
* the state is interpolated by a degree-K polynomial over the K + 1 *support points*
  ``{tau_0 = -1, tau_1, ..., tau_K}``; the control only over the K nodes;
* the (K, K+1) differentiation matrix ``D`` maps the state at the support points to its
  derivative at the nodes: ``Xdot(tau_k) = sum_{i=0..K} D[k-1, i] X(tau_i)``.

All interpolation is done in the numerically stable barycentric form (Berrut & Trefethen 2004),
so node counts of K = 60 and more are fine. Everything here is pure numpy/scipy on the
reference interval ``tau in [-1, 1]`` (dimensionless).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import eigh_tridiagonal

__all__ = [
    "barycentric_weights",
    "differentiation_matrix",
    "interpolation_matrix",
    "lagrange_interpolate",
    "legendre_gauss",
    "legendre_polynomial",
    "support_points",
]

FloatArray = NDArray[np.float64]


def _check_order(K: int) -> int:
    if isinstance(K, bool) or not isinstance(K, (int, np.integer)):
        raise ValueError(f"the number of nodes K must be an integer, got {K!r}")
    if K < 1:
        raise ValueError(f"the number of nodes K must be >= 1, got {K}")
    return int(K)


def legendre_polynomial(K: int, tau: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Evaluate the Legendre polynomial P_K and its derivative by the three-term recurrence.

    Paper eq. (LG) defines P_K by Rodrigues' formula; the recurrence
    ``(n+1) P_{n+1} = (2n+1) tau P_n - n P_{n-1}`` is the stable way to evaluate it.

    Args:
        K: polynomial degree, >= 0.
        tau: evaluation points, any shape (dimensionless, usually in [-1, 1]).

    Returns:
        ``(P_K(tau), P_K'(tau))``, both with the shape of ``tau``.
    """
    x = np.asarray(tau, dtype=float)
    p_prev = np.ones_like(x)
    if K == 0:
        return p_prev, np.zeros_like(x)
    p = x.copy()
    dp_prev = np.zeros_like(x)
    dp = np.ones_like(x)
    for n in range(1, K):
        p_next = ((2 * n + 1) * x * p - n * p_prev) / (n + 1)
        # derivative of the recurrence: (n+1) P'_{n+1} = (2n+1)(P_n + x P'_n) - n P'_{n-1}
        dp_next = ((2 * n + 1) * (p + x * dp) - n * dp_prev) / (n + 1)
        p_prev, p = p, p_next
        dp_prev, dp = dp, dp_next
    return p, dp


@lru_cache(maxsize=64)
def _legendre_gauss_cached(K: int) -> tuple[bytes, bytes]:
    # Golub-Welsch: the nodes are the eigenvalues of the symmetric Jacobi matrix of the
    # Legendre recurrence (zero diagonal, off-diagonal n / sqrt(4 n^2 - 1)).
    n = np.arange(1, K, dtype=float)
    offdiag = n / np.sqrt(4.0 * n * n - 1.0)
    tau = eigh_tridiagonal(np.zeros(K), offdiag, eigvals_only=True)
    # Two Newton steps on P_K polish the eigenvalues to full double precision.
    for _ in range(2):
        p, dp = legendre_polynomial(K, tau)
        tau = tau - p / dp
    tau = np.sort(tau)
    # Symmetrise (the LG points are symmetric about 0) to remove round-off asymmetry.
    tau = 0.5 * (tau - tau[::-1])
    _, dp = legendre_polynomial(K, tau)
    # Paper eq. (qweight): w_i = 2 / ((1 - tau_i^2) P_K'(tau_i)^2).
    w = 2.0 / ((1.0 - tau * tau) * dp * dp)
    w = 0.5 * (w + w[::-1])
    return tau.tobytes(), w.tobytes()


def legendre_gauss(K: int) -> tuple[FloatArray, FloatArray]:
    """Legendre-Gauss (LG) nodes and quadrature weights on [-1, 1].

    The nodes are the K roots of P_K (paper eq. LG), in increasing order, all strictly inside
    (-1, 1); the weights are paper eq. (qweight). The rule integrates polynomials of degree
    <= 2K - 1 exactly: ``int_{-1}^{1} q(tau) dtau = sum_k w_k q(tau_k)``.

    Args:
        K: number of nodes, >= 1.

    Returns:
        ``(nodes, weights)``, each of shape (K,), dimensionless; ``weights.sum() == 2``.
    """
    K = _check_order(K)
    tau_b, w_b = _legendre_gauss_cached(K)
    return np.frombuffer(tau_b).copy(), np.frombuffer(w_b).copy()


def support_points(K: int) -> FloatArray:
    """State support points of the LG method: ``[-1, tau_1, ..., tau_K]``, shape (K + 1,)."""
    tau, _ = legendre_gauss(K)
    return np.concatenate(([-1.0], tau))


def barycentric_weights(points: ArrayLike) -> FloatArray:
    """Barycentric weights ``b_j = 1 / prod_{i != j} (x_j - x_i)`` of distinct points.

    The weights are computed in log-magnitude form and normalised to max |b_j| = 1 (the scale
    cancels in every barycentric formula), so they neither overflow nor underflow for many
    points.

    Args:
        points: distinct interpolation points, shape (N,).

    Returns:
        Weights, shape (N,).
    """
    x = np.asarray(points, dtype=float).ravel()
    diff = x[:, None] - x[None, :]
    np.fill_diagonal(diff, 1.0)
    if np.any(diff == 0.0):
        raise ValueError("interpolation points must be distinct")
    log_mag = -np.sum(np.log(np.abs(diff)), axis=1)
    sign = np.prod(np.sign(diff), axis=1)
    return sign * np.exp(log_mag - log_mag.max())


def _differentiation_matrix_full(points: FloatArray) -> FloatArray:
    b = barycentric_weights(points)
    diff = points[:, None] - points[None, :]
    np.fill_diagonal(diff, 1.0)
    D = (b[None, :] / b[:, None]) / diff
    np.fill_diagonal(D, 0.0)
    # Negative-sum trick: rows of D annihilate constants exactly.
    np.fill_diagonal(D, -D.sum(axis=1))
    return D


@lru_cache(maxsize=64)
def _differentiation_matrix_cached(K: int) -> bytes:
    D = _differentiation_matrix_full(support_points(K))[1:, :]
    return D.tobytes()


def differentiation_matrix(K: int) -> FloatArray:
    """LG differentiation matrix, shape (K, K + 1) (paper eq. Diff, corrected).

    Row ``k - 1`` holds the derivatives of the K + 1 Lagrange basis polynomials built on the
    support points ``{-1, tau_1..tau_K}``, evaluated at node ``tau_k``. For any polynomial q of
    degree <= K, ``D @ q(support_points(K)) == q'(nodes)`` to round-off. Each row sums to 0.
    Derivatives are with respect to tau; multiply by ``2 / (tf - t0)`` for time derivatives.

    Args:
        K: number of LG nodes, >= 1.

    Returns:
        D, shape (K, K + 1).
    """
    K = _check_order(K)
    return np.frombuffer(_differentiation_matrix_cached(K)).reshape(K, K + 1).copy()


def interpolation_matrix(points: ArrayLike, tau: ArrayLike) -> FloatArray:
    """Matrix of Lagrange basis polynomials of ``points`` evaluated at ``tau``.

    Uses the second (true) barycentric formula; an evaluation point that coincides with an
    interpolation point gets the exact unit row. Evaluation outside the hull of ``points`` is
    polynomial extrapolation.

    Args:
        points: distinct interpolation points, shape (N,).
        tau: evaluation points, shape (M,) (a scalar is treated as shape (1,)).

    Returns:
        L, shape (M, N), with ``L[m, j] = ell_j(tau[m])``; rows sum to 1.
    """
    x = np.asarray(points, dtype=float).ravel()
    t = np.atleast_1d(np.asarray(tau, dtype=float)).ravel()
    b = barycentric_weights(x)
    diff = t[:, None] - x[None, :]
    exact = diff == 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = b[None, :] / diff
        L = terms / terms.sum(axis=1, keepdims=True)
    rows = exact.any(axis=1)
    if rows.any():
        L[rows] = exact[rows].astype(float)
    return L


def lagrange_interpolate(points: ArrayLike, values: ArrayLike, tau: ArrayLike) -> FloatArray:
    """Evaluate the Lagrange interpolant of ``values`` given at ``points``.

    Args:
        points: distinct interpolation points, shape (N,).
        values: data, shape (N,) or (N, d).
        tau: evaluation points, shape (M,).

    Returns:
        Interpolated values, shape (M,) or (M, d).
    """
    return interpolation_matrix(points, tau) @ np.asarray(values, dtype=float)
