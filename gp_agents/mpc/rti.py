"""Real-time iteration: one Gauss-Newton SQP step of the OCP per control period.

Diehl's real-time iteration (RTI), as acados runs it: instead of solving the OCP to convergence
at every period, take *one* SQP step from the previous plan shifted in time. Between two periods
the OCP changes little (a new initial state, one period more of horizon), so one step of a
method that converges quadratically tracks the optimum; the first plan of an episode is a
converged solve. The step, from the shifted plan ``w_s`` (its X(t0) the measured state):

    min_dw  1/2 dw' H dw + grad f(w_s)' dw
    s.t.    lbg - g(w_s) <= J(w_s) dw <= ubg - g(w_s),   lbx <= w_s + dw <= ubx

with ``H`` the Hessian of the objective alone (Gauss-Newton: the stage, terminal and soft-box
costs are sums of squares of functions that are linear between kinks, so ``H`` is positive
semidefinite and the QP convex; the one exception is the soft obstacle margin,
``(O_r + B_r + margin - |p - c|)^2`` while the plan is inside it, whose Hessian has a negative
part from the curvature of ``|p - c|``: there the QP is nonconvex, which is why the Dubins
vehicle's QP fallback is the interior-point piqp, robust on those steps). A
Levenberg-Marquardt term (``levenberg_marquardt``, ``H + mu I``) is the option for the
iteration's own weak spots: near ``v = 0`` the Dubins vehicle's heading rate does not act on
the position, the plain step can then alternate between two plans (turning left, then right)
and never settle. The QP is solved
by :class:`~gp_agents.mpc.active_set.ActiveSetQP` from the shifted plan's active set (or by
a CasADi conic plugin alone, ``qp_solver``). The whole warm
step (shift, angle alignment, fixing X(t0), the QP, the action) is one compiled CasADi
function; Python passes the state and the learned term's numbers in, and gets the plan out.

A learned term enters as its per-node linearization at the shifted plan
(:class:`~gp_agents.mpc.gp_linearized.LinearizedGP`: values and Jacobians as NLP parameters), so
the QP has the nominal structure and the learner is evaluated once per node per period. The
expansion and its error at the new plan are part of the same compiled function, computed from
the learner's exported parameters (its ``casadi_param_values``), so Python passes the state,
the model's parameters and the learner's numbers in.

**Safety net.** A step whose QP fails (a non-finite result, or the QP plugin raised) or whose
plan violates the NLP's constraints by more than ``max_violation`` (defects in state units,
path constraints in theirs, infinity norm) is replaced by a converged solve from the same
shifted plan and the previous step's multipliers (the QP's, an SQP step's estimate of the
NLP's) with IPOPT's warm-start options (the :class:`~gp_agents.mpc.planner.Planner`'s solve,
with its retry and fallback to the previous plan). Before that, with a recovery budget
(``recovery_iterations``), the step may be recovered inside the real-time scheme by
feasibility projections and SQP iterations (:meth:`RTIPlanner._recover`).
Every such step is counted (the planner's ``counts``: ``rti_rejected``,
``rti_recovered``). No wall-clock limit anywhere.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

import casadi as ca
import numpy as np

from gp_agents.mpc.active_set import ActiveSetQP
from gp_agents.mpc.diagnostics import StepStatus
from gp_agents.mpc.learned_term import LearnedTerm
from gp_agents.mpc.ocp import Constraints, Mesh
from gp_agents.mpc.planner import Plan, Planner
from gp_agents.mpc.planning_model import PlanningModel
from gp_agents.pseudospectral import BufferedFunction, OCPSolution

__all__ = ["ACTIVE_SET_PREFIX", "QP_SOLVER_OPTIONS", "STEP_OUTPUTS", "RTIPlanner",
           "check_levenberg_marquardt", "resolve_qp_solver"]

QP_SOLVER_OPTIONS: dict[str, dict[str, Any]] = {
    "osqp": {"osqp": {"verbose": False, "eps_abs": 1e-6, "eps_rel": 1e-6,
                      "max_iter": 10000, "polish": True}, "warm_start_primal": True},
    "proxqp": {"proxqp": {"eps_abs": 1e-6, "max_iter": 10000, "verbose": False}},
    "qrqp": {"print_iter": False, "print_header": False, "print_info": False},
    "hpipm": {"hpipm": {"iter_max": 100, "tol_stat": 1e-8, "tol_eq": 1e-8, "tol_ineq": 1e-8,
                        "tol_comp": 1e-8}},
    "piqp": {"piqp": {"eps_abs": 1e-8, "eps_rel": 1e-9, "max_iter": 250, "verbose": False}},
    "qpoases": {"printLevel": "none", "sparse": True},
}
"""QP options per solver: tolerances tight enough that the step is the QP's solution (the
iteration caps are counts, so the step is deterministic)."""

STEP_OUTPUTS = ("w", "u", "violation", "lam_g", "lam_x", "qp_iterations")
RECOVERY_CONTRACTION = 0.5
"""A recovery projection must at least halve the constraint violation, else the recovery
stops (the linearized constraints cannot be met near the step: the converged fallback)."""
"""The outputs of a compiled RTI step, in order: the new NLP point, the action, the NLP's
constraint violation there, the QP's multipliers and the active-set iterations."""

