"""The model an MPC plans with: nominal physics plus one learned term.

Paper, "Problem Formulation": ``f(x, u) = f_p(x, u) + f_err(x, u)``. Here

    xdot = f_nominal(x, u; p_nominal) + S r(x, u; theta, q)

with ``f_nominal`` the system's physics (``ControlModel.casadi_parametric_function``: the
nominal parameter values are NLP parameters, so a redrawn nominal model needs no rebuild),
``S`` (n, d_out) placing the learned rates on the uncertain components
(:attr:`gp_agents.residual.ResidualModel.selector`, by default the accelerations), and ``r`` the
:class:`~gp_agents.mpc.learned_term.LearnedTerm`'s rates. This is the only place the formula is
written; the OCP (:mod:`gp_agents.mpc.ocp`) calls it.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from gp_agents.mpc.learned_term import LearnedTerm
from gp_agents.residual import ResidualModel
from gp_envs.model import ControlModel

__all__ = ["PlanningModel"]


class PlanningModel:
    """Nominal physics of ``model`` plus the learned ``term`` on ``residual``'s components.

    The NLP parameter vector is ``p = [p_nominal (k,); theta (term.n_params())]``; the per-node
    parameters are the term's ``q``.

    Args:
        model: the nominal (or, for the oracle baseline, the true) model.
        residual: the learner's inputs, outputs and selector.
        term: how the learner enters the NLP (attached to its learner).
    """

    def __init__(self, model: ControlModel, residual: ResidualModel, term: LearnedTerm) -> None:
        self.model = model
        self.residual = residual
        self.term = term
        self.n_nominal = len(model.param_names)
        self.n_params = self.n_nominal + term.n_params()
        self.n_node_params = term.n_node_params()
        self._f = model.casadi_parametric_function()
        self._selector = ca.DM(residual.selector)

    def _xdot(self, x: Any, u: Any, p: Any, rates: Any | None) -> Any:
        xdot = self._f(x, u, p[: self.n_nominal])
        return xdot if rates is None else xdot + ca.mtimes(self._selector, rates)

    def dynamics(self, x: Any, u: Any, p: Any, q: Any) -> Any:
        """``xdot (n,)`` of symbolic state x (n,), control u (m,), p (n_params,), q."""
        return self._xdot(x, u, p, self.term.rates(x, u, p[self.n_nominal:], q))

    def hessian_dynamics(self, x: Any, u: Any, p: Any, q: Any) -> Any:
        """The dynamics as the Lagrangian Hessian sees them (the term's approximation)."""
        return self._xdot(x, u, p, self.term.hessian_rates(x, u, p[self.n_nominal:], q))

    def position_variance(self, x: Any, u: Any, p: Any, q: Any) -> tuple[Any, Any] | None:
        """The learned x and y rates' predictive variances, or None (see the term)."""
        return self.term.position_variance(x, u, p[self.n_nominal:], q)

    def param_values(self) -> np.ndarray:
        """``p`` for the next solve: the model's parameter values, then the term's theta."""
        return np.concatenate([np.asarray(self.model.param_vector, float),
                               self.term.param_values()])
