"""Solving the MPC's OCP robustly: warm start, re-linearization, retry and fallback.

:class:`Planner` turns a measured state into a :class:`Plan`. It builds the transcribed OCP
once (:func:`gp_agents.mpc.ocp.build_ocp`; again only if the learned term's parameter layout
changes) and at every call

1. warm-starts from the previous plan shifted by the time elapsed since it was made, its angles
   moved by multiples of 2 pi to start at the measured ones (cold start: a straight line in
   state space to the goal, which keeps a swing-up out of the "stay put" local minimum);
2. solves, as often as the learned term asks (:meth:`LearnedTerm.solves`: re-linearizations),
   each solve's plan becoming the next one's reference;
3. if no solve succeeded: retries once from the cold-start guess; if that fails too, keeps the
   previous plan while it covers the current time (a *fallback*), else the last finite iterate,
   else a constant plan at the task's reference control.

Every replan's record says what happened in :class:`~gp_agents.mpc.diagnostics.StepStatus`
terms; the counts since the agent was built are one
:class:`~gp_agents.mpc.diagnostics.SolveCounts` that every planner of an agent shares.

A planner owns its phases (:meth:`Planner.replan`, :meth:`Planner.after_action`): when the
learner's pending transitions are learned relative to the solve, and any work done after the
action is sent (the split real-time iteration's preparation).

Solves are capped by iterations only (IPOPT ``max_iter``), never by wall-clock time, so what the
controller does is a function of its inputs, not of the machine's load.

:meth:`Plan.action` is the control the plant holds over a period: the held decision where the
period is a held interval of the plan (always, except in a fallback), else the plan's mean
control over the period (5-point Gauss quadrature of the interpolant), clipped to the bounds.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from gp_agents.mpc.diagnostics import SolveCounts, StepStatus
from gp_agents.mpc.ocp import Constraints, Mesh, build_ocp
from gp_agents.mpc.planning_model import PlanningModel
from gp_agents.pseudospectral import (
    IPOPT_WARM_START_OPTIONS,
    GaussPseudospectralSolver,
    InitialGuess,
    OCPSolution,
)

__all__ = ["CAPPED_STATUSES", "Learn", "Plan", "Planner"]

CAPPED_STATUSES = ("Maximum_Iterations_Exceeded",)
"""The NLP solver's return statuses of a solve that ran into its iteration cap (read where the
solve returns, into the record's ``capped``)."""

Learn = Callable[[], "Planner"]
"""The agent's learning hook a planner calls when its scheme learns: it gives the learner the
pending transitions and returns the planner to go on with (rebuilt when the learned term's
parameter layout changed)."""

_PERIOD_QUADRATURE = np.polynomial.legendre.leggauss(5)


@dataclass
class Plan:
    """A plan made at control period ``step``: the solution and the mesh it was made on.

    Attributes:
        solution: the OCP solution (or a constant stand-in when no solve gave anything).
        step: control period at which the plan starts.
        dt: control period (s).
        held: (S,) held flags of the solution's intervals.
    """

    solution: OCPSolution | InitialGuess
    step: int
    dt: float
    held: tuple[bool, ...] = ()

    def action(self, step: int, u_lb: np.ndarray, u_ub: np.ndarray) -> np.ndarray:
        """The (m,) control for period ``step`` (>= the plan's), clipped to the bounds."""
        sol, start = self.solution, (step - self.step) * self.dt
        if isinstance(sol, OCPSolution):
            edges = sol.interval_times
            s = int(np.searchsorted(edges, start + 1e-9 * self.dt, side="right")) - 1
            if (0 <= s < len(self.held) and self.held[s]
                    and abs(edges[s] - start) < 1e-9 * self.dt + 1e-12
                    and abs(edges[s + 1] - start - self.dt) < 1e-9 * self.dt + 1e-12):
                first = int(sum(sol.nodes_per_interval[:s]))
                return np.clip(sol.u[first], u_lb, u_ub)
        nodes, weights = _PERIOD_QUADRATURE
        u = 0.5 * weights @ np.atleast_2d(sol.control(start + 0.5 * self.dt * (nodes + 1.0)))
        return np.clip(np.asarray(u, float).ravel(), u_lb, u_ub)

    def covers(self, step: int) -> bool:
        """Whether period ``step`` starts before the plan's horizon ends."""
        t_end = self.solution.tf if self.solution.tf is not None else 0.0
        return (step - self.step) * self.dt < t_end


