"""The learned residual frozen per node (zero-order), with an adjoint-corrected RTI step.

The NLP gets the learned mean's *value* at every collocation node of a reference trajectory
(the shifted plan), ``r(x_k, u_k) ~ g_k``, as a per-node parameter, and no Jacobian: the
constraint Jacobian, and so the real-time iteration's QP, has exactly the nominal model's
sparsity. Against :class:`~gp_agents.mpc.gp_linearized.LinearizedGP` (value and Jacobian per
node) this saves the Jacobian's evaluation and the QP's extra nonzeros (quadrotor: the
learned accelerations depend on every state and control, a dense 6 x 16 block per node).

Dropping the Jacobian alone would change the iteration's fixed point (an SQP step with an
inexact constraint Jacobian converges to a feasible point that is not optimal). The RTI step
therefore corrects the QP's gradient with the previous step's multipliers ``lambda``, as in
adjoint-based inexact SQP (Bock, Diehl et al.; acados calls the same idea a zero-order
scheme): ``grad f + (J_exact - J_nlp)' lambda``, where the gap ``(J_exact - J_nlp)' lambda``
is one reverse-mode sweep of the learned mean at the nodes, ``d/dw sum_k mu_k' mean(x_k,
u_k)`` with ``mu_k = (dg/dq_k)' lambda``. At a fixed point of the iteration (dw = 0, the
multipliers reproduced) the QP's optimality conditions are then the exact OCP's, so it is a
KKT point of the OCP with the learned mean (tested against the linearized scheme's fixed
point). The multipliers are the previous period's, not shifted in time: between periods the
RTI's plan moves anyway, and the gradient is approximate to the same order.

A converged solve with this term (the RTI's cold start and fallbacks, or ``scheme=
"converged"``) plans for the frozen values, re-evaluated about its own plan while solves remain
(:meth:`solves`): a plan consistent with the learned mean but optimal only for the frozen
model; the RTI steps that follow move it to the optimum of the learned one.

**Where it fails.** The correction fixes where the iteration stops, not whether it gets there:
the QP steps with the nominal model's Jacobian, so a control acting through a gain (true
``g``, nominal ``g_nom``) leaves the defect ``(1 - g / g_nom) e`` of a defect ``e``, which
shrinks only for ``0 < g / g_nom < 2``. A nominal model that believes an actuator more than
twice as weak as it is makes the iteration overshoot and alternate. On the Dubins vehicle,
whose learned residual is the actuator loss itself, every episode that failed with this term
had a gain ratio above 2, and none below 2 failed; the linearized term (the learned Jacobian
in the QP) reached the goal on all of them. Use it only where the nominal model's control gains are
within a factor of two of the truth, not where the learned term rescales an actuator by more;
no system's tuning uses it.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from gp_agents.mpc.gp_linearized import LinearizedGP

__all__ = ["ZeroOrderGP"]


class ZeroOrderGP(LinearizedGP):
    """``r(x, u) = g_k`` at node k: the learned mean at the reference, frozen.

    Per-node parameters ``q_k = [g_k; (vx_k, vy_k)]``: the mean (d_out,) at the reference node
    and, with an uncertainty radius, the reference's predictive variances of the x and y rates.

    Args:
        max_linearizations, tol: as for :class:`LinearizedGP` (the error of a frozen value is
            ``|mean(plan) - g_k|``).
    """

    name = "zero-order"

    @property
    def _n_jacobian(self) -> int:
        return self.residual.n_outputs

    def rates(self, x: Any, u: Any, theta: Any, q: Any) -> Any:
        return q[:self.residual.n_outputs]

    def node_param_values(self, X: np.ndarray, U: np.ndarray) -> np.ndarray:
        """The learned mean at node states X (M, n) and controls U (M, m) (kept for
        :meth:`plan_error`); returns (M, n_node_params)."""
        X, U = np.atleast_2d(X), np.atleast_2d(U)
        Z = self.residual.inputs(X, U)
        if self.variance:
            mean, std = self.learner.predict(Z, return_std=True)
            var = np.asarray(std) ** 2
        else:
            mean, var = self.learner.predict(Z), None
        mean = np.asarray(mean)
        points = np.hstack([X, U])
        blocks = [mean]
        if var is not None:
            unc = self.residual.uncertain_indices
            blocks.append(var[:, [unc.index(0), unc.index(1)]])
        self._expansion = dict(mean=mean, points=points,
                               jacobian=np.zeros((*mean.shape, points.shape[1])))
        return np.hstack(blocks)

    def node_param_expr(self, X: ca.MX, U: ca.MX, theta: ca.MX) -> ca.MX:
        """:meth:`node_param_values` as a CasADi expression of node states X (n, M), controls
        U (m, M) and the learner's parameters theta: (n_node_params, M)."""
        mean = self._mean_function(X.shape[1], theta.numel())(ca.vertcat(X, U), theta)
        if not self.variance:
            return mean
        Z = self.residual.input_function().map(X.shape[1])(X, U)
        var = self.learner.casadi_variance_batch(Z, theta)
        unc = self.residual.uncertain_indices
        return ca.vertcat(mean, var[unc.index(0), :], var[unc.index(1), :])

    def node_expansion_expr(self, X: ca.MX, U: ca.MX, theta: ca.MX) -> dict[str, ca.MX]:
        """``{"Q": node_param_expr(X, U, theta)}`` (no Jacobian to share)."""
        return {"Q": self.node_param_expr(X, U, theta)}

    def _rates_batch(self, P: ca.MX, Q: ca.MX) -> ca.MX:
        return Q[:self.residual.n_outputs, :]

    def jacobian_gap_expr(self, X: ca.MX, U: ca.MX, theta: ca.MX, mu: ca.MX,
                          Q: ca.MX) -> ca.MX:
        """``sum_k mu_k' mean(x_k, u_k)`` (scalar) for node states X (n, M), controls U (m, M)
        and weights mu (d_out, M) (Q unused): its gradient in (X, U) at the reference is the gap
        ``(J_exact - J_nlp)' lambda`` of the module docstring (the NLP's rates do not depend
        on (X, U))."""
        mean = self._mean_function(X.shape[1], theta.numel())(ca.vertcat(X, U), theta)
        return ca.sum1(ca.sum2(mu * mean))
