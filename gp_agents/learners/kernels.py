"""Squared-exponential ARD kernel (paper, Section "Gaussian Processes"; Rasmussen & Williams 2006,
Eq. 5.1) and its input gradient.

    k(z, z') = sigma_s^2 exp(-1/2 sum_k (z_k - z'_k)^2 / ell_k^2)
"""

from __future__ import annotations

import numpy as np

__all__ = ["scaled_sq_dist", "se_ard_kernel", "se_ard_kernel_input_grad"]


def scaled_sq_dist(Z1: np.ndarray, Z2: np.ndarray, length_scales: np.ndarray) -> np.ndarray:
    """Squared distances after dividing every input by its length scale.

    Args:
        Z1: (N1, d) inputs.
        Z2: (N2, d) inputs.
        length_scales: (d,) ``ell``.

    Returns:
        (N1, N2) ``sum_k (Z1[i, k] - Z2[j, k])^2 / ell_k^2``.
    """
    # coordinate-wise differences (not |a|^2 + |b|^2 - 2 a.b, which cancels badly near the
    # diagonal and makes the predictive mean noisy at the 1e-10 level)
    d2 = np.zeros((Z1.shape[0], Z2.shape[0]))
    for k in range(Z1.shape[1]):
        diff = Z1[:, k, None] / length_scales[k] - Z2[None, :, k] / length_scales[k]
        d2 += diff * diff
    return d2


def se_ard_kernel(
    Z1: np.ndarray, Z2: np.ndarray, length_scales: np.ndarray, signal_std: float
) -> np.ndarray:
    """Kernel matrix.

    Args:
        Z1: (N1, d) inputs.
        Z2: (N2, d) inputs.
        length_scales: (d,) ``ell``.
        signal_std: ``sigma_s``.

    Returns:
        (N1, N2) ``K[i, j] = k(Z1[i], Z2[j])``.
    """
    return signal_std**2 * np.exp(-0.5 * scaled_sq_dist(Z1, Z2, length_scales))


def se_ard_kernel_input_grad(
    Zq: np.ndarray, Z: np.ndarray, coef: np.ndarray, length_scales: np.ndarray, signal_std: float
) -> np.ndarray:
    """Gradient of ``m(z) = sum_i coef_i k(z, Z_i)`` with respect to ``z``.

    ``d k(z, Z_i) / d z = -k(z, Z_i) (z - Z_i) / ell^2``.

    Args:
        Zq: (M, d) query points.
        Z: (N, d) training inputs.
        coef: (N,) coefficients (e.g. ``alpha = K_y^{-1} y``).
        length_scales: (d,) ``ell``.
        signal_std: ``sigma_s``.

    Returns:
        (M, d) gradients.
    """
    Kq = se_ard_kernel(Zq, Z, length_scales, signal_std) * coef[None, :]  # (M, N)
    # sum_i Kq[m, i] (Z_i - z_m) / ell^2
    return (Kq @ Z - Kq.sum(1)[:, None] * Zq) / length_scales**2
