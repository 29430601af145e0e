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

from gp_agents.learners.base import mean_gradient_batch
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
        k's column equal to row k of ``node_param_values(X.T, U.T)``
        (:meth:`node_expansion_expr`'s ``"Q"``)."""
        return self.node_expansion_expr(X, U, theta)["Q"]

    def node_expansion_expr(self, X: ca.MX, U: ca.MX, theta: ca.MX) -> dict[str, ca.MX]:
        """The expansion about node states X (n, M) and controls U (m, M) as matrix operations
        over all nodes at once, nothing per node: ``"Q"`` (n_node_params, M), and what a
        Jacobian-gap correction reuses (:meth:`jacobian_gap_nodes_expr`): ``"J"``, the learned
        mean's Jacobians in ``[x; u]`` side by side (d_out, (n + m) M; node k's block is
        columns ``k (n + m) ...``), ``"E"``, the (M, (n + m) M) 0/1 matrix that repeats a
        node's column over its block.

        The mean and its gradient in the learner's inputs come from the learner at once
        (``casadi_mean_gradient_batch``: the random features' analytic gradient for the
        SSGPs), chained with the input map's Jacobians: ``J[j, block k] = sum_i
        G_j[i, k] dZ[i, block k]`` as one product with ``E`` and one elementwise product per
        output (cheaper than reverse-mode AD of the batched mean and a product per node)."""
        res = self.residual
        n, m = res.model.n_states, res.model.n_controls
        M, d_out, nx = X.shape[1], res.n_outputs, n + m
        Z, dZ = res.input_function(jacobian=True).map(M)(X, U)  # (d_in, M), (d_in, nx M)
        mean, grads = mean_gradient_batch(self.learner, Z, theta)
        E = ca.DM(ca.Sparsity.triplet(M, nx * M, [k for k in range(M) for _ in range(nx)],
                                      list(range(nx * M))), 1.0)
        J = ca.vertcat(*[ca.sum1(ca.mtimes(g, E) * dZ) for g in grads])  # (d_out, nx M)
        planned = self._planned_jacobian_expr(J, M)
        points = ca.reshape(ca.vertcat(X, U), 1, nx * M)  # node k's [x; u] in block k
        c = mean - ca.mtimes(planned * ca.repmat(points, d_out, 1), E.T)
        blocks = [c, ca.reshape(J, d_out * nx, M)[self._entry_rows(), :]]
        if self.variance:
            var = self.learner.casadi_variance_batch(Z, theta)
            unc = res.uncertain_indices
            blocks += [var[unc.index(0), :], var[unc.index(1), :]]
        return {"Q": ca.vertcat(*blocks), "J": J, "E": E}

    def _planned_jacobian_expr(self, J: ca.MX, M: int) -> ca.MX:
        """The part of the Jacobians ``J`` (d_out, (n + m) M, :meth:`node_expansion_expr`) the
        NLP plans with (symbolic :meth:`_planned_jacobian`): all of it."""
        return J

    def _entry_rows(self) -> list[int]:
        """Rows of a node's ``vec(J_k)`` (column-major, d_out (n + m)) that are its Jacobian
        node parameters (symbolic :meth:`_jacobian_entries`): ``vec(J_k[:, cols])``."""
        d = self.residual.n_outputs
        return [j + d * c for c in self.residual.jacobian_columns for j in range(d)]

    def jacobian_gap_nodes_expr(self, expansion: dict[str, ca.MX], mu: ca.MX, Q: ca.MX
                                ) -> ca.MX | None:
        """The gradient of :meth:`jacobian_gap_expr` in the nodes' ``[x; u]`` ((n + m, M)) at
        the expansion's own point, from :meth:`node_expansion_expr`'s Jacobians (no second
        pass through the learner); None for a term without a gap (this one) or without it
        in this form."""
        return None

    def _rates_batch(self, P: ca.MX, Q: ca.MX) -> ca.MX:
        """:meth:`rates` at every node at once: node points ``P = [X; U]`` (n + m, M) and node
        parameters Q (n_node_params, M) -> (d_out, M)."""
        d, cols = self.residual.n_outputs, list(self.residual.jacobian_columns)
        if not cols:
            return Q[:d, :]
        nc = len(cols)
        S = ca.DM(ca.Sparsity.triplet(d, d * nc, [j for _ in cols for j in range(d)],
                                      list(range(d * nc))), 1.0)
        rows = [c for c in cols for _ in range(d)]
        return Q[:d, :] + ca.mtimes(S, Q[d:self._n_jacobian, :] * P[rows, :])

    def plan_error_expr(self, X: ca.MX, U: ca.MX, Q: ca.MX, theta: ca.MX) -> ca.MX:
        """:meth:`plan_error` as a CasADi expression: the error of the expansion ``Q``
        (n_node_params, M) at node states X (n, M) and controls U (m, M), as a fraction of its
        tolerance (scalar)."""
        P = ca.vertcat(X, U)
        mean = self._mean_function(X.shape[1], theta.numel())(P, theta)
        err = ca.fabs(mean - self._rates_batch(P, Q))
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
