"""The learned residual linearized per node about a reference trajectory (real-time iteration).

Instead of the GP itself, the NLP gets its first-order expansion at every collocation node,
``mean(phi(x_k, u_k)) ~ g_k + J_k [x_k - xb_k; u_k - ub_k]``, about a reference ``(xb, ub)``
(the warm start: the previous plan shifted in time). ``g_k`` and ``J_k`` come from the learner's
numeric ``predict`` and ``predict_gradient`` (:meth:`gp_agents.residual.ResidualModel.
linearize`) and are per-node NLP parameters, so the NLP has the nominal model's Hessian and a
denser Jacobian, and the learner is evaluated once per node per solve instead of once per node
per IPOPT iteration with its second derivatives. The plan is optimal for the expansion, not for
the GP: after every solve the GP is evaluated at the plan's nodes and the expansion's error
recorded (:meth:`LinearizedGP.plan_error`); a fixed point of re-linearizing about the plan is a
KKT point of the exact OCP (model values and first derivatives agree there).

The same expansion and error also exist as CasADi expressions of the learner's exported
parameters (:meth:`LinearizedGP.node_param_expr`, :meth:`LinearizedGP.plan_error_expr`), so that
the real-time iteration computes them inside its one compiled step; tests check both paths
against each other.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from gp_agents.mpc.gp_in_nlp import not_fitted
from gp_agents.mpc.learned_term import LearnedTerm
from gp_agents.pseudospectral import OCPSolution

__all__ = ["COLD_START_LINEARIZATIONS", "LinearizedGP"]

COLD_START_LINEARIZATIONS = 5
"""Solves a linearized plan may take from a cold start (the goal guess): the expansion about a
straight line can be far off (once it made the cart pole's first NLP infeasible), and the plan it
gives is the reference of every later step."""


class LinearizedGP(LearnedTerm):
    """``r(x, u) = g_k + J_k [x; u] - J_k [xb_k; ub_k]`` at node k, ``g_k, J_k`` per solve.

    Per-node parameters ``q_k = [c_k; vec(J_k[:, cols]); (vx_k, vy_k)]`` with
    ``c_k = g_k - J_k [xb_k; ub_k]``, ``cols`` the columns of ``[x; u]`` the learner's input
    depends on (``ResidualModel.jacobian_columns``, column-major ``vec``), and, with an
    uncertainty radius, the reference's predictive variances of the x and y rates (frozen).

    Args:
        max_linearizations: solves per replan (>= 1): a plan whose expansion error exceeds 1
            (or a failed solve's finite last iterate) is re-linearized about and re-solved
            while solves remain; cold starts get at least :data:`COLD_START_LINEARIZATIONS`.
        tol: relative tolerance of the expansion: per output j, ``tol * max_k |mean_j| +
            1e-3`` (state-rate units), the largest over the plan's nodes.
    """

    name = "linearized"

    def __init__(self, max_linearizations: int = 1, tol: float = 0.1) -> None:
        super().__init__()
        if int(max_linearizations) < 1:
            raise ValueError(f"max_linearizations must be >= 1, got {max_linearizations}")
        if not (np.isfinite(tol) and tol > 0):
            raise ValueError(f"linearization tol must be > 0, got {tol}")
        self.max_linearizations = int(max_linearizations)
        self.tol = float(tol)
        self._expansion: dict[str, np.ndarray] | None = None

    @property
    def _n_jacobian(self) -> int:
        return self.residual.n_outputs * (1 + len(self.residual.jacobian_columns))

    def n_node_params(self) -> int:
        return self._n_jacobian + (2 if self.variance else 0)

    def param_values(self) -> np.ndarray:
        try:
            self.learner.casadi_param_size()  # fitted? (the NLP holds no learner parameters)
        except (ValueError, RuntimeError) as err:
            raise not_fitted(err) from err
        return np.zeros(0)

    def rates(self, x: Any, u: Any, theta: Any, q: Any) -> Any:
        d, cols = self.residual.n_outputs, list(self.residual.jacobian_columns)
        jac = ca.reshape(q[d:self._n_jacobian], d, len(cols))
        return q[:d] + ca.mtimes(jac, ca.vertcat(x, u)[cols])

    def position_variance(self, x: Any, u: Any, theta: Any, q: Any) -> tuple[Any, Any] | None:
        n = self.n_node_params()
        return q[n - 2], q[n - 1]

    def node_param_values(self, X: np.ndarray, U: np.ndarray) -> np.ndarray:
        """The expansion about node states X (M, n) and controls U (M, m), kept for
        :meth:`plan_error`; returns (M, n_node_params)."""
        X, U = np.atleast_2d(X), np.atleast_2d(U)
        mean, jac, var = self.residual.linearize(self.learner, X, U, variance=self.variance)
        points = np.hstack([X, U])
        jac = self._planned_jacobian(jac)
        c = mean - np.einsum("kij,kj->ki", jac, points)
        blocks = [c, self._jacobian_entries(jac)]
        if var is not None:
            unc = self.residual.uncertain_indices
            blocks.append(var[:, [unc.index(0), unc.index(1)]])
        self._expansion = dict(mean=mean, jacobian=jac, points=points)
        return np.hstack(blocks)

    def _planned_jacobian(self, jac: np.ndarray) -> np.ndarray:
        """The part (M, d_out, n + m) of the learned Jacobians ``jac`` the NLP plans with:
        all of it (a subclass may drop entries)."""
        return jac

    def _jacobian_entries(self, jac: np.ndarray) -> np.ndarray:
        """(M, n_jacobian - d_out) node parameters of the Jacobians ``jac`` (M, d_out, n + m):
        ``vec(J_k[:, cols])`` per node."""
        cols = list(self.residual.jacobian_columns)
        return jac[:, :, cols].transpose(0, 2, 1).reshape(jac.shape[0], -1)

    # ------------------------------------------------------------------ compiled expansion
    def expansion_param_values(self) -> np.ndarray:
        """The learner's parameters ``theta`` (P,) that :meth:`node_param_expr` and
        :meth:`plan_error_expr` read (its CasADi export): without the variance, the mean-only
        vector (``casadi_mean_param_values``, for a learner that has one), else
        ``casadi_param_values``.

        Raises:
            RuntimeError: the learner is not fitted.
        """
        try:
            mean_only = getattr(self.learner, "casadi_mean_param_values", None)
            if not self.variance and mean_only is not None:
                return np.asarray(mean_only(), float).ravel()
            values = self.learner.casadi_param_values(variance=self.variance)
            return np.asarray(values, float).ravel()
        except (ValueError, RuntimeError) as err:
            raise not_fitted(err) from err

    def _mean_function(self, M: int, n_theta: int) -> ca.Function:
        """``(P, theta) -> mean``: the learned mean (d_out, M) at M node points ``P = [X; U]``
        (n + m, M) as matrix operations (the learner's ``casadi_mean_batch``)."""
        n = self.residual.model.n_states
        inputs = self.residual.input_function().map(M)
        P = ca.MX.sym("P", n + self.residual.model.n_controls, M)
        theta = ca.MX.sym("theta", n_theta)
        mean = self.learner.casadi_mean_batch(inputs(P[:n, :], P[n:, :]), theta)
        return ca.Function("learned_mean", [P, theta], [mean])

    def node_param_expr(self, X: ca.MX, U: ca.MX, theta: ca.MX) -> ca.MX:
        """:meth:`node_param_values` as a CasADi expression, for a step compiled as one
        function (the real-time iteration): the expansion about node states X (n, M) and
        controls U (m, M) with the learner's parameters theta (P, 1); (n_node_params, M), node
        k's column equal to row k of ``node_param_values(X.T, U.T)``.

        The mean at all nodes at once by matrix operations (the learner's
        ``casadi_mean_batch``); its Jacobian in the learner's inputs is block diagonal (node
        k's mean depends on node k's inputs only) and is chained with each node's input-map
        Jacobian. (An ad-hoc timing on the quadrotor, not kept in the repository, found this
        form the fastest of four: a mapped per-node MX function, forward derivatives seeded
        at every node and the learner's scalar SX graph were slower; the step's time is what
        the ``rti`` preset measures.)"""
        res = self.residual
        n, m = res.model.n_states, res.model.n_controls
        M, d_in, d_out = X.shape[1], res.n_inputs, res.n_outputs
        Z, dZ = res.input_function(jacobian=True).map(M)(X, U)
        Zs, ts = ca.MX.sym("Z", d_in, M), ca.MX.sym("theta", theta.shape)
        mean_s = self.learner.casadi_mean_batch(Zs, ts)
        G = ca.jacobian(ca.vec(mean_s), ca.vec(Zs))
        mean, G = ca.Function("learned_mean_jacobian", [Zs, ts], [mean_s, G])(Z, theta)
        points = ca.vertcat(X, U)
        if self.variance:
            var = self.learner.casadi_variance_batch(Z, theta)
            unc = res.uncertain_indices
        columns = []
        for k in range(M):
            J = ca.mtimes(G[k * d_out:(k + 1) * d_out, k * d_in:(k + 1) * d_in],
                          dZ[:, k * (n + m):(k + 1) * (n + m)])
            col = self._node_expansion_expr(mean[:, k], J, points[:, k])
            if self.variance:
                col += [var[unc.index(0), k], var[unc.index(1), k]]
            columns.append(ca.vertcat(*col))
        return ca.horzcat(*columns)

    def _node_expansion_expr(self, mean: ca.MX, J: ca.MX, point: ca.MX) -> list[ca.MX]:
        """One node's ``[c_k; vec(J_k[:, cols])]`` from its mean (d_out,), Jacobian J
        (d_out, n + m) and point ``[xb_k; ub_k]`` (symbolic :meth:`node_param_values`)."""
        return [mean - ca.mtimes(J, point), ca.vec(J[:, list(self.residual.jacobian_columns)])]

    def plan_error_expr(self, X: ca.MX, U: ca.MX, Q: ca.MX, theta: ca.MX) -> ca.MX:
        """:meth:`plan_error` as a CasADi expression: the error of the expansion ``Q``
        (n_node_params, M) at node states X (n, M) and controls U (m, M), as a fraction of its
        tolerance (scalar)."""
        mean = self._mean_function(X.shape[1], theta.numel())(ca.vertcat(X, U), theta)
        predicted = ca.horzcat(*[self.rates(X[:, k], U[:, k], None, Q[:, k])
                                 for k in range(X.shape[1])])
        err = ca.fabs(mean - predicted)
        ratios = [ca.mmax(err[j, :]) / (self.tol * ca.mmax(ca.fabs(mean[j, :])) + 1e-3)
                  for j in range(self.residual.n_outputs)]
        return ca.mmax(ca.vertcat(*ratios))

    def solves(self, cold: bool) -> int:
        return max(self.max_linearizations, COLD_START_LINEARIZATIONS if cold else 1)

    def plan_error(self, plan: OCPSolution) -> float:
        """The expansion's largest error at ``plan``'s nodes as a fraction of its tolerance
        (NaN if the plan is not finite)."""
        X, U = plan.x_nodes, plan.u
        if self._expansion is None or not (np.all(np.isfinite(X)) and np.all(np.isfinite(U))):
            return float("nan")
        mean = self.learner.predict(self.residual.inputs(X, U))
        e = self._expansion
        dz = np.hstack([X, U]) - e["points"]
        predicted = e["mean"] + np.einsum("kij,kj->ki", e["jacobian"], dz)
        err = np.max(np.abs(mean - predicted), axis=0)
        tol = self.tol * np.max(np.abs(mean), axis=0) + 1e-3
        return float(np.max(err / tol))
