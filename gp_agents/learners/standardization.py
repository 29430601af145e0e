"""Affine input/output standardization used by every learner.

The GPs of the paper (Section "Gaussian Processes") are zero-mean with a stationary kernel; they
are fitted on ``z_s = (z - z_mean) / z_std`` and ``y_s = (y - y_mean) / y_std`` so that one set of
hyperparameter bounds fits every problem. Predictions are mapped back to the original units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Standardizer"]

_MIN_STD = 1e-12


@dataclass(frozen=True)
class Standardizer:
    """Per-column affine maps of the inputs and outputs.

    Attributes:
        z_mean: (d_in,) input offsets.
        z_std: (d_in,) input scales (> 0).
        y_mean: (d_out,) output offsets.
        y_std: (d_out,) output scales (> 0).
    """

    z_mean: np.ndarray
    z_std: np.ndarray
    y_mean: np.ndarray
    y_std: np.ndarray

    @classmethod
    def fit(cls, Z: np.ndarray, Y: np.ndarray, enabled: bool = True) -> Standardizer:
        """Column means and standard deviations of ``Z`` (N, d_in) and ``Y`` (N, d_out).

        Columns with (near) zero spread get scale 1. With ``enabled=False`` the map is the
        identity.
        """
        d_in, d_out = Z.shape[1], Y.shape[1]
        if not enabled:
            return cls(np.zeros(d_in), np.ones(d_in), np.zeros(d_out), np.ones(d_out))

        def _std(a: np.ndarray) -> np.ndarray:
            s = a.std(axis=0)
            scale = np.maximum(np.abs(a).max(axis=0), 1.0)
            return np.where(s > _MIN_STD * scale, s, 1.0)

        return cls(Z.mean(axis=0), _std(Z), Y.mean(axis=0), _std(Y))

    def transform_inputs(self, Z: np.ndarray) -> np.ndarray:
        """(N, d_in) original inputs -> standardized inputs."""
        return (Z - self.z_mean) / self.z_std

    def transform_outputs(self, Y: np.ndarray) -> np.ndarray:
        """(N, d_out) original targets -> standardized targets."""
        return (Y - self.y_mean) / self.y_std

    def inverse_mean(self, M: np.ndarray) -> np.ndarray:
        """(N, d_out) standardized means -> original units."""
        return M * self.y_std + self.y_mean

    def to_arrays(self) -> dict[str, np.ndarray]:
        """Arrays for persistence (keys prefixed ``std_``)."""
        return {
            "std_z_mean": self.z_mean,
            "std_z_std": self.z_std,
            "std_y_mean": self.y_mean,
            "std_y_std": self.y_std,
        }

    @classmethod
    def from_arrays(cls, data: dict[str, np.ndarray]) -> Standardizer:
        """Inverse of :meth:`to_arrays`."""
        return cls(
            np.asarray(data["std_z_mean"], dtype=float),
            np.asarray(data["std_z_std"], dtype=float),
            np.asarray(data["std_y_mean"], dtype=float),
            np.asarray(data["std_y_std"], dtype=float),
        )
