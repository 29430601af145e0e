"""The learned residual linearized per node on the nominal model's Jacobian pattern, with an
adjoint-corrected RTI step.

:class:`~gp_agents.mpc.gp_linearized.LinearizedGP` puts the learned mean's full Jacobian into
the NLP: every column of ``[x; u]`` the learner's input depends on, so the constraint
Jacobian, and the real-time iteration's QP, get entries the nominal model does not have (the
Dubins vehicle's learned rates depend on its position, the nominal ones do not; on the
quadrotor the learned accelerations depend on every state and control). Those entries make the
QP's linear solves slower. :class:`~gp_agents.mpc.gp_zero_order.ZeroOrderGP` keeps the nominal
structure by dropping the Jacobian altogether, and fails where the learned term rescales an
actuator (its QP steps with the nominal control gain).

This term keeps, of the learned Jacobian ``J_k`` at node k, exactly the entries where the
nominal model's Jacobian is structurally nonzero (:func:`nominal_pattern`: the parametric
nominal rates of the uncertain components differentiated in ``[x; u]`` with the parameters
symbolic), and drops the rest:

    r(x, u) = c_k + (S o J_k) [x; u],     c_k = g_k - (S o J_k) [xb_k; ub_k]

(``S`` the 0/1 pattern, ``o`` the elementwise product, ``g_k`` the mean at the reference
``(xb_k, ub_k)``). The value at the reference is exact and the QP has exactly the nominal
model's sparsity; the control gains the nominal model has (the entries in ``u``) are learned
ones. The dropped derivatives are handled as the zero-order term handles all of them: the RTI
step corrects the QP's gradient by ``(J_exact - J_nlp)' lambda`` with the previous step's
multipliers (:meth:`PatternLinearizedGP.jacobian_gap_expr`), so that a fixed point of the
iteration is a KKT point of the OCP with the learned mean (tested against the exact OCP's).
A converged solve with this term plans for the masked expansion, re-linearized about its own
plan while solves remain, as the linearized term does.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from gp_agents.mpc.gp_linearized import LinearizedGP
from gp_agents.residual import ResidualModel

__all__ = ["PatternLinearizedGP", "nominal_pattern"]


def nominal_pattern(residual: ResidualModel) -> tuple[tuple[int, int], ...]:
    """The learned Jacobian's entries on the nominal model's structure.

    Args:
        residual: the learner's inputs and outputs on the nominal model.

    Returns:
        Pairs ``(j, c)``: output j (the rate of state ``uncertain_indices[j]``) and column c
        of ``[x; u]`` where the parametric nominal rate depends on ``[x; u]_c`` structurally
        and the learner's input does too (``c`` in ``jacobian_columns``), in column-major
        order (by ``c``, then ``j``: the order of ``vec``).
    """
    model = residual.model
    x = ca.SX.sym("x", model.n_states)
    u = ca.SX.sym("u", model.n_controls)
    p = ca.SX.sym("p", len(model.param_names))
    f = model.casadi_parametric_function()(x, u, p)[list(residual.uncertain_indices)]
    rows, cols = ca.jacobian(f, ca.vertcat(x, u)).sparsity().get_triplet()
    learned = set(residual.jacobian_columns)
    return tuple(sorted(((int(j), int(c)) for j, c in zip(rows, cols, strict=True)
                         if int(c) in learned), key=lambda e: (e[1], e[0])))


class PatternLinearizedGP(LinearizedGP):
    """``r(x, u) = c_k + (S o J_k) [x; u]`` at node k: the learned expansion on the nominal
    Jacobian pattern ``S`` (module docstring).

    Per-node parameters ``q_k = [c_k; J_k entries at S (column-major); (vx_k, vy_k)]`` (the
    variances with an uncertainty radius, as for :class:`LinearizedGP`).

    Args:
        max_linearizations, tol: as for :class:`LinearizedGP` (the expansion error is that
            of the masked expansion the NLP plans with).
    """

    name = "linearized-pattern"

    def attach(self, residual: ResidualModel, learner: Any | None, variance: bool = False
               ) -> None:
        super().attach(residual, learner, variance)
        self.pattern = nominal_pattern(residual)
        """``(j, c)`` entries of the learned Jacobian the NLP plans with."""
        d, n_x = residual.n_outputs, residual.model.n_states + residual.model.n_controls
        self._mask = np.zeros((d, n_x))
        for j, c in self.pattern:
            self._mask[j, c] = 1.0

    @property
    def _n_jacobian(self) -> int:
        return self.residual.n_outputs + len(self.pattern)

    def rates(self, x: Any, u: Any, theta: Any, q: Any) -> Any:
        d, e = self.residual.n_outputs, len(self.pattern)
        if not e:
            return q[:d]
        rows, cols = (list(v) for v in zip(*self.pattern, strict=True))
        place = ca.DM(ca.Sparsity.triplet(d, e, rows, list(range(e))), 1.0)
        return q[:d] + ca.mtimes(place, q[d:d + e] * ca.vertcat(x, u)[cols])

    def _planned_jacobian(self, jac: np.ndarray) -> np.ndarray:
        return jac * self._mask[None]

    def _jacobian_entries(self, jac: np.ndarray) -> np.ndarray:
        if not self.pattern:
            return np.zeros((jac.shape[0], 0))
        rows, cols = (list(v) for v in zip(*self.pattern, strict=True))
        return jac[:, rows, cols]

    def _planned_jacobian_expr(self, J: ca.MX, M: int) -> ca.MX:
        return J * ca.repmat(ca.DM(self._mask), 1, M)

    def _entry_rows(self) -> list[int]:
        d = self.residual.n_outputs
        return [j + d * c for j, c in self.pattern]

    def _rates_batch(self, P: ca.MX, Q: ca.MX) -> ca.MX:
        d, e = self.residual.n_outputs, len(self.pattern)
        if not e:
            return Q[:d, :]
        rows, cols = (list(v) for v in zip(*self.pattern, strict=True))
        place = ca.DM(ca.Sparsity.triplet(d, e, rows, list(range(e))), 1.0)
        return Q[:d, :] + ca.mtimes(place, Q[d:d + e, :] * P[cols, :])

    def jacobian_gap_nodes_expr(self, expansion: dict[str, ca.MX], mu: ca.MX, Q: ca.MX
                                ) -> ca.MX:
        """The gradient of :meth:`jacobian_gap_expr` in the nodes' ``[x; u]`` ((n + m, M)) at
        the expansion's point: ``J_k' mu_k`` minus the planned entries' part (``Q``'s
        ``S o J_k`` weighted by ``mu_k``), with ``J`` the expansion's own Jacobians (the
        learner is not evaluated again)."""
        J, E = expansion["J"], expansion["E"]
        d, e = self.residual.n_outputs, len(self.pattern)
        nx, M = J.shape[1] // mu.shape[1], mu.shape[1]
        full = ca.reshape(ca.sum1(J * ca.mtimes(mu, E)), nx, M)
        if not e:
            return full
        rows, cols = (list(v) for v in zip(*self.pattern, strict=True))
        place = ca.DM(ca.Sparsity.triplet(nx, e, cols, list(range(e))), 1.0)
        return full - ca.mtimes(place, mu[rows, :] * Q[d:d + e, :])

    def jacobian_gap_expr(self, X: ca.MX, U: ca.MX, theta: ca.MX, mu: ca.MX,
                          Q: ca.MX) -> ca.MX:
        """``sum_k mu_k' (mean(x_k, u_k) - (S o J_k) [x_k; u_k])`` (scalar) for node states
        X (n, M), controls U (m, M), weights mu (d_out, M) and the node parameters Q
        (n_node_params, M) holding ``S o J_k``: its gradient in (X, U) is the gap ``(J_exact -
        J_nlp)' lambda`` (the dropped entries' part)."""
        mean = self._mean_function(X.shape[1], theta.numel())(ca.vertcat(X, U), theta)
        gap = ca.sum1(ca.sum2(mu * mean))
        if not self.pattern:
            return gap
        d, e = self.residual.n_outputs, len(self.pattern)
        rows, cols = (list(v) for v in zip(*self.pattern, strict=True))
        planned = mu[rows, :] * Q[d:d + e, :] * ca.vertcat(X, U)[cols, :]
        return gap - ca.sum1(ca.sum2(planned))
