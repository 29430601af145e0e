"""Real-time iteration split into a preparation and a feedback phase (acados' ``rti_phase``).

The one-call RTI (:class:`~gp_agents.mpc.rti.RTIPlanner`) does everything after the state is
measured: it shifts the plan, puts the measured state at X(t0), linearizes there (the learned
term's expansion included), solves the QP. Everything but the QP and the measured state can be
done *before* the measurement, in the time between sending a control and receiving the next
state. Split, as acados does it:

- **preparation** (:meth:`SplitRTIPlanner.prepare`, right after a plan is made): shift it to
  the next replanning period, keeping its own *predicted* X(t0); expand the learned term at
  the shifted plan's nodes and evaluate the QP's matrices and vectors there (the adjoint
  correction of a frozen term included); the previous feedback's expansion error; with an
  active-set QP (:class:`~gp_agents.mpc.active_set.ActiveSetQP`), the feedback's initial
  active set: that of the same QP's solution at the predicted state, so that the feedback
  needs one active-set iteration when the measurement matches the prediction (tested), and
  more only as far as the prediction error moves the set. It costs the preparation one QP
  solve. (Measured ad hoc on the Dubins vehicle's split RTI, seed 100, 149 feedback steps:
  from the shifted plan's set, the one-call step's guess, one iteration in 90 steps with the
  learned model (``linearized-pattern``) and 89 with the nominal one, the fallback QP in 2
  and 13; from the predicted set, one iteration in 147 and 75, the fallback in 0 and 1: the
  nominal model's predictions are further off.)
- **feedback** (:meth:`SplitRTIPlanner.plan`, when the state is measured): the QP with the
  measured state as the bound on X(t0) (``dw(t0) = x - X_pred(t0)``), the constraint check of
  the safety net, the action. Its time is the controller's latency.

What changes against the one-call RTI: the linearization point is the predicted, not the
measured, initial state (the QP's step from it is exact in X(t0)); and the learner update
with the newest sample happens in the preparation *after* it, so each QP plans with the
learner as it was one sample earlier. The safety net is the one-call RTI's. Every plan is
prepared for, a converged one (cold start, a rejected step's replacement) too; a step that
was not prepared for, or whose measured angles lie more than half a turn from the
prediction (counted in ``counts.unprepared`` when warm), takes the one-call path.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from typing import Any

import casadi as ca
import numpy as np

from gp_agents.mpc.active_set import ActiveSetQP
from gp_agents.mpc.diagnostics import StepStatus
from gp_agents.mpc.planner import Learn, Plan
from gp_agents.mpc.rti import STEP_OUTPUTS, RTIPlanner
from gp_agents.pseudospectral import BufferedFunction, OCPSolution

__all__ = ["SplitRTIPlanner"]


class SplitRTIPlanner(RTIPlanner):
    """:class:`RTIPlanner` with a preparation phase (:meth:`prepare`) and a feedback phase
    (:meth:`plan`); arguments as for :class:`RTIPlanner`.

    Its phases in the closed loop: :meth:`replan` is the feedback (the learner as it was after
    the last preparation), :meth:`after_action` learns the newest transitions and prepares the
    next replan. Counted in ``counts.prepared`` (feedback steps) and ``counts.unprepared`` (warm
    steps that took the one-call path).
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._prepares: dict[int, BufferedFunction] = {}
        self._errors: dict[int, BufferedFunction] = {}
        self._feedback, self._predict_active_set = self._build_feedback()
        self._prepared: dict[str, Any] | None = None

    # ------------------------------------------------------------------ the closed loop
    def replan(self, x: np.ndarray, previous: Plan | None, step: int, learn: Learn
               ) -> tuple[Plan, dict[str, Any]]:
        """The feedback phase (:meth:`plan`): the learner is updated after the action, in the
        preparation (:meth:`after_action`), not before the solve."""
        return self.plan(x, previous, step)

    def after_action(self, plan: Plan, record: Mapping[str, Any], learn: Learn
                     ) -> dict[str, Any]:
        """Learn the pending transitions, then the preparation of the next replan from
        ``plan`` (on the planner ``learn`` returns). Returns the record's
        ``preparation_time`` (s: the learning and the preparation) and, after an accepted
        RTI step, its ``linearization_error`` (the expansion error at the new plan)."""
        start = time.perf_counter()
        planner = learn()
        assert isinstance(planner, SplitRTIPlanner)
        info = planner.prepare(plan, plan.step + self.mesh.held_periods)
        out: dict[str, Any] = {}
        if record["status"] == StepStatus.RTI:
            out["linearization_error"] = info["linearization_error"]
        out["preparation_time"] = time.perf_counter() - start
        return out

    # ------------------------------------------------------------------ compiled phases
    def _prepare_function(self, n_theta: int) -> BufferedFunction:
        """``(w_prev, p[, theta[, lam_prev]]) -> (w_s, h, grad, a, g, P)``: the plan shifted
        with its predicted X(t0), the QP's Hessian and Jacobian nonzeros, gradient and
        constraint values there, and the NLP parameters (node parameters included)."""
        fn = self._prepares.get(n_theta)
        if fn is not None:
            return fn
        ocp, term = self.ocp, self.planning.term
        n, n_w = self.planning.model.n_states, ocp.n_variables
        lbx, ubx = (ca.DM(b) for b in ocp.bounds()[:2])
        w_prev = ca.MX.sym("w_prev", n_w)
        ws = ca.mtimes(self._shift_matrix, w_prev)
        ws = ca.vertcat(ws[:n], ca.fmin(ca.fmax(ws[n:], lbx[n:]), ubx[n:]))
        p_size = ocp.nlp["p"].numel()
        inputs, names = [w_prev], ["w_prev"]
        grad_offset: Any = ca.DM.zeros(n_w)
        if n_theta:
            M = ocp.node_indices()[0].shape[0]
            p = ca.MX.sym("p", p_size - M * term.n_node_params())
            theta = ca.MX.sym("theta", n_theta)
            expansion = term.node_expansion_expr(*self._nodes(ws), theta)
            Q = expansion["Q"]
            P_full = ca.vertcat(p, ca.vec(Q))
            inputs, names = [*inputs, p, theta], [*names, "p", "theta"]
            grad_offset, lam = self._gap_offset(ws, P_full, theta, n_theta, expansion)
            if lam is not None:
                inputs, names = [*inputs, lam], [*names, "lam_prev"]
        else:
            P_full = ca.MX.sym("p", p_size)
            inputs, names = [*inputs, P_full], [*names, "p"]
        g0, J0, grad0, H0 = self._derivatives(ws, P_full)
        fn = BufferedFunction(ca.Function(
            "rti_prepare", inputs, [ws, H0.nz[:], grad0 + grad_offset, J0.nz[:], g0, P_full],
            names, ["w_s", "h", "grad", "a", "g", "p_full"]))
        self._prepares[n_theta] = fn
        return fn

    def _error_function(self, n_theta: int) -> BufferedFunction:
        """``(w, P, theta) -> error``: the learned term's expansion error at the plan ``w``
        for the node parameters in ``P`` (:meth:`LearnedTerm.plan_error_expr`)."""
        fn = self._errors.get(n_theta)
        if fn is None:
            ocp, term = self.ocp, self.planning.term
            M = ocp.node_indices()[0].shape[0]
            n_q = term.n_node_params()
            w, theta = ca.MX.sym("w", ocp.n_variables), ca.MX.sym("theta", n_theta)
            P = ca.MX.sym("p", ocp.nlp["p"].numel())
            Q = ca.reshape(P[P.numel() - M * n_q:], n_q, M)
            fn = BufferedFunction(ca.Function(
                "rti_plan_error", [w, P, theta],
                [term.plan_error_expr(*self._nodes(w), Q, theta)]))
            self._errors[n_theta] = fn
        return fn

    def _build_feedback(self) -> tuple[BufferedFunction, BufferedFunction | None]:
        """The feedback, ``(w_s, x0, h, grad, a, g, P[, guess_x, guess_a]) -> (w, u,
        violation, lam_g, lam_x, qp_iterations)``: the QP from prepared data with X(t0) moved
        to the measured state (from the active-set guess ``guess_*`` with an active-set QP);
        and with an active-set QP the prediction of that guess, ``(w_s, h, grad, a, g, P) ->
        (guess_x, guess_a)``: the active set of the same QP's solution at the predicted
        state (else None)."""
        ocp = self.ocp
        n, n_w = self.planning.model.n_states, ocp.n_variables
        w_s = ca.MX.sym("w_s", n_w)
        P = ca.MX.sym("p", ocp.nlp["p"].numel())
        _, J_sym, _, H_sym = self._derivatives(w_s, P)
        x0 = ca.MX.sym("x0", n)
        h = ca.MX.sym("h", H_sym.nnz())
        a = ca.MX.sym("a", J_sym.nnz())
        grad, g0 = ca.MX.sym("grad", n_w), ca.MX.sym("g", ocp.nlp["g"].numel())
        H, J = ca.MX(H_sym.sparsity(), h), ca.MX(J_sym.sparsity(), a)
        inputs, names = [w_s, x0, h, grad, a, g0, P], ["w_s", "x0", "h", "grad", "a", "g", "p"]
        if not isinstance(self.qp_solver, ActiveSetQP):
            return BufferedFunction(ca.Function(
                "rti_feedback", inputs, self._qp_outputs(w_s, x0, H, grad, J, g0, P),
                names, list(STEP_OUTPUTS))), None
        guess = (ca.MX.sym("guess_x", n_w), ca.MX.sym("guess_a", g0.numel()))
        feedback = BufferedFunction(ca.Function(
            "rti_feedback", [*inputs, *guess], self._qp_outputs(w_s, x0, H, grad, J, g0, P,
                                                                guess),
            [*names, "guess_x", "guess_a"], list(STEP_OUTPUTS)))
        predicted = self._qp_outputs(w_s, w_s[:n], H, grad, J, g0, P)
        data = self._qp_data(w_s, w_s[:n], H, grad, J, g0)
        guess_out = self._active_at(data, predicted[0] - w_s)
        predict = BufferedFunction(ca.Function(
            "rti_predict_active_set", [w_s, h, grad, a, g0, P], list(guess_out),
            ["w_s", "h", "grad", "a", "g", "p"], ["guess_x", "guess_a"]))
        return feedback, predict

    # ------------------------------------------------------------------ the phases
    def prepare(self, previous: Plan, step: int) -> dict[str, float]:
        """The preparation phase for the replan at period ``step`` from ``previous`` (the plan
        just made); call it after updating the learner.

        Returns:
            ``preparation_time`` (s) and ``linearization_error``: the expansion error of
            ``previous`` if it came from a prepared feedback step (else NaN).
        """
        start = time.perf_counter()
        error = float("nan")
        done = self._prepared
        if done is not None and done.get("plan") is previous and done["n_theta"]:
            error = float(self._error_function(done["n_theta"])(
                previous.solution.nlp_x, done["p"], done["theta"])[0][0])
        self._prepared = None
        if not (isinstance(previous.solution, OCPSolution)
                and self.ocp.same_transcription(previous.solution)):
            return dict(preparation_time=time.perf_counter() - start, linearization_error=error)
        term = self.planning.term
        p = self.planning.param_values()
        w_prev = previous.solution.nlp_x
        if term.n_node_params():
            theta = term.expansion_param_values()
            fn = self._prepare_function(theta.size)
            args = [w_prev, p, theta]
            if fn.fn.n_in() == 4:
                args.append(self._multipliers(previous))
        else:
            theta = np.zeros(0)
            fn = self._prepare_function(0)
            args = [w_prev, p]
        ws, h, grad, a, g, P = fn(*args)
        guess: tuple[np.ndarray, ...] = ()
        if self._predict_active_set is not None:
            guess = tuple(self._predict_active_set(ws, h, grad, a, g, P))
        self._prepared = dict(previous=previous, step=step, w_s=ws, h=h, grad=grad, a=a, g=g,
                              p=P, guess=guess, p_nlp=p, theta=theta, n_theta=theta.size)
        return dict(preparation_time=time.perf_counter() - start, linearization_error=error)

    def plan(self, x: np.ndarray, previous: Plan | None, step: int) -> tuple[Plan, dict[str, Any]]:
        """The feedback phase if this step was prepared for (:meth:`prepare`), else the
        one-call RTI step (or a converged solve)."""
        prep, self._prepared = self._prepared, None
        if prep is None or prep["previous"] is not previous or prep["step"] != step:
            return self._one_call(x, previous, step)
        angles = list(self.planning.model.angle_indices)
        if angles and np.any(np.abs(x[angles] - prep["w_s"][angles]) > np.pi):
            return self._one_call(x, previous, step)
        start = time.perf_counter()
        out: tuple[np.ndarray, ...] | None
        try:
            out = self._feedback(prep["w_s"], x, prep["h"], prep["grad"], prep["a"], prep["g"],
                                 prep["p"], *prep["guess"])
        except RuntimeError:  # the QP plugin raised
            out = None
        self.counts.prepared += 1
        plan, record = self._accept(x, previous, step, out, prep["p_nlp"], float("nan"),
                                    time.perf_counter() - start)
        if record["status"] == StepStatus.RTI:
            prep["plan"] = plan
            self._prepared = prep  # kept for the expansion error at the next preparation
        return plan, record

    def _one_call(self, x: np.ndarray, previous: Plan | None, step: int
                  ) -> tuple[Plan, dict[str, Any]]:
        warm = previous is not None and step - previous.step == self.mesh.held_periods
        self.counts.unprepared += int(warm)
        return super().plan(x, previous, step)
