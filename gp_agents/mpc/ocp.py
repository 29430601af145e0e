"""The MPC's optimal control problem: mesh, cost, state box and obstacles.

**The plan is what the plant executes.** A ``gp_envs`` env holds each action for one control
period ``dt`` (zero-order hold). The Gauss pseudospectral control has no node at ``t0`` (errata
note 5) and is a polynomial elsewhere, so no polynomial control is what the plant does. The
mesh here makes every period that will be executed from a plan a *held* interval: one control
decision, constant over the period, with its dynamics collocated exactly under that constant
(:class:`gp_agents.pseudospectral.GaussPseudospectralSolver` ``hold``). That decision *is* the
action sent to the env, which settles errata note 5: the control applied at ``t0`` is the first
held interval's decision, not an extrapolation of node values.

- Receding horizon (:meth:`Mesh.receding`): the first ``replan_every`` periods held (a few LG
  nodes each), then LG intervals with polynomial control over the rest of the horizon.
- Episodic (:meth:`Mesh.episodic`): every period of the task held; state bounds and path
  constraints hold at every period boundary, so the open-loop plan is feasible for the plant.

Cost: the task's stage cost integrated over the horizon plus its terminal cost, and a steep
quadratic penalty on leaving the state box shrunk by ``state_margin`` (the box itself is hard; a
hard margin would make the NLP infeasible whenever the measured state is already in it).
Obstacles: ``|p - c| >= O_r + B_r (+ kappa U_r)`` hard at every node and held period end,
``U_r`` the one-step position standard deviation from the learned term's variance in the
obstacle's direction (paper, "Obstacle Avoidance using SSGP"), and the ``obstacle_margin``
beyond it soft, with the state margin's penalty: a hard margin made the NLP infeasible whenever
the vehicle was already inside it (measured: with the first period held, its nodes lie within
10 ms of t0, and the nominal Dubins MPC then lost 15 of the 50 episodes to infeasible solves
and obstacle contact).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from gp_agents.mpc.planning_model import PlanningModel
from gp_agents.pseudospectral import GaussPseudospectralSolver, OptimalControlProblem

__all__ = ["Constraints", "Mesh", "build_ocp"]


@dataclass(frozen=True)
class Mesh:
    """How the horizon is transcribed.

    Attributes:
        horizon: seconds.
        nodes: (S,) LG nodes per interval.
        boundaries: (S + 1,) interval boundaries as fractions of the horizon.
        hold: (S,) whether an interval's control is one held decision (a control period).
    """

    horizon: float
    nodes: tuple[int, ...]
    boundaries: tuple[float, ...]
    hold: tuple[bool, ...]

    @classmethod
    def receding(cls, horizon: float, dt: float, n_nodes: int, n_intervals: int = 1,
                 held_periods: int = 1, held_nodes: int = 3) -> Mesh:
        """``held_periods`` held periods of ``dt`` (``held_nodes`` nodes each), then
        ``n_intervals`` equal LG intervals of ``n_nodes`` nodes over the rest.

        Raises:
            ValueError: a horizon not longer than the held periods, or counts < 1.
        """
        held = held_periods * dt
        if not horizon > held + 1e-9:
            raise ValueError(f"horizon {horizon} s must exceed the {held_periods} held "
                             f"period(s) of {dt} s")
        if min(n_nodes, n_intervals, held_periods, held_nodes) < 1:
            raise ValueError("n_nodes, n_intervals, held periods and held nodes must be >= 1")
        edges = np.concatenate([np.arange(held_periods + 1) * dt,
                                np.linspace(held, horizon, n_intervals + 1)[1:]]) / horizon
        edges[-1] = 1.0
        return cls(float(horizon), (held_nodes,) * held_periods + (n_nodes,) * n_intervals,
                   tuple(edges.tolist()), (True,) * held_periods + (False,) * n_intervals)

    @classmethod
    def episodic(cls, duration: float, dt: float, nodes_per_period: int = 3) -> Mesh:
        """Every period of a ``duration``-second task held, ``nodes_per_period`` nodes each."""
        periods = round(duration / dt)
        if periods < 1 or abs(periods * dt - duration) > 1e-9 * max(1.0, duration):
            raise ValueError(f"duration {duration} s is not a whole number of {dt} s periods")
        edges = np.arange(periods + 1) / periods
        return cls(float(duration), (int(nodes_per_period),) * periods, tuple(edges.tolist()),
                   (True,) * periods)

    @property
    def n_collocation(self) -> int:
        """Collocation nodes M."""
        return int(sum(self.nodes))

    def describe(self) -> str:
        """E.g. ``"1 held period x 3 nodes + 1 LG interval x 16 nodes"``."""
        parts, i = [], 0
        while i < len(self.nodes):
            j = i
            while j < len(self.nodes) and (self.nodes[j], self.hold[j]) == (self.nodes[i],
                                                                             self.hold[i]):
                j += 1
            kind = "held period" if self.hold[i] else "LG interval"
            parts.append(f"{j - i} {kind}{'s' if j - i > 1 else ''} x {self.nodes[i]} nodes")
            i = j
        return " + ".join(parts)

    @property
    def held_periods(self) -> int:
        """Leading held intervals (periods whose action is a decision of the plan)."""
        return next((i for i, h in enumerate(self.hold) if not h), len(self.hold))


@dataclass(frozen=True)
class Constraints:
    """Constraint settings of the OCP.

    Attributes:
        state_margin: fraction of each finite half-range by which the plan keeps inside the
            env's state box (soft); in [0, 0.5).
        state_penalty: weight of the squared violation of the shrunk box, or None (hard).
        obstacle_margin: metres beyond obstacle plus body radius the plan keeps clear of (soft
            with ``state_penalty``, hard if that is None).
        uncertainty_radius: ``kappa`` >= 0 (0: the paper's run).
    """

    state_margin: float = 0.05
    state_penalty: float | None = 1e4
    obstacle_margin: float = 0.1
    uncertainty_radius: float = 0.0

    def __post_init__(self) -> None:
        if not (0 <= self.state_margin < 0.5 and self.obstacle_margin >= 0):
            raise ValueError("state_margin must be in [0, 0.5) and obstacle_margin >= 0")
        if self.state_penalty is not None and not self.state_penalty > 0:
            raise ValueError(f"state_penalty must be > 0 or None, got {self.state_penalty}")
        if not (np.isfinite(self.uncertainty_radius) and self.uncertainty_radius >= 0):
            raise ValueError(f"uncertainty_radius must be >= 0, got {self.uncertainty_radius}")


def build_ocp(planning: PlanningModel, mesh: Mesh, constraints: Constraints, *,
              solver: str = "ipopt", solver_options: Mapping[str, Any] | None = None,
              jit: bool = False) -> GaussPseudospectralSolver:
    """The transcribed OCP, built once; re-solved with ``p = planning.param_values()``.

    Args:
        planning: the dynamics (and the learned term's parameter layout).
        mesh: the transcription.
        constraints: state box margin and obstacle settings.
        solver, solver_options, jit: see :class:`GaussPseudospectralSolver`.
    """
    model, c = planning.model, constraints
    task = model.task
    half = 0.5 * (model.x_ub - model.x_lb)
    shrink = np.where(np.isfinite(half), c.state_margin * half, 0.0)
    x_lb, x_ub = model.x_lb + shrink, model.x_ub - shrink
    soft = c.state_penalty is not None

    def running_cost(x: Any, u: Any, p: Any) -> Any:
        cost = task.stage_cost(x, u)
        if soft:
            above = ca.fmax(0, x - ca.DM(np.where(np.isfinite(x_ub), x_ub, 0.0)))
            below = ca.fmax(0, ca.DM(np.where(np.isfinite(x_lb), x_lb, 0.0)) - x)
            w_ub = ca.DM(np.isfinite(x_ub).astype(float))
            w_lb = ca.DM(np.isfinite(x_lb).astype(float))
            cost += c.state_penalty * (ca.dot(w_ub, above**2) + ca.dot(w_lb, below**2))
            for ob in task.obstacles:  # the obstacle margin is soft like the state margin
                clear = ob.radius + task.body_radius + c.obstacle_margin
                dist = ca.sqrt(ca.sumsqr(x[:2] - ca.DM(ob.center)) + 1e-12)
                cost += c.state_penalty * ca.fmax(0, clear - dist) ** 2
        return cost

    radius_term = (c.uncertainty_radius > 0 and bool(task.obstacles)
                   and planning.term.variance)

    def obstacles(x: Any, u: Any, p: Any, q: Any) -> Any:
        out = []
        for ob in task.obstacles:
            d = x[:2] - ca.DM(ob.center)
            radius = ob.radius + task.body_radius + (0.0 if soft else c.obstacle_margin)
            if radius_term:  # U_r: the 1-sigma ellipse of sqrt(v) dt along d
                vx, vy = planning.position_variance(x, u, p, q)
                dist2 = ca.sumsqr(d) + 1e-12
                radius = radius + c.uncertainty_radius * model.dt / ca.sqrt(
                    (d[0] ** 2 / vx + d[1] ** 2 / vy) / dist2)
            out.append(radius**2 - ca.sumsqr(d))  # <= 0 keeps clear
        return ca.vertcat(*out)

    problem = OptimalControlProblem(
        n_states=model.n_states, n_controls=model.n_controls, dynamics=planning.dynamics,
        n_params=planning.n_params, n_node_params=planning.n_node_params,
        running_cost=running_cost, terminal_cost=lambda x0, xf: task.terminal_cost(xf),
        t0=0.0, tf=mesh.horizon, x_lb=model.x_lb if soft else x_lb,
        x_ub=model.x_ub if soft else x_ub, u_lb=model.u_lb, u_ub=model.u_ub,
        x0=np.zeros(model.n_states), path_constraints=obstacles if task.obstacles else None,
        hessian_dynamics=None if planning.term.exact_hessian else planning.hessian_dynamics,
    )
    planning.term.check_size(mesh.n_collocation)
    return GaussPseudospectralSolver(problem, n_nodes=list(mesh.nodes), mesh=list(mesh.boundaries),
                                     hold=list(mesh.hold), solver=solver,
                                     solver_options=solver_options, jit=jit)
