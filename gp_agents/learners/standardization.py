"""Affine input/output standardization used by every learner.

The GPs of the paper (Section "Gaussian Processes") are zero-mean with a stationary kernel; they
are fitted on ``z_s = (z - z_mean) / z_std`` and ``y_s = (y - y_mean) / y_std`` so that one set of
hyperparameter bounds fits every problem. Predictions are mapped back to the original units.

*Input saturation* (``input_saturation = s < inf``): the standardized inputs are passed through
``sat(z_s) = s tanh(z_s / s)``, the identity to within 1% for ``|z_s| < s / 6`` and bounded by
``s``. A learner then treats a query far outside its data (a plan at the corner of the control
box, many standard deviations from the initial data) as one at ``s`` standard deviations: its
linear features stop growing there and its Jacobian decays, instead of extrapolating a slope
fitted on a small region across the whole box. ``s = inf`` is the plain affine map.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Standardizer", "check_input_saturation"]

_MIN_STD = 1e-12


def check_input_saturation(value: float | None) -> float:
    """``value`` as the saturation level ``s`` (``None`` -> ``inf``, no saturation); raises
    ``ValueError`` unless it is positive (``inf`` allowed) and not NaN."""
    s = np.inf if value is None else float(value)
    if not s > 0.0:  # also rejects NaN
        raise ValueError(f"input_saturation must be positive (or None / inf), got {value!r}")
    return s


@dataclass(frozen=True)
class Standardizer:
    """Per-column affine maps of the inputs and outputs.

    Attributes:
        z_mean: (d_in,) input offsets.
        z_std: (d_in,) input scales (> 0).
        y_mean: (d_out,) output offsets.
        y_std: (d_out,) output scales (> 0).
        input_saturation: ``s`` of the saturation ``s tanh(z_s / s)`` of the standardized
            inputs (module docstring); ``inf``: none.
    """

    z_mean: np.ndarray
    z_std: np.ndarray
    y_mean: np.ndarray
    y_std: np.ndarray
    input_saturation: float = np.inf

    def __post_init__(self) -> None:
        object.__setattr__(self, "input_saturation", check_input_saturation(
            self.input_saturation))

    @property
    def saturates(self) -> bool:
        """Whether the standardized inputs are saturated (``input_saturation < inf``)."""
        return bool(np.isfinite(self.input_saturation))

    @classmethod
    def fit(cls, Z: np.ndarray, Y: np.ndarray, enabled: bool = True,
            input_saturation: float = np.inf) -> Standardizer:
        """Column means and standard deviations of ``Z`` (N, d_in) and ``Y`` (N, d_out).

        Columns with (near) zero spread get scale 1. With ``enabled=False`` the affine maps are
        the identity (a saturation still applies to the inputs).
        """
        d_in, d_out = Z.shape[1], Y.shape[1]
        if not enabled:
            return cls(np.zeros(d_in), np.ones(d_in), np.zeros(d_out), np.ones(d_out),
                       input_saturation)

        def _std(a: np.ndarray) -> np.ndarray:
            s = a.std(axis=0)
            scale = np.maximum(np.abs(a).max(axis=0), 1.0)
            return np.where(s > _MIN_STD * scale, s, 1.0)

        return cls(Z.mean(axis=0), _std(Z), Y.mean(axis=0), _std(Y), input_saturation)

    def transform_inputs(self, Z: np.ndarray) -> np.ndarray:
        """(N, d_in) original inputs -> standardized (and, if set, saturated) inputs."""
        Zs = (Z - self.z_mean) / self.z_std
        if not self.saturates:
            return Zs
        s = self.input_saturation
        return s * np.tanh(Zs / s)

    def input_jacobian(self, Z: np.ndarray) -> np.ndarray:
        """(N, d_in) diagonal of ``d transform_inputs(z) / d z`` at each row of ``Z`` (N, d_in):
        ``sech^2(z_s / s) / z_std`` (``1 / z_std`` without saturation)."""
        if not self.saturates:
            return np.broadcast_to(1.0 / self.z_std, np.shape(Z)).copy()
        t = np.tanh((Z - self.z_mean) / self.z_std / self.input_saturation)
        return (1.0 - t * t) / self.z_std

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
            "std_input_saturation": np.array(self.input_saturation),
        }

    @classmethod
    def from_arrays(cls, data: dict[str, np.ndarray]) -> Standardizer:
        """Inverse of :meth:`to_arrays`."""
        return cls(
            np.asarray(data["std_z_mean"], dtype=float),
            np.asarray(data["std_z_std"], dtype=float),
            np.asarray(data["std_y_mean"], dtype=float),
            np.asarray(data["std_y_std"], dtype=float),
            float(data.get("std_input_saturation", np.inf)),
        )
