"""Checks of what a user hands the MPC: observations, actions, initial data, and a learner's
linear-feature columns against the agent's residual."""

from __future__ import annotations

from typing import Any

import numpy as np

from gp_agents.data import Transitions
from gp_agents.residual import ResidualModel
from gp_envs.model import ControlModel

__all__ = ["bind_sensitivity_columns", "checked", "transitions"]


def transitions(data: Any, model: ControlModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``data``'s ``(X, U, X_next)`` checked against ``model`` (see :meth:`PseudospectralMPC.
    pretrain`)."""
    if isinstance(data, Transitions):
        arrays = (data.X, data.U, data.X_next)
    elif isinstance(data, tuple | list) and len(data) == 3:
        arrays = tuple(data)
    else:
        raise TypeError(f"pretrain takes Transitions (gp_agents.collect_initial_data(env, n, "
                        f"seed=...)) or a tuple (X, U, X_next), got {type(data).__name__}")
    n, m = model.n_states, model.n_controls
    out = []
    for name, value, width in zip(("X", "U", "X_next"), arrays, (n, m, n), strict=True):
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise TypeError(f"pretrain: {name} must be an array of numbers") from None
        if arr.ndim != 2 or arr.shape[1] != width:
            raise ValueError(f"pretrain: {name} must have shape (N, {width}) for the "
                             f"{model.name} model, got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"pretrain: {name} has non-finite values")
        out.append(arr)
    if out[0].shape[0] < 1:
        raise ValueError("pretrain needs at least one transition, got none")
    if not out[0].shape[0] == out[1].shape[0] == out[2].shape[0]:
        raise ValueError(f"pretrain: X, U, X_next must have as many rows, got "
                         f"{[a.shape[0] for a in out]}")
    return out[0], out[1], out[2]

def checked(value: Any, shape: tuple[int, ...], name: str) -> np.ndarray:
    """``value`` as a float array of ``shape``, finite, else a ``ValueError``."""
    arr = np.asarray(value, dtype=float)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr}")
    return arr

def bind_sensitivity_columns(learner: Any, residual: ResidualModel) -> None:
    """Give a learner whose linear features are on ``"sensitivities"``
    (:func:`gp_agents.parametric_ssgp` without columns) this MPC's sensitivity columns, and check
    explicit linear-feature columns against the learner's input width."""
    features = getattr(learner, "linear_features", None)
    if isinstance(features, str):
        if features != "sensitivities":
            raise ValueError(f"learner.linear_features {features!r}: only 'sensitivities' "
                             f"names columns")
        if not residual.sensitivities:
            raise TypeError("this learner's linear features are on the parameter sensitivities "
                            "(parametric_ssgp()): build the MPC with "
                            "residual=Residual(sensitivities=True), as make_mpc(env, 'robust') "
                            "does")
        learner.linear_features = residual.sensitivity_columns
        return
    if features is None or isinstance(features, bool | np.bool_ | np.ndarray):
        return
    width = len(residual.input_names)
    bad = [int(c) for c in features if not -width <= int(c) < width]
    if bad:
        hint = ("" if residual.sensitivities else "; columns of parameter sensitivities need "
                "residual=Residual(sensitivities=True)")
        raise TypeError(f"learner.linear_features names input column(s) {bad}, but this MPC's "
                        f"learner has {width} inputs ({', '.join(residual.input_names)}){hint}; "
                        f"parametric_ssgp() without columns takes the MPC's own")
