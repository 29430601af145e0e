"""Valid ranges of physical parameters, and the one check every parameter set goes through.

Each physics module declares ``PARAM_RANGES``, a table ``name -> ParamRange`` next to its ODE
(the parameters' order, meaning and unit are that table's). :func:`check_params` is called by
:class:`gp_envs.model.ControlModel` on construction, so every way of getting a model with some
parameter values (an env's true parameters and their ``true_params`` overrides, randomized or
drawn per-episode values, the nominal model, :meth:`~gp_envs.model.ControlModel.with_params`)
is checked against the same table and fails with the same ``ValueError``.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class ParamRange:
    """An interval of valid values of one parameter, with its meaning and unit.

    Attributes:
        lower, upper: interval ends in the parameter's unit (``inf`` for unbounded).
        lower_inclusive, upper_inclusive: whether each end is a valid value.
        meaning: what the parameter is, with its unit, e.g. ``"cart mass, kg"``.
    """

    lower: float
    upper: float
    lower_inclusive: bool
    upper_inclusive: bool
    meaning: str

    @classmethod
    def positive(cls, meaning: str) -> ParamRange:
        """``(0, inf)``: masses, lengths, inertias, gravity."""
        return cls(0.0, np.inf, False, False, meaning)

    @classmethod
    def nonnegative(cls, meaning: str) -> ParamRange:
        """``[0, inf)``: damping and friction coefficients (zero means none)."""
        return cls(0.0, np.inf, True, False, meaning)

    def contains(self, value: float) -> bool:
        """Whether ``value`` lies in the interval (NaN never does)."""
        above = value >= self.lower if self.lower_inclusive else value > self.lower
        below = value <= self.upper if self.upper_inclusive else value < self.upper
        return bool(above and below)

    def __str__(self) -> str:
        return (f"{'[' if self.lower_inclusive else '('}{self.lower:g}, "
                f"{self.upper:g}{']' if self.upper_inclusive else ')'}")


def as_real(value: Any) -> float | None:
    """``value`` as a float if it is a real number (Python or NumPy int/float, or a 0-d such
    array), else None: bools, strings, complex numbers, None and arrays are not."""
    if isinstance(value, (bool, np.bool_)):
        return None
    if isinstance(value, numbers.Real):
        return float(value)
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        return float(value)
    return None


def check_value(owner: str, name: str, value: Any, valid: ParamRange) -> float:
    """``value`` as a float, checked to be a finite real number inside ``valid``.

    Args:
        owner: who the value belongs to, for the message (a system or env name).
        name: the value's name, for the message.
        value: the value to check.
        valid: its valid range.

    Raises:
        ValueError: naming ``name``, the value and the valid range, if the value is not a real
            number (bool and str included), not finite, or outside ``valid``.
    """
    number = as_real(value)
    if number is None:
        raise ValueError(f"{owner}: {name} must be a real number in {valid} ({valid.meaning}), "
                         f"got {value!r} of type {type(value).__name__}")
    if not np.isfinite(number):
        raise ValueError(f"{owner}: {name} = {number} is not finite; valid range {valid} "
                         f"({valid.meaning})")
    if not valid.contains(number):
        raise ValueError(f"{owner}: {name} = {number!r} is outside its valid range {valid} "
                         f"({valid.meaning})")
    return number


def check_params(system: str, ranges: Mapping[str, ParamRange], params: Mapping[str, Any]
                 ) -> dict[str, float]:
    """The validated parameter set: exactly the names of ``ranges``, each value inside its range.

    Args:
        system: system name, for messages (``"cartpole"``, ...).
        ranges: the system's ``PARAM_RANGES``; its order is the parameters' order.
        params: parameter values by name.

    Returns:
        ``{name: float(value)}`` in the order of ``ranges``.

    Raises:
        ValueError: unknown or missing names, or a value that :func:`check_value` rejects
            (the message names the parameter, its value and its valid range).
    """
    unknown = set(params) - set(ranges)
    missing = set(ranges) - set(params)
    if unknown or missing:
        raise ValueError(f"{system}: parameters must be exactly {list(ranges)}; "
                         f"unknown {sorted(unknown)}, missing {sorted(missing)}")
    return {name: check_value(system, f"parameter {name}", params[name], valid)
            for name, valid in ranges.items()}
