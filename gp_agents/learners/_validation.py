"""Input checking shared by the learners (shapes, finiteness, fitted state)."""

from __future__ import annotations

import numpy as np

__all__ = ["NotFittedError", "check_inputs", "check_training_data"]


class NotFittedError(ValueError):
    """Raised when a learner is used before :meth:`fit` (scikit-learn convention)."""


def _as_2d_float(name: str, a: object) -> np.ndarray:
    try:
        arr = np.asarray(a, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name} must be a numeric array, got {type(a).__name__}") from exc
    if arr.ndim != 2:
        raise ValueError(f"{name} must be a 2-D array (N, d), got shape {arr.shape}")
    return arr


def check_inputs(Z: object, d_in: int | None = None, name: str = "Z") -> np.ndarray:
    """Validate an input matrix.

    Args:
        Z: (N, d_in) inputs.
        d_in: required number of columns, or ``None`` to accept any.
        name: name used in error messages.

    Returns:
        (N, d_in) float64 array (a copy only when a conversion was needed).

    Raises:
        ValueError: wrong rank or width, zero rows, or non-finite entries.
    """
    arr = _as_2d_float(name, Z)
    if arr.shape[0] == 0:
        raise ValueError(f"{name} has zero rows; at least one sample is required")
    if arr.shape[1] == 0:
        raise ValueError(f"{name} has zero columns")
    if d_in is not None and arr.shape[1] != d_in:
        raise ValueError(f"{name} has {arr.shape[1]} columns, the learner expects {d_in}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} contains NaN or infinite values")
    return arr


def check_training_data(
    Z: object, Y: object, d_in: int | None = None, d_out: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Validate a training set.

    Args:
        Z: (N, d_in) inputs.
        Y: (N, d_out) targets.
        d_in, d_out: required widths, or ``None`` to accept any.

    Returns:
        ``(Z, Y)`` as float64 arrays.

    Raises:
        ValueError: wrong ranks or widths, mismatched N, zero rows, non-finite entries.
    """
    Z = check_inputs(Z, d_in, "Z")
    Y = check_inputs(Y, d_out, "Y")
    if Z.shape[0] != Y.shape[0]:
        raise ValueError(f"Z has {Z.shape[0]} rows but Y has {Y.shape[0]}")
    return Z, Y
