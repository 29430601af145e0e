"""Fall back to the nominal model while the learned residual predicts worse than none.

The learners model the residual ``y = f_true - f_nominal``: predicting zero *is* the nominal
model. A learner fitted on data of another system (the
system changed between data collection and control) can be further from the system now
controlled than the nominal model is, and the MPC exploits its model where it is least
supported: on the quadrotor, the first plan puts the rotors at a corner of the control box, tens
of the data's standard deviations away, where the other system's model is off by ~20 rad/s^2
in the angular accelerations against the nominal model's 4-8, and the vehicle leaves its
attitude box within 0.2 s.

:class:`NominalFallback` watches the learner's one-step prediction errors (each sample's error
*before* it is learned, standardized) against those of the zero residual on the same samples,
both squared and summed over the outputs, and averages each with ``memory`` weight on the past
(``memory = 0.8``: about five samples). While the learner's average exceeds zero's the residual
is *off*: the learner predicts zero mean and zero gradient, in NumPy and in its CasADi export
alike (its predictive variance is unchanged), and it keeps learning every sample. Before the
first sample it is on. It is the statement "learning must never make it worse than the
nominal model" as a test on the newest data, not a guarantee: a learner that is better than zero
on the last samples and wrong where the plan goes next is not caught.

It rescues quadrotor episodes with another system's data and leaves episodes where the learner
is right as they were: the residual is switched off only where it predicts worse than none.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["NominalFallback"]


class NominalFallback:
    """Switches a learner's residual off while it predicts the newest samples worse than zero.

    Args:
        memory: weight of the past in the exponential averages of the squared errors, in
            [0, 1) (0: only the newest sample decides).

    Use: :meth:`reset` at fit, then :meth:`step` per sample in time order; :attr:`on_` tells
    whether the residual is used. The learner owns a copy (:meth:`clone`).
    """

    def __init__(self, memory: float = 0.8) -> None:
        self.memory = memory

    def get_params(self) -> dict[str, Any]:
        """The constructor's settings."""
        return {"memory": self.memory}

    def clone(self) -> NominalFallback:
        """A fresh fallback with the same settings (no state)."""
        return NominalFallback(**self.get_params())

    def __repr__(self) -> str:
        return f"NominalFallback(memory={self.memory!r})"

    def reset(self) -> None:
        """Forget the errors (at a fit): the residual is on."""
        m = float(self.memory)
        if not (np.isfinite(m) and 0.0 <= m < 1.0):
            raise ValueError(f"memory must be in [0, 1), got {self.memory!r}")
        self.learned_error_: float | None = None
        """Average squared standardized error of the learner (None before the first sample)."""
        self.zero_error_: float | None = None
        """The same of the zero residual (the nominal model)."""
        self.on_ = True

    def step(self, learned_error: np.ndarray, zero_error: np.ndarray) -> bool:
        """Take one sample's (d_out,) errors of the learner and of zero (standardized, before
        the sample is learned); returns :attr:`on_` after it.

        Raises:
            ValueError: shapes differ or an error is not finite.
        """
        a = np.asarray(learned_error, dtype=float).reshape(-1)
        b = np.asarray(zero_error, dtype=float).reshape(-1)
        if a.shape != b.shape or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            raise ValueError(f"errors must be finite and of one shape, got {a} and {b}")
        now_a, now_b, m = float(a @ a), float(b @ b), float(self.memory)
        if self.learned_error_ is None or self.zero_error_ is None:
            self.learned_error_, self.zero_error_ = now_a, now_b
        else:
            self.learned_error_ = m * self.learned_error_ + (1.0 - m) * now_a
            self.zero_error_ = m * self.zero_error_ + (1.0 - m) * now_b
        self.on_ = self.learned_error_ <= self.zero_error_
        return self.on_
