"""Export of learned means and variances as CasADi expressions with a flat parameter vector.

Every learner exposes the contract used by the MPC (paper, Section "Gauss Pseudospectral Optimal
Control": the GP residual enters the collocation defects)::

    theta_val = learner.casadi_param_values()         # (P,) numpy, refreshed after every update
    P = learner.casadi_param_size()                   # fixed once fitted
    mean = learner.casadi_mean(z, theta)              # (d_out, 1) casadi expression
    var = learner.casadi_variance(z, theta)           # (d_out, 1) casadi expression

``theta`` is a symbolic (P, 1) vector (SX or MX); all data-dependent arrays are sliced out of it
according to a :class:`ParamLayout`, so a solver built once keeps working after the data change.
Matrices are packed column-major, matching ``casadi.reshape``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import casadi as ca
import numpy as np

__all__ = [
    "ParamLayout",
    "sym_fourier_features",
    "sym_saturate",
    "sym_se_ard_mean_var",
    "sym_standardize",
]


class ParamLayout:
    """Named blocks of a flat parameter vector.

    Args:
        blocks: sequence of ``(name, shape)`` with shape ``(n,)`` or ``(n, m)``.
    """

    def __init__(self, blocks: Sequence[tuple[str, tuple[int, ...]]]) -> None:
        self._blocks: dict[str, tuple[int, tuple[int, ...]]] = {}
        offset = 0
        for name, shape in blocks:
            if name in self._blocks:
                raise ValueError(f"duplicate block {name!r}")
            if len(shape) not in (1, 2):
                raise ValueError(f"block {name!r}: shape must be 1-D or 2-D, got {shape}")
            self._blocks[name] = (offset, tuple(int(s) for s in shape))
            offset += int(np.prod(shape))
        self.size = offset

    def pack(self, values: Mapping[str, np.ndarray], fill_missing: bool = False) -> np.ndarray:
        """Flatten ``values`` (one array per block, exact shapes) into a (P,) vector.

        Args:
            values: block name -> array.
            fill_missing: leave blocks absent from ``values`` zero instead of raising.
        """
        out = np.zeros(self.size)
        missing = set(self._blocks) - set(values)
        if missing and not fill_missing:
            raise ValueError(f"missing blocks {sorted(missing)}")
        for name, (off, shape) in self._blocks.items():
            if name in missing:
                continue
            a = np.asarray(values[name], dtype=float)
            if a.shape != shape:
                raise ValueError(f"block {name!r}: expected shape {shape}, got {a.shape}")
            out[off : off + a.size] = a.ravel(order="F")
        return out

    def unpack(self, theta: ca.SX | ca.MX, name: str) -> ca.SX | ca.MX:
        """Symbolic block ``name`` of ``theta`` ((P, 1)); 1-D blocks come back as columns."""
        if theta.shape != (self.size, 1):
            raise ValueError(f"theta must have shape ({self.size}, 1), got {theta.shape}")
        off, shape = self._blocks[name]
        n = int(np.prod(shape))
        block = theta[off : off + n]
        if len(shape) == 1:
            return block
        return ca.reshape(block, shape[0], shape[1])


def _check_z(z: ca.SX | ca.MX, d_in: int) -> None:
    if z.shape != (d_in, 1):
        raise ValueError(f"z must have shape ({d_in}, 1), got {z.shape}")


def sym_saturate(zs: ca.SX | ca.MX, saturation: float) -> ca.SX | ca.MX:
    """``s tanh(zs / s)`` elementwise (:class:`~gp_agents.learners.Standardizer`'s input
    saturation); ``zs`` itself for ``s = inf``."""
    if not np.isfinite(saturation):
        return zs
    return saturation * ca.tanh(zs / saturation)


def sym_standardize(z: ca.SX | ca.MX, z_mean: ca.SX | ca.MX, z_std: ca.SX | ca.MX,
                    saturation: float = np.inf) -> ca.SX | ca.MX:
    """``(z - z_mean) / z_std`` for column vectors (d_in, 1), then saturated at ``saturation``
    standard deviations (:func:`sym_saturate`)."""
    _check_z(z, z_mean.shape[0])
    return sym_saturate((z - z_mean) / z_std, saturation)


def sym_se_ard_mean_var(
    zs: ca.SX | ca.MX,
    Zs: ca.SX | ca.MX,
    alpha: ca.SX | ca.MX,
    inv_ls: ca.SX | ca.MX,
    sf: ca.SX | ca.MX,
    sn: ca.SX | ca.MX,
    Linv: ca.SX | ca.MX | None,
) -> tuple[ca.SX | ca.MX, ca.SX | ca.MX | None]:
    """Exact-GP predictive mean and noisy predictive variance at one standardized point.

    Args:
        zs: (d, 1) standardized query.
        Zs: (N, d) standardized training inputs.
        alpha: (N, 1) ``K_y^{-1} y``.
        inv_ls: (d, 1) ``1 / ell``.
        sf, sn: scalars ``sigma_s``, ``sigma_n``.
        Linv: (N, N) inverse of the lower Cholesky factor of ``K_y``, or ``None`` to skip the
            variance.

    Returns:
        ``(mean, var)`` scalars in standardized units; ``var = sigma_n^2 + max(sigma_s^2 -
        |L^{-1} k|^2, 0)``.
    """
    n = Zs.shape[0]
    diff = (Zs - ca.repmat(zs.T, n, 1)) * ca.repmat(inv_ls.T, n, 1)
    k = sf**2 * ca.exp(-0.5 * ca.sum2(diff**2))  # (N, 1)
    mean = ca.dot(k, alpha)
    if Linv is None:
        return mean, None
    v = ca.mtimes(Linv, k)
    var = sn**2 + ca.fmax(sf**2 - ca.sumsqr(v), 0.0)
    return mean, var


def sym_fourier_features(
    zs: ca.SX | ca.MX, omega: ca.SX | ca.MX, sf: ca.SX | ca.MX
) -> ca.SX | ca.MX:
    """``phi(z) = sigma_s / sqrt(r) [cos(Omega^T z); sin(Omega^T z)]`` as a (2r, 1) column.

    Args:
        zs: (d, 1) standardized query.
        omega: (d, r) frequencies.
        sf: scalar ``sigma_s``.
    """
    r = omega.shape[1]
    u = ca.mtimes(omega.T, zs)
    return (sf / np.sqrt(max(r, 1))) * ca.vertcat(ca.cos(u), ca.sin(u))