class Planner:
    """Plans for a :class:`PlanningModel` on a :class:`Mesh` (see the module doc).

    Args:
        planning: the model and learned term.
        mesh: the transcription.
        constraints: the OCP's constraint settings.
        solver: CasADi NLP plugin. solver_options: CasADi options (nested) over quiet
            defaults; ``max_iterations`` is IPOPT's ``max_iter`` unless given there.
        max_iterations: iteration cap of one solve (deterministic).
        jit: compile the NLP's functions (CasADi JIT).
        warm_start_duals: a warm solve also starts from the previous plan's multipliers, with
            IPOPT's warm-start options (:data:`gp_agents.pseudospectral.IPOPT_WARM_START_OPTIONS`).
        counts: where this planner counts (the agent's, shared by its planners); None: its own.
    """

    def __init__(self, planning: PlanningModel, mesh: Mesh, constraints: Constraints, *,
                 solver: str = "ipopt", solver_options: Mapping[str, Any] | None = None,
                 max_iterations: int = 500, jit: bool = False,
                 warm_start_duals: bool = False, counts: SolveCounts | None = None) -> None:
        if int(max_iterations) < 1:
            raise ValueError(f"max_iterations must be >= 1, got {max_iterations}")
        self.planning, self.mesh, self.constraints = planning, mesh, constraints
        self.warm_start_duals = bool(warm_start_duals) and solver == "ipopt"
        options = {key: (dict(v) if isinstance(v, Mapping) else v)
                   for key, v in (solver_options or {}).items()}
        if self.warm_start_duals:
            for key, value in IPOPT_WARM_START_OPTIONS["ipopt"].items():
                options.setdefault("ipopt", {}).setdefault(key, value)
        if solver == "ipopt":
            options.setdefault("ipopt", {}).setdefault("max_iter", int(max_iterations))
        self.ocp: GaussPseudospectralSolver = build_ocp(
            planning, mesh, constraints, solver=solver, solver_options=options, jit=jit)
        self.counts = SolveCounts() if counts is None else counts
        self.counts.builds += 1

    def replan(self, x: np.ndarray, previous: Plan | None, step: int, learn: Learn
               ) -> tuple[Plan, dict[str, Any]]:
        """A replan of the closed loop: learn the pending transitions first (Algorithm 1:
        the learner is updated before the next solve), then :meth:`plan` with the planner
        ``learn`` returns."""
        return learn().plan(x, previous, step)

    def after_action(self, plan: Plan, record: Mapping[str, Any], learn: Learn
                     ) -> dict[str, Any]:
        """Work done after the action of the new plan ``plan`` (whose replan gave ``record``)
        is sent; returns updates of the step's record. A converged or one-call scheme has
        none."""
        return {}

    def plan(self, x: np.ndarray, previous: Plan | None, step: int) -> tuple[Plan, dict[str, Any]]:
        """A plan from state ``x`` (n,) at control period ``step``, and the solve's record:
        ``success, status`` (:class:`~gp_agents.mpc.diagnostics.StepStatus`), ``solver_status,
        capped, iterations, solve_time, solves, fallback, linearization_error``."""
        model = self.planning.model
        p = self.planning.param_values()
        cold = previous is None or not isinstance(previous.solution, OCPSolution)
        duals = None
        if cold:
            guess: Any = self._goal_guess(x)
        else:
            guess = self._aligned(previous.solution.shift((step - previous.step) * model.dt), x)
            if self.warm_start_duals and previous.solution.nlp_lam_g is not None:
                duals = (previous.solution.nlp_lam_x, previous.solution.nlp_lam_g)
        sol, record = self._solve(p, x, guess, cold, duals)
        usable = sol.success and np.all(np.isfinite(sol.u))
        if not usable and not cold:
            retry, again = self._solve(p, x, self._goal_guess(x), True)
            self.counts.retries += 1
            record = {key: record[key] + again[key] if key in ("iterations", "solve_time",
                                                               "solves") else again[key]
                      for key in record}
            if retry.success and np.all(np.isfinite(retry.u)):
                sol, usable = retry, True
        fallback = False
        plan = Plan(sol, step, model.dt, self.ocp.hold)
        if not usable:
            self.counts.failures += 1
            if previous is not None and previous.covers(step):
                plan, fallback = previous, True
            elif not (np.all(np.isfinite(sol.u)) and np.all(np.isfinite(sol.x))):
                plan, fallback = Plan(self._hold_guess(x), step, model.dt), True
            self.counts.fallbacks += int(fallback)
        record.update(success=bool(sol.success), status=StepStatus.SOLVED,
                      solver_status=str(sol.status), capped=sol.status in CAPPED_STATUSES,
                      fallback=fallback)
        return plan, record

    def _solve(self, p: np.ndarray, x: np.ndarray, guess: Any, cold: bool,
               duals: tuple[np.ndarray, np.ndarray] | None = None
               ) -> tuple[OCPSolution, dict[str, Any]]:
        """Solve as often as the term asks; each plan the next reference (and, with
        ``duals``, the first solve starts from those multipliers)."""
        term, t_nodes = self.planning.term, self.ocp.node_times()
        reference = (guess.state(t_nodes), guess.control(t_nodes))
        iterations, solve_time, error, limit = 0, 0.0, 0.0, term.solves(cold)
        for solves in range(1, limit + 1):
            q = term.node_param_values(*reference)
            sol = self.ocp.solve(p=p, x0=x, initial_guess=guess, node_params=q,
                                 multipliers=duals if solves == 1 else None)
            self.counts.solves += 1
            self.counts.capped += int(sol.status in CAPPED_STATUSES)
            iterations += max(int(sol.iterations), 0)
            solve_time += float(sol.solve_time)
            if q is None:
                break
            error = term.plan_error(sol)
            if not np.isfinite(error) or (sol.success and error <= 1.0) or solves == limit:
                break
            reference, guess = (sol.x_nodes, sol.u), sol
        return sol, dict(iterations=iterations, solve_time=solve_time, solves=solves,
                         linearization_error=float(error))

    def _goal_guess(self, x: np.ndarray) -> InitialGuess:
        """A straight line in state space from ``x`` to the nearest copy of the goal."""
        model, horizon = self.planning.model, self.mesh.horizon
        goal = np.asarray(model.task.goal, float).copy()
        for i in model.task.periodic_indices:
            goal[i] = x[i] - model.task.error(x)[i]
        t = np.linspace(0.0, horizon, 2 * self.mesh.n_collocation + 1)
        s = (t / horizon)[:, None]
        states = np.clip((1 - s) * x + s * goal, model.x_lb, model.x_ub)
        u = np.clip(model.task.u_ref, model.u_lb, model.u_ub)
        return InitialGuess(t=t, x=states, t_u=t, u=np.tile(u, (t.size, 1)))

    def _aligned(self, guess: InitialGuess, x: np.ndarray) -> InitialGuess:
        """``guess`` with its angle trajectories shifted by 2 pi k to start at ``x``'s."""
        angles = self.planning.model.angle_indices
        if not angles:
            return guess
        gx = guess.x.copy()
        for i in angles:
            gx[:, i] += 2 * np.pi * np.round((x[i] - gx[0, i]) / (2 * np.pi))
        return InitialGuess(t=guess.t, x=gx, t_u=guess.t_u, u=guess.u, tf=guess.tf)

    def _hold_guess(self, x: np.ndarray) -> InitialGuess:
        """Constant state and the reference control (when no solve gave anything finite)."""
        model = self.planning.model
        u = np.clip(model.task.u_ref, model.u_lb, model.u_ub)
        t = np.array([0.0, self.mesh.horizon])
        return InitialGuess(t=t, x=np.vstack([x, x]), t_u=t, u=np.vstack([u, u]),
                            tf=self.mesh.horizon)
