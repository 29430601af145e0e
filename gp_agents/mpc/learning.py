"""What the MPC learns and when: the transitions observed since the last update, every
transition learned so far, and the rule that turns them into a learner ``update`` or ``fit``.

:class:`OnlineData` is the agent's record of learning (Algorithm 1, line 4): observed
transitions wait in a buffer until the planner's phase says to learn them
(:meth:`OnlineData.learn`); then the learner is updated with them, or fitted anew on all of them
when it has never been fitted (no initial data) or when
:class:`~gp_agents.mpc.settings.Residual`'s ``refit_until`` asks for a refit.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gp_agents.residual import ResidualModel

__all__ = ["OnlineData"]

Batch = tuple[np.ndarray, np.ndarray, np.ndarray]


class OnlineData:
    """The transitions an MPC learns from (module doc).

    Args:
        refit_until: refit the learner on every transition learned so far each time their
            number has doubled since its last fit, while it was last fitted on fewer than this
            (0: never refit; :class:`~gp_agents.mpc.settings.Residual`).
    """

    def __init__(self, refit_until: int = 0) -> None:
        self.refit_until = int(refit_until)
        self.pending: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self.learned: list[Batch] = []
        self.fitted_on = 0

    def start(self, data: Batch | None) -> None:
        """Start over from initial data ``(X, U, X_next)`` the learner was fitted on, or from
        none (the learner is fitted on the first transitions it learns)."""
        self.learned = [] if data is None else [(data[0].copy(), data[1].copy(), data[2].copy())]
        self.fitted_on = 0 if data is None else len(data[0])

    def add(self, x: np.ndarray, u: np.ndarray, x_next: np.ndarray) -> None:
        """Buffer one transition (n,), (m,), (n,) until the next :meth:`learn`."""
        self.pending.append((x, u, x_next))

    def clear_pending(self) -> None:
        """Drop the buffered transitions (an env reset)."""
        self.pending.clear()

    def learn(self, learner: Any, residual: ResidualModel, fitted: bool) -> None:
        """Give ``learner`` the buffered transitions as residual targets: an ``update``, or a
        ``fit`` on every transition learned when it is not ``fitted`` yet or a refit is due."""
        if not self.pending:
            return
        X, U, Xn = (np.array(a) for a in zip(*self.pending, strict=True))
        self.pending.clear()
        self.learned.append((X, U, Xn))
        seen = sum(len(x) for x, _, _ in self.learned)
        refit = self.fitted_on < self.refit_until and seen >= 2 * self.fitted_on
        if refit or not fitted:
            X, U, Xn = (np.concatenate(a) for a in zip(*self.learned, strict=True))
            learner.fit(*residual.targets(X, U, Xn))
            self.fitted_on = seen
        else:
            learner.update(*residual.targets(X, U, Xn))