ACTIVE_SET_PREFIX = "active-set:"
"""A QP solver name ``"active-set:<plugin>"`` is :class:`~gp_agents.mpc.active_set.ActiveSetQP`
from the shifted plan's active set, with the CasADi ``<plugin>`` as its fallback."""


def resolve_qp_solver(qp_solver: str | ActiveSetQP,
                      qp_options: Mapping[str, Any] | None = None) -> str | ActiveSetQP:
    """A CasADi conic plugin name (checked), or the :class:`ActiveSetQP` a name
    ``"active-set:<plugin>"`` (or an instance) stands for.

    Raises:
        ValueError: an unknown plugin.
    """
    if isinstance(qp_solver, ActiveSetQP):
        return qp_solver
    name = str(qp_solver)
    if name.startswith(ACTIVE_SET_PREFIX):
        fallback = name[len(ACTIVE_SET_PREFIX):]
        options = QP_SOLVER_OPTIONS.get(fallback, {}) if qp_options is None else qp_options
        return ActiveSetQP(fallback, options)
    if not ca.has_conic(name):
        raise ValueError(f"CasADi QP solver plugin {name!r} is not available (or name "
                         f"{ACTIVE_SET_PREFIX}<plugin> for the active-set solve)")
    return name


def check_levenberg_marquardt(mu: float) -> float:
    """``mu`` as a float, checked: the RTI's Levenberg-Marquardt term is finite and >= 0.

    Raises:
        ValueError: a negative, NaN or infinite ``mu``.
    """
    mu = float(mu)
    if not (np.isfinite(mu) and mu >= 0):
        raise ValueError(f"levenberg_marquardt must be a finite number >= 0, got {mu}")
    return mu


