"""The same cart-pole swing-up MPC solved by this project and by do-mpc, in one process.

Trial kind ``"peers"`` (:mod:`benchmarks.trial`): one episode of the ``nominal-mpc`` recipe
(:class:`gp_agents.PseudospectralMPC`, Gauss pseudospectral collocation) and one episode of a
do-mpc controller built from the same ingredients, from the same seeded initial state, measured
in lockstep in the same process (one step of each in turn, on two envs reset with the same seed):

- dynamics: the env's nominal model, ``model.casadi_function()`` (CasADi SX);
- cost: ``integral of l(x, u) dt + e' Qf e`` with the task's ``Q``, ``R``, ``Qf`` and goal (do-mpc
  sums ``lterm`` once per interval, so ``lterm = dt * l``; the angle error is wrapped in both);
- horizon: the system's registered default (:class:`gp_agents.defaults.PlanningDefaults`; 1.5 s
  for the cart pole);
- bounds: the control box, and the state box shrunk by the same ``state_margin`` (5% of each
  finite half-range) that the pseudospectral MPC uses;
- solver: IPOPT through CasADi with the same quiet options (``print_level 0``); default
  tolerances and linear solver (MUMPS) in both.

Discretization: do-mpc's own default, orthogonal collocation on finite elements with
``t_step = dt`` (the control period, piecewise-constant controls) and Radau collocation of degree
2, i.e. 30 intervals x 2 collocation points over the 1.5 s horizon. The pseudospectral MPC holds
its first period's control too (the action it sends is a decision of its plan,
:mod:`gp_agents.mpc.ocp`): one held period of 3 LG nodes, then 16 LG nodes with polynomial
control over the remaining 1.45 s. Both warm-start from their previous solution (do-mpc does so
automatically; its first guess is the initial state everywhere, as documented).

The per-step time is the wall-clock time of one ``act`` (``make_step`` for do-mpc), so it
includes each library's Python overhead; the time of the solver call alone is recorded too.
do-mpc is an optional dependency (``pip install do-mpc``); without it the trial is recorded as
unavailable.
"""

from __future__ import annotations

import time
import warnings
from typing import Any

import numpy as np

from benchmarks.controllers import ControllerUnavailableError, make_env
from benchmarks.trial import TrialSpec
from gp_agents.agent import Episode, rollout_lockstep

STATE_MARGIN = 0.05
"""Same default as :class:`gp_agents.PseudospectralMPC` ``state_margin``."""
IPOPT_OPTIONS = {"ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": 0}
"""The options :func:`gp_agents.pseudospectral.default_solver_options` gives IPOPT."""
COLLOCATION_DEG = 2


class DoMPCController:
    """A do-mpc MPC of a ``gp_envs`` model's nominal dynamics and task, with ``act(obs)``.

    Args:
        model: the env's ``nominal_model``.
        horizon: prediction horizon in seconds (rounded to whole control periods).
    """

    def __init__(self, model: Any, horizon: float) -> None:
        try:
            import do_mpc
        except ImportError as err:
            raise ControllerUnavailableError("do-mpc is not installed (pip install do-mpc)"
                                             ) from err
        self.version = str(getattr(do_mpc, "__version__", "unknown"))
        task = model.task
        m = do_mpc.model.Model("continuous", "SX")
        x = m.set_variable("_x", "x", shape=(model.n_states, 1))
        u = m.set_variable("_u", "u", shape=(model.n_controls, 1))
        m.set_rhs("x", model.casadi_function()(x, u))
        m.setup()
        mpc = do_mpc.controller.MPC(m)
        self.n_horizon = round(horizon / model.dt)
        mpc.settings.n_horizon = self.n_horizon
        mpc.settings.t_step = model.dt
        mpc.settings.state_discretization = "collocation"
        mpc.settings.collocation_type = "radau"
        mpc.settings.collocation_deg = COLLOCATION_DEG
        mpc.settings.collocation_ni = 1
        mpc.settings.store_full_solution = False
        mpc.settings.nlpsol_opts = dict(IPOPT_OPTIONS)
        mpc.set_objective(mterm=task.terminal_cost(x), lterm=model.dt * task.stage_cost(x, u))
        mpc.set_rterm(u=0.0)
        half = 0.5 * (model.x_ub - model.x_lb)
        shrink = np.where(np.isfinite(half), STATE_MARGIN * half, 0.0)
        mpc.bounds["lower", "_x", "x"] = model.x_lb + shrink
        mpc.bounds["upper", "_x", "x"] = model.x_ub - shrink
        mpc.bounds["lower", "_u", "u"] = model.u_lb
        mpc.bounds["upper", "_u", "u"] = model.u_ub
        mpc.setup()
        self.mpc = mpc
        self.model = model
        self._last_solve = float("nan")
        solve = mpc.solve

        def timed_solve() -> None:  # the IPOPT call inside make_step, timed like ours
            t0 = time.perf_counter()
            solve()
            self._last_solve = time.perf_counter() - t0

        mpc.solve = timed_solve
        self.n_variables = int(mpc.opt_x.shape[0])
        self._prev: np.ndarray | None = None
        self.solve_times: list[float] = []
        self.n_failures = 0

    def reset(self) -> None:
        """Start an episode: the first ``act`` sets do-mpc's initial guess to its state."""
        self._prev = None
        self.solve_times = []
        self.n_failures = 0

    def observe(self, obs: np.ndarray, action: np.ndarray, next_obs: np.ndarray) -> None:
        """Nothing to learn (the :class:`gp_agents.Agent` interface)."""

    def act(self, obs: np.ndarray) -> np.ndarray:
        """(m,) float32 action; angles are unwrapped to be continuous with the last call's."""
        x = np.asarray(obs, float).copy()
        if self._prev is None:  # first call of the episode: do-mpc's documented initial guess
            self.mpc.x0 = x.reshape(-1, 1)
            self.mpc.set_initial_guess()
        else:
            for i in self.model.angle_indices:
                x[i] += 2 * np.pi * np.round((self._prev[i] - x[i]) / (2 * np.pi))
        self._prev = x
        u = np.asarray(self.mpc.make_step(x.reshape(-1, 1)), float).ravel()
        stats = self.mpc.solver_stats
        self.solve_times.append(self._last_solve)
        if not stats.get("success", False):
            self.n_failures += 1
        return np.clip(u, self.model.u_lb, self.model.u_ub).astype(np.float32)


