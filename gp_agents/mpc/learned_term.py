"""How a learned residual enters the planning NLP: the strategy interface, and "none".

The planning model (:class:`gp_agents.mpc.planning_model.PlanningModel`) is
``xdot = f_nominal(x, u; p) + S r(x, u; theta, q)``. A :class:`LearnedTerm` supplies the
learned rates ``r`` as CasADi expressions of the NLP's parameters and says what numbers to
put into those parameters at each solve:

- ``theta`` (size :meth:`~LearnedTerm.n_params`): constant over the horizon, e.g. a GP's
  weights and features (:class:`~gp_agents.mpc.gp_in_nlp.GPInNLP`);
- ``q`` (size :meth:`~LearnedTerm.n_node_params`): one value per collocation node, e.g. a
  GP linearized about a reference trajectory
  (:class:`~gp_agents.mpc.gp_linearized.LinearizedGP`).

Terms are the only code that knows how a learner enters the NLP. This module's
:class:`NoLearnedTerm` is the nominal MPC's (``r = 0``).
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from gp_agents.pseudospectral import OCPSolution
from gp_agents.residual import ResidualModel

__all__ = ["LearnedTerm", "NoLearnedTerm"]


class LearnedTerm:
    """Base class of the learned-term strategies.

    Subclasses override what they use; the defaults describe a term with no parameters and
    one solve per replan. A term is *attached* to a learner and its :class:`ResidualModel`
    before use (:meth:`attach`); ``variance`` asks it to provide the position variance of the
    obstacle constraint's uncertainty radius.
    """

    name = "base"

    def __init__(self) -> None:
        self.residual: ResidualModel | None = None
        self.learner: Any | None = None
        self.variance = False

    def attach(self, residual: ResidualModel, learner: Any | None, variance: bool = False
               ) -> None:
        """Use ``learner`` (fitted or not yet) through ``residual``'s inputs and outputs."""
        self.residual, self.learner, self.variance = residual, learner, bool(variance)

    # ------------------------------------------------------------------ NLP layout
    def n_params(self) -> int:
        """Size of ``theta`` (the learner's block of the NLP parameter vector)."""
        return 0

    def n_node_params(self) -> int:
        """Size of ``q`` (per-node NLP parameters)."""
        return 0

    def check_size(self, n_collocation: int) -> None:
        """Raise ``ValueError`` if the term is too large to plan with on this many nodes."""

    # ------------------------------------------------------------------ symbolic
    def rates(self, x: Any, u: Any, theta: Any, q: Any) -> Any | None:
        """The learned rates ``r`` (d_out,) of the uncertain state components, or None."""
        return None

    def hessian_rates(self, x: Any, u: Any, theta: Any, q: Any) -> Any | None:
        """``r`` as the Lagrangian Hessian should see it (default: exact, :meth:`rates`)."""
        return self.rates(x, u, theta, q)

    @property
    def exact_hessian(self) -> bool:
        """Whether :meth:`hessian_rates` is :meth:`rates` (no Hessian approximation)."""
        return True

    def position_variance(self, x: Any, u: Any, theta: Any, q: Any) -> tuple[Any, Any] | None:
        """Predictive variances (m^2/s^4) of the x and y rates, or None without a learner."""
        return None

    # ------------------------------------------------------------------ numeric, per solve
    def param_values(self) -> np.ndarray:
        """``theta``'s value for the next solve, (n_params,).

        Raises:
            RuntimeError: the learner is not fitted.
        """
        return np.zeros(0)

    def node_param_values(self, X: np.ndarray, U: np.ndarray) -> np.ndarray | None:
        """``q`` for a solve about reference node states X (M, n) and controls U (M, m):
        (M, n_node_params), or None for a term without node parameters."""
        return None

    def solves(self, cold: bool) -> int:
        """Most solves per replan (re-linearizations); ``cold``: no previous plan."""
        return 1

    # ------------------------------------------------------------------ compiled steps
    def expansion_param_values(self) -> np.ndarray:
        """The learner's numbers (P,) that :meth:`node_param_expr` reads (none by default)."""
        return np.zeros(0)

    def node_param_expr(self, X: Any, U: Any, theta: Any) -> Any:
        """:meth:`node_param_values` as a CasADi expression of node states X (n, M), controls
        U (m, M) and :meth:`expansion_param_values` theta (P, 1): (n_node_params, M). A term
        with node parameters implements it to take part in a compiled step (the real-time
        iteration's)."""
        raise NotImplementedError(f"the learned term {self.name!r} has no symbolic node "
                                  "parameters")

    def node_expansion_expr(self, X: Any, U: Any, theta: Any) -> dict[str, Any]:
        """:meth:`node_param_expr` as ``{"Q": ...}``, with whatever else of the expansion a
        term's :meth:`jacobian_gap_nodes_expr` reuses (default: ``Q`` alone)."""
        return {"Q": self.node_param_expr(X, U, theta)}

    def jacobian_gap_nodes_expr(self, expansion: dict[str, Any], mu: Any, Q: Any) -> Any | None:
        """The gradient of :meth:`jacobian_gap_expr` in the nodes' ``[x; u]`` ((n + m, M)) at
        the point of ``expansion`` (:meth:`node_expansion_expr`), computed from it; None (the
        default): not available, the compiled step differentiates :meth:`jacobian_gap_expr`
        instead."""
        return None

    def plan_error_expr(self, X: Any, U: Any, Q: Any, theta: Any) -> Any:
        """:meth:`plan_error` as a CasADi expression (scalar) of a plan's node states X
        (n, M), controls U (m, M), the node parameters Q (n_node_params, M) it was planned
        with and theta; 0 for an exact term."""
        return ca.DM(0.0)

    def jacobian_gap_expr(self, X: Any, U: Any, theta: Any, mu: Any, Q: Any) -> Any | None:
        """For a term whose rates in the NLP have another Jacobian than the learned mean's (a
        frozen value, a dropped entry): a scalar CasADi expression of node states X (n, M),
        controls U (m, M), theta, weights mu (d_out, M) and the node parameters Q
        (n_node_params, M) of the reference, whose gradient in (X, U) at the reference is
        ``sum_k (d mean_k - d rates_k)' mu_k``, the gradient correction of an adjoint-based
        RTI step (:mod:`~gp_agents.mpc.gp_zero_order`). None (the default): no gap.
        """
        return None

    def plan_error(self, plan: OCPSolution) -> float:
        """How far ``plan`` is from the term's own model of it, as a fraction of the term's
        tolerance (> 1: re-solve if solves remain); 0 for an exact term."""
        return 0.0


class NoLearnedTerm(LearnedTerm):
    """The nominal model: no learned rates (``r = 0``)."""

    name = "none"