class RTIPlanner(Planner):
    """A :class:`Planner` that takes one SQP step per period from the shifted previous plan.

    Args:
        planning, mesh, constraints: as for :class:`Planner`.
        qp_solver: the step's QP solver: a CasADi conic plugin (``"osqp"``, ``"proxqp"``,
            ``"piqp"``, ...), or ``"active-set:<plugin>"`` / an
            :class:`~gp_agents.mpc.active_set.ActiveSetQP` (primal-dual active-set iterations
            from the shifted plan's active set, that plugin as the fallback); chosen per
            system by measurement, :func:`gp_agents.defaults.default_planning`.
        qp_options: CasADi options of the plugin (default :data:`QP_SOLVER_OPTIONS`).
        max_violation: largest constraint violation of an accepted step (see module doc).
        levenberg_marquardt: ``mu`` >= 0 added to the QP Hessian's diagonal (``H + mu I``, as
            acados' ``levenberg_marquardt``): it shortens the steps where ``H`` is singular or
            indefinite and damps an iteration that alternates between two plans; it does not
            move the fixed points (a KKT point of the OCP is still one, ``dw = 0``). 0 (the
            default): the plain Gauss-Newton step.
        **settings: the converged solver's settings (:class:`Planner`).
    """

    def __init__(self, planning: PlanningModel, mesh: Mesh, constraints: Constraints, *,
                 qp_solver: str | ActiveSetQP = "proxqp",
                 qp_options: Mapping[str, Any] | None = None,
                 max_violation: float = 1e-2, levenberg_marquardt: float = 0.0,
                 recovery_iterations: int = 0, **settings: Any) -> None:
        settings.setdefault("warm_start_duals", True)
        super().__init__(planning, mesh, constraints, **settings)
        solver = resolve_qp_solver(qp_solver, qp_options)
        if not (np.isfinite(max_violation) and max_violation > 0):
            raise ValueError(f"max_violation must be > 0, got {max_violation}")
        self.qp_solver, self.max_violation = solver, float(max_violation)
        self.levenberg_marquardt = check_levenberg_marquardt(levenberg_marquardt)
        options: dict[str, Any] = {}
        if isinstance(solver, str):
            options = dict(QP_SOLVER_OPTIONS.get(solver, {}) if qp_options is None
                           else qp_options)
            options.setdefault("error_on_fail", False)
        self._qp_options = options
        self._shift, self._qp_step, step = self._build(options)
        self._step = BufferedFunction(step)
        self._learned_steps: dict[tuple[int, bool], BufferedFunction] = {}
        self._iterate: BufferedFunction | None = None
        self._projections: dict[int, BufferedFunction] = {}
        if isinstance(recovery_iterations, bool) or int(recovery_iterations) < 0:
            raise ValueError(f"recovery_iterations must be an int >= 0, got "
                             f"{recovery_iterations!r}")
        self.recovery_iterations = int(recovery_iterations)

    def _build(self, qp_options: dict[str, Any]) -> tuple[ca.Function, ca.Function, ca.Function]:
        ocp, model = self.ocp, self.planning.model
        nlp = ocp.nlp
        w, P, f, g = nlp["x"], nlp["p"], nlp["f"], nlp["g"]
        n, N, n_w = model.n_states, ocp.n_points, ocp.n_variables
        lbx, ubx = (ca.DM(b) for b in ocp.bounds()[:2])
        H = ca.hessian(f, w)[0]
        if self.levenberg_marquardt > 0:
            H = H + self.levenberg_marquardt * ca.DM.eye(n_w)
        J = ca.jacobian(g, w)
        derivatives = ca.Function("rti_derivatives", [w, P],
                                  [g, J, ca.gradient(f, w), H]).expand()
        constraints = ca.Function("rti_g", [w, P], [g]).expand()
        self._derivatives, self._constraints = derivatives, constraints

        # the shift: interpolants at the shifted times, angles moved by 2 pi k to start at the
        # measured ones, clipped into the bounds, X(t0) the measured state
        w_prev, x0 = ca.MX.sym("w_prev", n_w), ca.MX.sym("x0", n)
        dt = self.mesh.held_periods * model.dt
        self._shift_matrix = ca.DM(ca.sparsify(ca.DM(ocp.shift_operator(dt))))
        ws = ca.mtimes(self._shift_matrix, w_prev)
        for i in model.angle_indices:
            turns = ca.floor((x0[i] - ws[i]) / (2 * np.pi) + 0.5)
            mask = np.zeros(n_w)
            mask[[j * n + i for j in range(N)]] = 1.0
            ws = ws + 2 * np.pi * turns * ca.DM(mask)
        ws = ca.vertcat(x0, ca.fmin(ca.fmax(ws[n:], lbx[n:]), ubx[n:]))
        shift = ca.Function("rti_shift", [w_prev, x0], [ws], ["w_prev", "x0"], ["w"])
        # no time shift (iterate): X(t0) the measured state, the rest clipped into the bounds
        self._fix_x0 = ca.Function(
            "rti_fix_x0", [w_prev, x0], [ca.vertcat(x0, ca.fmin(ca.fmax(w_prev[n:], lbx[n:]),
                                                              ubx[n:]))], ["w_prev", "x0"], ["w"])
        if isinstance(self.qp_solver, ActiveSetQP):
            self._qp = self.qp_solver.function(H.sparsity(), J.sparsity())
        else:
            self._qp = ca.conic("rti_qp", self.qp_solver,
                                {"h": H.sparsity(), "a": J.sparsity()}, qp_options)

        # the Gauss-Newton QP step and what it gives (grad_offset: an adjoint correction)
        w_s, p = ca.MX.sym("w_s", n_w), ca.MX.sym("p", P.numel())
        grad_offset = ca.MX.sym("grad_offset", n_w)
        g0, J0, grad0, H0 = derivatives(w_s, p)
        outputs = self._qp_outputs(w_s, w_s[:n], H0, grad0 + grad_offset, J0, g0, p)
        names = list(STEP_OUTPUTS)
        qp_step = ca.Function("rti_qp_step", [w_s, p, grad_offset], outputs,
                              ["w_s", "p", "grad_offset"], names)
        step = ca.Function("rti_step", [w_prev, x0, p], qp_step(ws, p, ca.DM.zeros(n_w)),
                           ["w_prev", "x0", "p"], names)
        return shift, qp_step, step

    def _qp_data(self, w_s: ca.MX, x0: ca.MX, H: ca.MX, grad: ca.MX, J: ca.MX,
                 g0: ca.MX) -> dict[str, ca.MX]:
        """The Gauss-Newton QP in the step ``dw`` about ``w_s`` (Hessian ``H``, gradient
        ``grad``, constraint Jacobian ``J`` and values ``g0`` there, X(t0) fixed to ``x0``)
        as CasADi conic data (``h, g, a, lba, uba, lbx, ubx``)."""
        ocp, n = self.ocp, self.planning.model.n_states
        lbx, ubx, lbg, ubg = (ca.DM(b) for b in ocp.bounds())
        lo, hi = ca.vertcat(x0, lbx[n:]), ca.vertcat(x0, ubx[n:])
        return dict(h=H, g=grad, a=J, lba=lbg - g0, uba=ubg - g0, lbx=lo - w_s, ubx=hi - w_s)

    def _active_at(self, data: dict[str, ca.MX], dw: ca.MX | None = None
                   ) -> tuple[ca.MX, ca.MX]:
        """The active-set guess ``(guess_x, guess_a)`` of the QP ``data``: the bounds the
        step ``dw`` (default 0: the shifted plan itself) sits at, within the active-set
        solver's tolerance, and the rows its constraint values sit at (-1 lower, +1 upper)."""
        assert isinstance(self.qp_solver, ActiveSetQP)
        tol = self.qp_solver.tol
        if dw is None:
            return ((data["ubx"] <= tol) - (data["lbx"] >= -tol),
                    (data["uba"] <= tol) - (data["lba"] >= -tol))
        r = ca.mtimes(data["a"], dw)
        return ((data["ubx"] - dw <= tol) - (data["lbx"] - dw >= -tol),
                (data["uba"] - r <= tol) - (data["lba"] - r >= -tol))

    def _qp_outputs(self, w_s: ca.MX, x0: ca.MX, H: ca.MX, grad: ca.MX, J: ca.MX, g0: ca.MX,
                    P: ca.MX, guess: tuple[ca.MX, ca.MX] | None = None,
                    qp: ca.Function | None = None) -> list[ca.MX]:
        """The QP of :meth:`_qp_data` solved symbolically, and what it gives:
        :data:`STEP_OUTPUTS` (the active-set iterations are 0 when it fell back, -1 for a
        plain plugin). ``guess``: the active-set solver's initial ``(guess_x, guess_a)``
        (default: the bounds and rows the shifted plan sits at, :meth:`_active_at`)."""
        ocp = self.ocp
        lbg, ubg = (ca.DM(b) for b in ocp.bounds()[2:])
        data = self._qp_data(w_s, x0, H, grad, J, g0)
        qp = self._qp if qp is None else qp
        if isinstance(self.qp_solver, ActiveSetQP):
            guess_x, guess_a = guess if guess is not None else self._active_at(data)
            res = qp(**data, guess_x=guess_x, guess_a=guess_a)
            iterations = res["iterations"]
        else:
            res = qp(**data, x0=ca.DM.zeros(ocp.n_variables))
            iterations = ca.MX(-1)
        w_new = w_s + res["x"]
        g_new = self._constraints(w_new, P)
        violation = ca.mmax(ca.vertcat(ca.fmax(lbg - g_new, 0), ca.fmax(g_new - ubg, 0)))
        action = w_new[ocp.control_decision(ocp.decision_of_node(0))]
        return [w_new, action, violation, res["lam_a"], res["lam_x"], iterations]

    def _nodes(self, w: ca.MX) -> tuple[ca.MX, ca.MX]:
        """Node states (n, M) and controls (m, M) of the NLP point ``w``."""
        ix, iu = self.ocp.node_indices()
        n, m = self.planning.model.n_states, self.planning.model.n_controls
        M = ix.shape[0]
        return (ca.reshape(w[ix.ravel().tolist()], n, M),
                ca.reshape(w[iu.ravel().tolist()], m, M))

    def _gap_offset(self, ws: ca.MX, P_full: ca.MX, theta: ca.MX, n_theta: int,
                    expansion: dict[str, Any] | None = None) -> tuple[Any, ca.MX | None]:
        """The adjoint correction of the QP's gradient at ``ws`` for a term with a Jacobian
        gap, ``(J_exact - J_nlp)' lam_prev``, and the symbol of the previous multipliers it
        reads; zeros and None for any other term. ``expansion``: the term's expansion at
        ``ws`` (:meth:`LearnedTerm.node_expansion_expr`), from which a term computes the gap's
        gradient at the nodes without evaluating the learner again
        (:meth:`LearnedTerm.jacobian_gap_nodes_expr`); else (or for a term without that) the
        gradient of :meth:`LearnedTerm.jacobian_gap_expr` by AD."""
        ocp, term = self.ocp, self.planning.term
        M, d = ocp.node_indices()[0].shape[0], term.residual.n_outputs
        n_q = term.n_node_params()
        w_sym, t_sym, mu_sym = (ca.MX.sym("w", ocp.n_variables), ca.MX.sym("theta", n_theta),
                                ca.MX.sym("mu", d, M))
        q_sym = ca.MX.sym("q", n_q, M)
        gap = term.jacobian_gap_expr(*self._nodes(w_sym), t_sym, mu_sym, q_sym)
        if gap is None:
            return ca.DM.zeros(ocp.n_variables), None
        # mu_k = (dg/dq_k)' lam: the multipliers' weight on node k's learned rates
        nlp = ocp.nlp
        lam_sym = ca.MX.sym("lam", nlp["g"].numel())
        adjoint = ca.Function("rti_param_adjoint", [nlp["x"], nlp["p"], lam_sym],
                              [ca.gradient(ca.dot(lam_sym, nlp["g"]), nlp["p"])]).expand()
        lam_prev = ca.MX.sym("lam_prev", nlp["g"].numel())
        tail = adjoint(ws, P_full, lam_prev)[P_full.numel() - M * n_q:]
        mu = ca.reshape(tail, n_q, M)[:d, :]
        Q = ca.reshape(P_full[P_full.numel() - M * n_q:], n_q, M)
        nodes = (None if expansion is None
                 else term.jacobian_gap_nodes_expr(expansion, mu, Q))
        if nodes is not None:  # (n + m, M) at the nodes, placed into w
            return ca.mtimes(self._node_scatter(), ca.vec(nodes)), lam_prev
        gap_gradient = ca.Function("rti_jacobian_gap", [w_sym, t_sym, mu_sym, q_sym],
                                   [ca.gradient(gap, w_sym)])
        return gap_gradient(ws, theta, mu, Q), lam_prev

    def _node_scatter(self) -> ca.DM:
        """The (n_w, (n + m) M) 0/1 matrix that adds node k's ``[x; u]`` entries (column block
        k) into their NLP variables: the transpose of :meth:`_nodes`' selection."""
        ix, iu = self.ocp.node_indices()
        n, m = self.planning.model.n_states, self.planning.model.n_controls
        M = ix.shape[0]
        rows = np.hstack([ix, iu]).ravel()  # node k's [x; u] indices, node after node
        return ca.DM(ca.Sparsity.triplet(self.ocp.n_variables, (n + m) * M,
                                         [int(r) for r in rows], list(range((n + m) * M))), 1.0)

    def _learned_step(self, n_theta: int, shift: bool = True) -> BufferedFunction:
        """The warm step with a node-parameter term (built once per learner size ``n_theta``):
        ``(w_prev, x0, p, theta[, lam_prev]) -> (w, u, violation, lam_g, lam_x, qp_iterations,
        linearization_error)``.
        Inside: the shift, the term's expansion at the shifted plan's nodes from the
        learner's parameters theta, the QP step, and the expansion's error at the new plan.
        For a term with a Jacobian gap (:meth:`LearnedTerm.jacobian_gap_expr`, a frozen
        value) also ``lam_prev``, the previous plan's constraint multipliers (n_g,), and the
        QP's gradient gets the adjoint correction ``(J_exact - J_nlp)' lam_prev``.
        ``shift=False``: from ``w_prev`` itself (:meth:`iterate`)."""
        step = self._learned_steps.get((n_theta, shift))
        if step is not None:
            return step
        ocp, term = self.ocp, self.planning.term
        n = self.planning.model.n_states
        M = ocp.node_indices()[0].shape[0]
        w_prev, x0 = ca.MX.sym("w_prev", ocp.n_variables), ca.MX.sym("x0", n)
        p, theta = ca.MX.sym("p", ocp.nlp["p"].numel() - M * term.n_node_params()), \
            ca.MX.sym("theta", n_theta)
        ws = (self._shift if shift else self._fix_x0)(w_prev, x0)
        expansion = term.node_expansion_expr(*self._nodes(ws), theta)
        Q = expansion["Q"]
        P_full = ca.vertcat(p, ca.vec(Q))
        inputs, names = [w_prev, x0, p, theta], ["w_prev", "x0", "p", "theta"]
        grad_offset, lam_prev = self._gap_offset(ws, P_full, theta, n_theta, expansion)
        if lam_prev is not None:
            inputs, names = [*inputs, lam_prev], [*names, "lam_prev"]
        out = self._qp_step(ws, P_full, grad_offset)
        error = term.plan_error_expr(*self._nodes(out[0]), Q, theta)
        step = ca.Function("rti_learned_step", inputs, [*out, error], names,
                           [*STEP_OUTPUTS, "linearization_error"])
        self._learned_steps[n_theta, shift] = BufferedFunction(step)
        return self._learned_steps[n_theta, shift]

    def _projection_step(self, n_theta: int) -> BufferedFunction:
        """The feasibility projection from an NLP point (built once per learner size):
        ``(w, x0, p[, theta]) -> STEP_OUTPUTS``: X(t0) set to ``x0``, the rest clipped into the
        bounds, the learned term expanded there (with ``n_theta`` > 0), and the QP of the
        real-time iteration's constraints with the objective replaced by the step's length,
        ``min 1/2 |dw|^2`` over the linearized constraints and bounds (the minimum-norm
        Gauss-Newton step on the constraints: convex whatever the objective's Hessian, and
        quadratically convergent to a feasible point near ``w``; the objective is left to the
        next period's step)."""
        fn = self._projections.get(n_theta)
        if fn is not None:
            return fn
        ocp, term = self.ocp, self.planning.term
        n = self.planning.model.n_states
        w, x0 = ca.MX.sym("w", ocp.n_variables), ca.MX.sym("x0", n)
        ws = self._fix_x0(w, x0)
        if n_theta:
            M = ocp.node_indices()[0].shape[0]
            p = ca.MX.sym("p", ocp.nlp["p"].numel() - M * term.n_node_params())
            theta = ca.MX.sym("theta", n_theta)
            Q = term.node_param_expr(*self._nodes(ws), theta)
            P_full = ca.vertcat(p, ca.vec(Q))
            inputs, names = [w, x0, p, theta], ["w_in", "x0", "p", "theta"]
        else:
            p = P_full = ca.MX.sym("p", ocp.nlp["p"].numel())
            inputs, names = [w, x0, p], ["w_in", "x0", "p"]
        g0, J0 = self._derivatives(ws, P_full)[:2]
        n_w = ocp.n_variables
        eye = ca.DM.eye(n_w)
        if isinstance(self.qp_solver, ActiveSetQP):
            qp = self.qp_solver.function(eye.sparsity(), J0.sparsity())
        else:
            qp = ca.conic("rti_projection_qp", self.qp_solver,
                          {"h": eye.sparsity(), "a": J0.sparsity()}, self._qp_options)
        out = self._qp_outputs(ws, x0, ca.MX(eye), ca.MX.zeros(n_w), J0, g0, P_full, qp=qp)
        outputs = list(STEP_OUTPUTS)
        if n_theta:  # the expansion's error at the projected plan
            out.append(term.plan_error_expr(*self._nodes(out[0]), Q, theta))
            outputs.append("linearization_error")
        fn = BufferedFunction(ca.Function("rti_projection", inputs, out, names, outputs))
        self._projections[n_theta] = fn
        return fn

    def _project_outputs(self, x: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, ...]:
        """One feasibility projection (:meth:`_projection_step`) from ``w`` with X(t0) at
        ``x``."""
        term: LearnedTerm = self.planning.term
        p = self.planning.param_values()
        if term.n_node_params():
            theta = term.expansion_param_values()
            return tuple(self._projection_step(theta.size)(w, x, p, theta))
        return tuple(self._projection_step(0)(w, x, p))

    def _iterate_outputs(self, x: np.ndarray, w: np.ndarray, lam_g: np.ndarray | None
                         ) -> tuple[np.ndarray, ...]:
        """The compiled SQP iteration of :meth:`iterate`: :data:`STEP_OUTPUTS` and, with a
        node-parameter term, the expansion error at the new point."""
        term: LearnedTerm = self.planning.term
        p = self.planning.param_values()
        n_g = self.ocp.nlp["g"].numel()
        lam = np.zeros(n_g) if lam_g is None else np.asarray(lam_g, float)
        if term.n_node_params():
            theta = term.expansion_param_values()
            step = self._learned_step(theta.size, shift=False)
            args = [w, x, p, theta] + ([lam] if step.fn.n_in() == 5 else [])
            return tuple(step(*args))
        if self._iterate is None:
            w_in, x_in = ca.MX.sym("w", self.ocp.n_variables), ca.MX.sym("x0", x.size)
            p_in = ca.MX.sym("p", self.ocp.nlp["p"].numel())
            self._iterate = BufferedFunction(ca.Function(
                "rti_iterate", [w_in, x_in, p_in],
                self._qp_step(self._fix_x0(w_in, x_in), p_in,
                              ca.DM.zeros(self.ocp.n_variables))))
        return tuple(self._iterate(w, x, p))

    def iterate(self, x: np.ndarray, w: np.ndarray, lam_g: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray, float]:
        """One Gauss-Newton SQP step of this period's OCP from the NLP point ``w`` (n_w,),
        without the time shift: X(t0) set to ``x`` (n,), the rest clipped into the bounds,
        the learned term expanded there. A fixed point (``w`` returned unchanged, with the
        multipliers it was given) is a KKT point of the OCP. For checking convergence; the
        controller calls :meth:`plan`.

        Args:
            x: (n,) the initial state.
            w: (n_w,) the NLP point.
            lam_g: (n_g,) constraint multipliers of the previous step (a term with a Jacobian
                gap reads them; default zeros).

        Returns:
            The new point (n_w,), its QP's constraint multipliers (n_g,) and the NLP's
            constraint violation there.
        """
        out = self._iterate_outputs(x, w, lam_g)
        return out[0], out[3], float(out[2][0])

    def plan(self, x: np.ndarray, previous: Plan | None, step: int) -> tuple[Plan, dict[str, Any]]:
        """One SQP step from ``previous`` shifted to period ``step``, or a converged solve
        (cold start, a previous plan that is not this OCP's, or a rejected step)."""
        periods = self.mesh.held_periods
        warm = (previous is not None and isinstance(previous.solution, OCPSolution)
                and self.ocp.same_transcription(previous.solution)
                and step - previous.step == periods)
        if not warm:
            return super().plan(x, previous, step)
        start = time.perf_counter()
        term: LearnedTerm = self.planning.term
        p = self.planning.param_values()
        w_prev = previous.solution.nlp_x
        error = 0.0
        out: tuple[np.ndarray, ...] | None
        try:
            if term.n_node_params():
                theta = term.expansion_param_values()
                learned = self._learned_step(theta.size)
                args = [w_prev, x, p, theta]
                if learned.fn.n_in() == 5:  # a Jacobian gap: the previous multipliers
                    args.append(self._multipliers(previous))
                out = learned(*args)
                error = float(out[6][0])
            else:
                out = self._step(w_prev, x, p)
        except RuntimeError:  # the QP plugin raised (e.g. osqp's "Problem in osqp_update_P_A")
            out = None
        return self._accept(x, previous, step, out, p, error, time.perf_counter() - start)

    def _multipliers(self, previous: Plan) -> np.ndarray:
        """``previous``'s constraint multipliers (n_g,), zeros if it has none (finite)."""
        lam = previous.solution.nlp_lam_g
        if lam is None or not np.all(np.isfinite(lam)):
            return np.zeros(self.ocp.nlp["g"].numel())
        return lam

    def _accept(self, x: np.ndarray, previous: Plan, step: int,
                out: tuple[np.ndarray, ...] | None, p: np.ndarray, error: float,
                elapsed: float) -> tuple[Plan, dict[str, Any]]:
        """The safety net on a step's outputs ``(w, u, violation, lam_g, lam_x,
        qp_iterations, ...)`` (None: the QP plugin raised): the step's plan, or the converged
        solve that replaces a rejected one."""
        if out is None:
            w_new, violation = np.full(self.ocp.n_variables, np.nan), np.inf
            lam_g = lam_x = w_new
        else:
            w_new, _, violation, lam_g, lam_x, qp_iterations = out[:6]
            violation = float(violation[0])
            self.counts.qp_fallbacks += int(qp_iterations[0] == 0)
        self.counts.rti_steps += 1
        recovered = 0
        attempted = bool(np.isfinite(violation) and violation > self.max_violation
                         and self.recovery_iterations and np.all(np.isfinite(w_new)))
        if attempted:
            assert out is not None
            began = time.perf_counter()
            out, recovered, error = self._recover(x, out, error)
            w_new, _, violation = out[:3]  # the step's multipliers stay the estimate
            violation = float(violation[0])
            elapsed += time.perf_counter() - began
        if not (np.all(np.isfinite(w_new)) and violation <= self.max_violation) or (
                attempted and not recovered):
            self.counts.rti_rejected += 1
            plan, record = super().plan(x, previous, step)
            record["solve_time"] += elapsed
            record["status"] = StepStatus.RTI_REJECTED
            return plan, record
        status = StepStatus.RTI_RECOVERED if recovered else StepStatus.RTI
        self.counts.rti_recovered += int(recovered > 0)
        self.counts.recovery_iterations += recovered
        sol = self.ocp.solution_from_primal(w_new, p, status=str(status), success=True,
                                            iterations=1 + recovered, solve_time=elapsed,
                                            lam_x=lam_x, lam_g=lam_g)
        return Plan(sol, step, self.planning.model.dt, self.ocp.hold), dict(
            success=True, status=status, solver_status=str(status), capped=False,
            iterations=1 + recovered, solve_time=elapsed, solves=1, fallback=False,
            linearization_error=float(error))

    def _recover(self, x: np.ndarray, out: tuple[np.ndarray, ...], error: float
                 ) -> tuple[tuple[np.ndarray, ...], int, float]:
        """Recover a step ``out`` whose constraint violation is too large inside the real-time
        scheme, within :attr:`recovery_iterations` QP solves (an iteration count, never a
        time): while the point violates, a feasibility projection (:meth:`_projection_step`:
        X(t0) the measured state ``x``, the learned term re-expanded there, the QP without the
        objective, i.e. a minimum-norm Newton step on the linearized constraints), which must
        contract the violation by :data:`RECOVERY_CONTRACTION` (else the linearized
        constraints cannot be met near the step: the converged fallback); from a feasible
        point, an SQP iteration (the objective's share, the learned term re-expanded there).
        The step is recovered at the first SQP iteration that ends within tolerance; one that
        does not is projected again, and when the budget ends there, that feasible projection
        of an SQP iteration is the recovered point (an SQP step with its feasibility
        correction). A feasible point that no SQP iteration preceded is never the plan: it
        forgets the objective, and its action can be far from any plan's (a quadrotor from a
        perturbed start can flip over on one).

        Returns:
            The outputs (:data:`STEP_OUTPUTS`) of the last point reached, the QP solves taken
            when it is recovered (0 otherwise: the caller rejects the step) and the expansion
            error at the recovered point (``error`` unchanged without a learned term, or when
            not recovered).
        """
        lam_g = np.asarray(out[3]).ravel()
        violation, k, objective = float(out[2][0]), 0, False
        while k < self.recovery_iterations:
            if violation > self.max_violation:  # a projection towards feasibility
                try:
                    nxt = self._project_outputs(x, np.asarray(out[0]).ravel())
                except RuntimeError:  # the QP plugin raised
                    break
                k += 1
                now = float(nxt[2][0])
                if not (np.all(np.isfinite(nxt[0])) and now < RECOVERY_CONTRACTION * violation):
                    break  # no Newton-like contraction: the linearized constraints cannot be met
                out, violation = nxt, now
                continue
            # from a feasible point: the SQP iteration (the objective's share)
            try:
                step = self._iterate_outputs(x, np.asarray(out[0]).ravel(), lam_g)
            except RuntimeError:
                break
            k += 1
            if not np.all(np.isfinite(step[0])):
                break
            out, violation, objective = step, float(step[2][0]), True
            lam_g = np.asarray(step[3]).ravel()
            if violation <= self.max_violation:
                break
        if objective and violation <= self.max_violation:
            return out, k, (float(out[6][0]) if len(out) > 6 else error)
        return out, 0, error
