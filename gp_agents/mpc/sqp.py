"""Sequential quadratic programming to convergence, on the real-time iteration's machinery.

The real-time iteration (:mod:`~gp_agents.mpc.rti`) takes one Gauss-Newton SQP step per period
from the shifted plan. :class:`SQPPlanner` takes as many as convergence needs, within an
iteration budget (a count, never a time): every iteration is the RTI's compiled QP step from the
current point (X(t0) the measured state, the learned term expanded there, the active-set QP
warm-started from the current active set), globalized by a backtracking line search on the
exact-penalty merit function

    phi(w) = f(w) + nu |c(w)|_1,

with ``c`` the NLP's constraint violations (the dynamics defects, the path constraints; the box
bounds hold exactly in every QP step) evaluated with the learned term expanded at ``w`` itself,
and ``nu`` kept above the QP multipliers' largest magnitude (so that the QP's step is a descent
direction of ``phi`` at a point that is not a KKT point). The iteration stops converged when a
full step is shorter than ``tolerance`` (infinity norm, in the NLP variables' units) and the
constraint violation is below ``tolerance``: a KKT point of the OCP (the Gauss-Newton Hessian
changes the path to it, not the point). A plan that does not converge within the budget, or a
step that fails, falls back to the converged IPOPT solve from the shifted plan (the
:class:`~gp_agents.mpc.planner.Planner`'s, with its retry and fallback); so does the cold start.
"""

from __future__ import annotations

import time
from typing import Any

import casadi as ca
import numpy as np

from gp_agents.mpc.diagnostics import StepStatus
from gp_agents.mpc.learned_term import LearnedTerm
from gp_agents.mpc.planner import Plan, Planner
from gp_agents.mpc.rti import RTIPlanner
from gp_agents.pseudospectral import BufferedFunction, OCPSolution

__all__ = ["SQPPlanner"]

ARMIJO = 1e-4
"""Sufficient decrease of the merit function, as a share of the step's predicted decrease."""
MIN_STEP = 2.0 ** -10
"""Smallest line-search step length before the iteration gives up (the IPOPT fallback)."""
PENALTY_MARGIN = 1.1
"""``nu`` is kept at least this factor above the largest QP multiplier magnitude."""
ROUNDING = 1e-10
"""Relative merit change below which a step counts as no change (rounding and the QP's own
accuracy, not a lack of descent)."""


