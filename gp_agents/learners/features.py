"""Random Fourier features of the SE-ARD kernel (paper, Section "Sparse Spectrum Gaussian
Processes"; Lazaro-Gredilla et al. 2010; Rahimi & Recht 2007).

    phi(z) = sigma_s / sqrt(r) [cos(Omega^T z); sin(Omega^T z)],   Omega = W^{-1/2} Omega_0,

with the ``r`` base frequencies ``Omega_0 ~ N(0, I)`` drawn once from a seeded generator, so
``Omega ~ N(0, W^{-1})`` and ``E[phi(z)^T phi(z')] = k(z, z')``. The features are returned row-wise:
``F = Phi^T`` with shape (N, 2r).
"""

from __future__ import annotations

import numpy as np

__all__ = ["draw_base_frequencies", "fourier_features", "fourier_mean_grad", "scale_frequencies"]


def draw_base_frequencies(
    d_out: int, d_in: int, n_frequencies: int, random_state: int | np.random.Generator | None
) -> np.ndarray:
    """Standard-normal base frequencies ``Omega_0``.

    Returns:
        (d_out, d_in, r) array, one independent draw per output GP.
    """
    rng = np.random.default_rng(random_state)
    return rng.standard_normal((d_out, d_in, n_frequencies))


def scale_frequencies(base: np.ndarray, length_scales: np.ndarray) -> np.ndarray:
    """``Omega = diag(1 / ell) Omega_0`` for one output: (d_in, r), (d_in,) -> (d_in, r)."""
    return base / length_scales[:, None]


def fourier_features(Z: np.ndarray, omega: np.ndarray, signal_std: float) -> np.ndarray:
    """Feature matrix ``F = Phi^T``.

    Args:
        Z: (N, d_in) standardized inputs.
        omega: (d_in, r) frequencies.
        signal_std: ``sigma_s``.

    Returns:
        (N, 2r) rows ``phi(z_n)^T = sigma_s / sqrt(r) [cos(z_n^T Omega), sin(z_n^T Omega)]``.
    """
    U = Z @ omega
    c = signal_std / np.sqrt(max(omega.shape[1], 1))  # no Fourier features: r = 0
    return c * np.concatenate([np.cos(U), np.sin(U)], axis=1)


def fourier_mean_grad(
    Z: np.ndarray, omega: np.ndarray, signal_std: float, weights: np.ndarray
) -> np.ndarray:
    """Gradient of ``m(z) = w^T phi(z)`` with respect to ``z``.

    Args:
        Z: (N, d_in) standardized inputs.
        omega: (d_in, r) frequencies.
        signal_std: ``sigma_s``.
        weights: (2r,) ``w``.

    Returns:
        (N, d_in) gradients ``c (-w_c sin(U) + w_s cos(U)) Omega^T``.
    """
    r = omega.shape[1]
    U = Z @ omega
    c = signal_std / np.sqrt(max(r, 1))
    H = c * (np.cos(U) * weights[r:] - np.sin(U) * weights[:r])
    return H @ omega.T