def _summary(ep: Episode) -> dict[str, Any]:
    return {"act": ep.act_times, "cost": ep.cost, "success": ep.success,
            "obs": ep.observations,
            "termination": ep.final_info.get("termination_reason") or "time limit"}


def run_peers(spec: TrialSpec) -> dict[str, Any]:
    """One episode each of the pseudospectral MPC and do-mpc on ``spec.env``/``scenario``."""
    from gp_agents import PseudospectralMPC
    from gp_agents.defaults import default_planning

    env = make_env(spec.env, spec.scenario)
    env.reset(seed=spec.seed)
    model = env.unwrapped.nominal_model
    horizon = float(default_planning(model).horizon)
    ps = PseudospectralMPC.from_env(env, horizon=horizon)
    env_rti = make_env(spec.env, spec.scenario)
    rti_agent = PseudospectralMPC.from_env(env_rti, horizon=horizon, scheme="rti")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        peer = DoMPCController(model, horizon)

        # one step of each in turn: a change of the machine's load slows all alike
        ours, rti, theirs = (_summary(e) for e in rollout_lockstep(
            [(env, ps), (env_rti, rti_agent), (make_env(spec.env, spec.scenario), peer)],
            spec.seed))
    ps_solve = np.array([r.solve_time for r in ps.diagnostics if r.replanned])
    med_ours, med_theirs = float(np.median(ours["act"])), float(np.median(theirs["act"]))
    n_ps_vars = int(ps.planner.ocp.n_variables) if ps.planner is not None else -1
    metrics = {
        "horizon_s": horizon,
        "ps_nodes": ps.planner.mesh.describe() if ps.planner is not None else "",
        "dompc_discretization": f"{peer.n_horizon} intervals x Radau degree {COLLOCATION_DEG}",
        "ps_nlp_variables": n_ps_vars,
        "dompc_nlp_variables": peer.n_variables,
        "ps_act_median_ms": 1e3 * med_ours,
        "dompc_act_median_ms": 1e3 * med_theirs,
        "ps_act_p95_ms": 1e3 * float(np.percentile(ours["act"], 95)),
        "dompc_act_p95_ms": 1e3 * float(np.percentile(theirs["act"], 95)),
        "ps_solve_median_ms": 1e3 * float(np.median(ps_solve)),
        "dompc_solve_median_ms": 1e3 * float(np.nanmedian(peer.solve_times)),
        "time_ratio": med_ours / med_theirs,
        "rti_act_median_ms": 1e3 * float(np.median(rti["act"])),
        "rti_time_ratio": float(np.median(rti["act"])) / med_theirs,
        "rti_cost": rti["cost"],
        "rti_success": rti["success"],
        "rti_rejected": int(rti_agent.counts.rti_rejected),
        "ps_cost": ours["cost"],
        "dompc_cost": theirs["cost"],
        "ps_success": ours["success"],
        "dompc_success": theirs["success"],
        "ps_termination": ours["termination"],
        "dompc_termination": theirs["termination"],
        "ps_failures": int(ps.counts.failures),
        "dompc_failures": int(peer.n_failures),
        "dompc_version": peer.version,
    }
    env.close()
    return {"metrics": metrics, "arrays": {"ps_act_time": ours["act"],
                                           "dompc_act_time": theirs["act"],
                                           "rti_act_time": rti["act"], "rti_obs": rti["obs"],
                                           "ps_obs": ours["obs"], "dompc_obs": theirs["obs"]}}