class SQPPlanner(RTIPlanner):
    """Plans by SQP iterations to convergence from the shifted previous plan (module doc).

    Args:
        planning, mesh, constraints: as for :class:`~gp_agents.mpc.planner.Planner`.
        sqp_iterations: the iteration budget of one plan, >= 1.
        tolerance: convergence tolerance on the step and on the constraint violation (> 0).
        **settings: the RTI's QP settings (``qp_solver``, ``levenberg_marquardt``, ...) and the
            fallback's converged-solve settings (:class:`~gp_agents.mpc.rti.RTIPlanner`).
    """

    def __init__(self, *args: Any, sqp_iterations: int = 30, tolerance: float = 1e-4,
                 **settings: Any) -> None:
        if isinstance(sqp_iterations, bool) or int(sqp_iterations) < 1:
            raise ValueError(f"sqp_iterations must be an int >= 1, got {sqp_iterations!r}")
        if not (np.isfinite(tolerance) and tolerance > 0):
            raise ValueError(f"tolerance must be a positive number, got {tolerance!r}")
        super().__init__(*args, **settings)
        self.sqp_iterations, self.tolerance = int(sqp_iterations), float(tolerance)
        self._merits: dict[int, BufferedFunction] = {}

    def _merit_function(self, n_theta: int) -> BufferedFunction:
        """``(w, p[, theta]) -> (f, |c|_1, |c|_inf)`` at the NLP point ``w``, the learned term
        expanded at ``w`` (with ``n_theta`` > 0)."""
        fn = self._merits.get(n_theta)
        if fn is not None:
            return fn
        ocp, term = self.ocp, self.planning.term
        nlp = ocp.nlp
        w = ca.MX.sym("w", ocp.n_variables)
        if n_theta:
            M = ocp.node_indices()[0].shape[0]
            p = ca.MX.sym("p", nlp["p"].numel() - M * term.n_node_params())
            theta = ca.MX.sym("theta", n_theta)
            P = ca.vertcat(p, ca.vec(term.node_param_expr(*self._nodes(w), theta)))
            inputs = [w, p, theta]
        else:
            p = P = ca.MX.sym("p", nlp["p"].numel())
            inputs = [w, p]
        f = ca.Function("sqp_f", [nlp["x"], nlp["p"]], [nlp["f"]])(w, P)
        g = self._constraints(w, P)
        lbg, ubg = (ca.DM(b) for b in ocp.bounds()[2:])
        c = ca.vertcat(ca.fmax(lbg - g, 0), ca.fmax(g - ubg, 0))
        fn = BufferedFunction(ca.Function("sqp_merit", inputs, [f, ca.sum1(c), ca.mmax(c)]))
        self._merits[n_theta] = fn
        return fn

    def plan(self, x: np.ndarray, previous: Plan | None, step: int) -> tuple[Plan, dict[str, Any]]:
        """SQP iterations to convergence from ``previous`` shifted to period ``step``, or the
        converged IPOPT solve (cold start, a previous plan of another OCP, no convergence
        within the budget)."""
        warm = (previous is not None and isinstance(previous.solution, OCPSolution)
                and self.ocp.same_transcription(previous.solution)
                and step - previous.step == self.mesh.held_periods)
        if not warm:
            return Planner.plan(self, x, previous, step)
        assert previous is not None
        start = time.perf_counter()
        term: LearnedTerm = self.planning.term
        p = self.planning.param_values()
        theta = term.expansion_param_values() if term.n_node_params() else None
        merit_fn = self._merit_function(0 if theta is None else theta.size)

        def merit(w: np.ndarray) -> tuple[float, float, float]:
            out = merit_fn(w, p) if theta is None else merit_fn(w, p, theta)
            return float(out[0][0]), float(out[1][0]), float(out[2][0])

        w = np.asarray(self._shift(previous.solution.nlp_x, x), float).ravel()
        lam = self._multipliers(previous)
        lam_x = np.zeros(self.ocp.n_variables)
        nu, converged, k, error = 0.0, False, 0, 0.0
        f, l1, _ = merit(w)
        while k < self.sqp_iterations:
            try:
                out = self._iterate_outputs(x, w, lam)
            except RuntimeError:  # the QP plugin raised
                break
            k += 1
            self.counts.sqp_iterations += 1
            d = np.asarray(out[0], float).ravel() - w
            lam_qp, lam_x_qp = (np.asarray(a, float).ravel() for a in (out[3], out[4]))
            if not (np.all(np.isfinite(d)) and np.all(np.isfinite(lam_qp))):
                break
            if len(out) > 6:
                error = float(out[6][0])
            if np.max(np.abs(d)) <= self.tolerance:  # a KKT point to the QP's accuracy
                tf, tl1, tlinf = merit(w + d)
                if tlinf <= self.tolerance:
                    w, lam, lam_x, converged = w + d, lam_qp, lam_x_qp, True
                    break
            nu = max(nu, PENALTY_MARGIN * float(np.max(np.abs(lam_qp), initial=0.0)))
            phi = f + nu * l1
            # the step's predicted decrease: the QP's model of f plus the l1 violation it
            # removes (a lower bound on the directional derivative's magnitude)
            decrease = max(nu * l1, 0.0)
            alpha = 1.0
            while True:
                trial = w + alpha * d
                tf, tl1, _ = merit(trial)
                slack = ROUNDING * (1.0 + abs(phi))
                if np.isfinite(tf) and tf + nu * tl1 <= phi - ARMIJO * alpha * decrease + slack:
                    break
                if alpha <= MIN_STEP:
                    alpha = 0.0
                    break
                alpha *= 0.5
            if alpha == 0.0:
                break
            w, f, l1 = trial, tf, tl1
            lam = (1 - alpha) * lam + alpha * lam_qp
            lam_x = (1 - alpha) * lam_x + alpha * lam_x_qp
        elapsed = time.perf_counter() - start
        if not converged:
            self.counts.sqp_fallbacks += 1
            plan, record = Planner.plan(self, x, previous, step)
            record["solve_time"] += elapsed
            return plan, record
        sol = self.ocp.solution_from_primal(w, p, status="SQP converged", success=True,
                                            iterations=k, solve_time=elapsed,
                                            lam_x=lam_x, lam_g=lam)
        return Plan(sol, step, self.planning.model.dt, self.ocp.hold), dict(
            success=True, status=StepStatus.SOLVED, solver_status="SQP converged", capped=False,
            iterations=k, solve_time=elapsed, solves=1, fallback=False,
            linearization_error=float(error))
