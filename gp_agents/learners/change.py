"""Change detection for an online learner: when the system it learns changes, restart from the
samples of the new regime.

Why exponential forgetting alone does not do this: the SSGP's prior weight is ``sigma_n^2`` and a
datum of age ``k`` enters with ``lambda^k phi phi^T``, ``|phi|^2 ~ sigma_s^2``. With the
marginal-likelihood hyperparameters of these systems (noise on its floor, signal std 10-15x the
targets' spread) a datum stops mattering only when ``lambda^k sigma_s^2 << sigma_n^2``, i.e.
after ``k ~ 18 / (1 - lambda)`` samples: 18 s at ``lambda = 0.95``. Until then the learner fits
the old and the new system at once wherever their inputs differ slightly (before and after a
payload the hover thrust differs by 20%), and its predictions between them are neither.

:class:`ChangeDetector` watches the learner's one-step prediction errors (each sample's error
*before* it is learned, in the learner's standardized output units). A sample is *surprising*
when, for some output, its error exceeds ``ratio`` times the median of that output's last
``history`` unsurprising errors. ``patience`` surprising samples in a row declare a change; the
learner then keeps only those samples (its hyperparameters, frequencies and standardization stay
as fitted). One surprising sample is not enough: visiting a new region of the state space also
surprises a learner, but a change of the system persists while the errors of a new region fall
as soon as the learner has seen it.

At a fit the history is seeded with the fitted data's leave-one-out errors (what the learner's
error on new samples of the *same* system looks like), so that a system that changed between
the data collection and the first sample is caught
within ``patience`` samples. After a declared change the history starts empty: nothing is
surprising before ``history // 2`` errors of the new regime have been seen.

The defaults are the first settings tried; they were never tuned.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

__all__ = ["ChangeDetector"]


class ChangeDetector:
    """Declares a change of the learned function from the one-step prediction errors.

    Args:
        ratio: a sample is surprising when ``|error_j| > ratio * median_j`` for some output
            ``j`` (``median_j`` over the last ``history`` unsurprising samples).
        patience: surprising samples in a row that declare a change (>= 1).
        history: unsurprising errors kept per output for the median; no sample is surprising
            before ``history // 2`` of them have been seen (after a fit or a change).

    Use: :meth:`reset` at fit, then :meth:`step` per sample in time order. The learner owns a
    copy (:meth:`clone`), so one configured detector can be handed to many learners.
    """

    def __init__(self, ratio: float = 10.0, patience: int = 3, history: int = 40) -> None:
        self.ratio = ratio
        self.patience = patience
        self.history = history

    def get_params(self) -> dict[str, Any]:
        """The constructor's settings."""
        return {"ratio": self.ratio, "patience": self.patience, "history": self.history}

    def clone(self) -> ChangeDetector:
        """A fresh detector with the same settings (no state)."""
        return ChangeDetector(**self.get_params())

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"ChangeDetector({args})"

    def _check(self) -> None:
        if not (np.isfinite(self.ratio) and self.ratio > 1.0):
            raise ValueError(f"ratio must be a finite number > 1, got {self.ratio}")
        if int(self.patience) != self.patience or self.patience < 1:
            raise ValueError(f"patience must be an integer >= 1, got {self.patience}")
        if int(self.history) != self.history or self.history < 2:
            raise ValueError(f"history must be an integer >= 2, got {self.history}")

    def reset(self, n_outputs: int) -> None:
        """Forget all errors (at a fit, and after a declared change)."""
        self._check()
        self._errors: list[deque[float]] = [deque(maxlen=int(self.history))
                                             for _ in range(n_outputs)]
        self.n_surprising_ = 0
        """Surprising samples in a row so far."""

    def seed(self, errors: np.ndarray) -> None:
        """Fill the history with (N, d_out) errors known to be typical (e.g. leave-one-out
        errors of the fitted data), oldest first, so that the first samples after a fit can
        already be surprising."""
        errors = np.abs(np.asarray(errors, dtype=float))
        for row in errors[-int(self.history):]:
            for e, v in zip(self._errors, row, strict=True):
                e.append(float(v))

    def threshold(self) -> np.ndarray | None:
        """(d_out,) current thresholds ``ratio * median`` of the absolute error, or None while
        fewer than ``history // 2`` unsurprising errors have been seen."""
        if len(self._errors[0]) < max(1, int(self.history) // 2):
            return None
        return self.ratio * np.median(np.array(self._errors), axis=1)  # rows of one length

    def step(self, error: np.ndarray) -> bool:
        """Take one sample's (d_out,) one-step prediction error; True when it completes a run
        of ``patience`` surprising samples (a change: the caller keeps only that run's samples
        and calls :meth:`reset`)."""
        error = np.abs(np.asarray(error, dtype=float).reshape(-1))
        if error.size != len(self._errors) or not np.all(np.isfinite(error)):
            raise ValueError(f"error must be {len(self._errors)} finite numbers, got {error}")
        limit = self.threshold()
        if limit is not None and np.any(error > limit):
            self.n_surprising_ += 1
            return self.n_surprising_ >= int(self.patience)
        self.n_surprising_ = 0
        for e, v in zip(self._errors, error, strict=True):
            e.append(float(v))
        return False
