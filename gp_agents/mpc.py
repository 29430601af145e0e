"""Pseudospectral model predictive control with an online-learned GP residual.

The paper's Algorithm 1 ("Model Predictive Pseudospectral Control with Online Learning"):

1. initialise the (sparse spectrum) GP with initial training data (:meth:`PseudospectralMPC.
   pretrain`, data from :func:`gp_agents.data.collect_initial_data`);
2. solve the Gauss pseudospectral OCP from the current state (:mod:`gp_agents.pseudospectral`);
3. roll out the first ``p`` control periods of the plan (``replan_every``);
4. update the GP with the ``p`` new transitions (:meth:`PseudospectralMPC.observe`);
5. warm-start the next solve from the previous plan shifted in time; repeat.

The model is ``xdot = f_nominal(x, u; params) + S * mean_GP(phi(x, u); theta)``
(:class:`gp_agents.residual.ResidualModel`). The NLP is built once per agent: the nominal
parameter values, the learner's parameter vector ``theta`` (weights, features, ...) and the
initial state are NLP parameters, so learning never rebuilds the solver.

**The control applied at the current time.** The Legendre-Gauss control has no node at ``t0``
(errata note 5) and the plant holds each action for a whole period ``dt``. The agent applies the
*period mean* of the planned control over ``[t, t + dt]`` (5-point Gauss quadrature of the
control interpolant), clipped to the bounds: the constant control with the same impulse as the
plan over the period. ``control_at_t0="extrapolate"`` (the interpolant at ``t0``) and
``"first_node"`` (the first LG node's value) are available for comparison.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import casadi as ca
import gymnasium as gym
import numpy as np

from gp_agents.data import Transitions
from gp_agents.learners import IncrementalSSGP
from gp_agents.learners.hyperparameters import HyperparameterBounds
from gp_agents.pseudospectral import (
    GaussPseudospectralSolver,
    InitialGuess,
    OCPSolution,
    OptimalControlProblem,
)
from gp_agents.residual import ResidualModel
from gp_envs.model import ControlModel

ControlAtT0 = Literal["period_mean", "extrapolate", "first_node"]
LearnedDynamics = Literal["exact", "linearized"]

DEFAULT_SETTINGS: dict[str, dict[str, Any]] = {
    "cartpole": {"horizon": 1.5, "n_nodes": 16, "n_intervals": 1},
    "quadrotor": {"horizon": 1.5, "n_nodes": 10, "n_intervals": 1},
    "dubins": {"horizon": 4.0, "n_nodes": 12, "n_intervals": 2},
}
"""Receding-horizon settings per system (horizon in seconds, LG nodes per interval)."""

EPISODIC_SETTINGS: dict[str, dict[str, Any]] = {
    "cartpole": {"n_nodes": 12, "n_intervals": 6},
    "quadrotor": {"n_nodes": 10, "n_intervals": 6},
    "dubins": {"n_nodes": 12, "n_intervals": 5},
}
"""Settings of the episodic (plan once over the whole task) mode."""

def online_ssgp(n_frequencies: int = 50, forgetting_factor: float = 0.995,
                random_state: int | None = 0) -> IncrementalSSGP:
    """The online learner of the paper's Algorithm 1, as this project's benchmarks use it.

    An :class:`~gp_agents.learners.IncrementalSSGP` whose hyperparameters come from the SSGP's
    own marginal likelihood on the initial data, with length scales of at least one standard
    deviation of the (standardized) inputs. Without that floor the likelihood's optimum on 200
    points in the quadrotor's 19 input dimensions sits at the bound (length scales 0.01): a
    model that fits noise and predicts no better than zero (test nMSE ~1.0), on which the NLP
    stops converging; with it the quadrotor test nMSE is ~1e-3 and the cart pole's is unchanged.

    Args:
        n_frequencies: ``r`` (``2r`` features per output).
        forgetting_factor: ``lambda``; 0.995 halves a sample's weight in ~140 steps (7 s).
        random_state: seeds the frequency draws.
    """
    return IncrementalSSGP(n_frequencies, forgetting_factor=forgetting_factor,
                           hyperparameters="ssgp", random_state=random_state,
                           bounds=HyperparameterBounds(length_scale=(1.0, 100.0)))


MAX_LEARNED_MODEL_SIZE = 50_000_000
"""Largest learned model :class:`PseudospectralMPC` builds an NLP for: instructions of the
learner's CasADi mean at one node x learner inputs x collocation nodes (a proxy for the size of
the NLP's derivatives). Measured on this project's recipes: the SSGP quadrotor plan over the
whole episode (2.3e7) builds in ~1 GB; the exact GP on 200 points over the same plan (1.2e8)
exhausted 24 GB of memory while CasADi generated the constraint Jacobian, expanded or not."""

COLD_START_LINEARIZATIONS = 5
"""Solves a linearized agent may take from a cold start (the goal guess): the expansion about a
straight line can be far off, and the plan it gives is the reference of every later step."""

_PERIOD_QUADRATURE = np.polynomial.legendre.leggauss(5)
"""Gauss-Legendre rule for the period mean of the control (exact to degree 9)."""


@dataclass
class StepRecord:
    """Diagnostics of one :meth:`PseudospectralMPC.act` call.

    Attributes:
        step: control period index since the last reset.
        replanned: whether an OCP was solved in this call.
        success: solver success of that solve (True when not replanned).
        status: solver status string (``"reuse"`` when not replanned).
        iterations: NLP iterations (0 when not replanned), summed over this call's solves.
        solve_time: seconds spent in the NLP solver, summed likewise.
        act_time: seconds spent in the whole ``act`` call (learning update included).
        fallback: the applied control came from the previous plan because the solve failed.
        learner_samples: samples the learner has seen after this call's update.
        plan_t: (N,) times of the current plan's state points (relative to its start).
        plan_x: (N, n) the current plan's states (the predicted trajectory).
        action: (m,) the applied action.
        solves: NLP solves in this call (retries and re-linearizations included).
        linearization_error: with ``learned_dynamics="linearized"``, the plan's largest
            expansion error as a fraction of its tolerance (NaN if the solve gave no finite
            plan; 0 otherwise).
    """

    step: int
    replanned: bool
    success: bool
    status: str
    iterations: int
    solve_time: float
    act_time: float
    fallback: bool
    learner_samples: int
    plan_t: np.ndarray
    plan_x: np.ndarray
    action: np.ndarray
    solves: int = 0
    linearization_error: float = 0.0


@dataclass
class _Plan:
    solution: OCPSolution
    step: int  # control period at which the plan starts


@dataclass
class _Buffer:
    X: list[np.ndarray] = field(default_factory=list)
    U: list[np.ndarray] = field(default_factory=list)
    X_next: list[np.ndarray] = field(default_factory=list)

    def clear(self) -> None:
        self.X.clear()
        self.U.clear()
        self.X_next.clear()


class PseudospectralMPC:
    """Gauss pseudospectral MPC on nominal physics plus an optional learned residual.

    Args:
        model: the model the controller plans with: an env's ``nominal_model``, or (for the
            upper-bound baseline only) ``gp_envs.oracle_model(env)``.
        learner: a residual learner (``gp_agents.IncrementalSSGP``, ``SSGP`` or ``ExactGP``), or
            None for the pure physics model. It must be fitted before the first ``act``
            (:meth:`pretrain` does it from transitions).
        mode: ``"receding"`` (Algorithm 1) or ``"episodic"`` (plan once over the task's whole
            duration at the first ``act``, then execute open loop; no learning).
        horizon: prediction horizon in seconds (receding mode; default per system in
            :data:`DEFAULT_SETTINGS`).
        n_nodes: LG nodes per mesh interval. n_intervals: mesh intervals.
        replan_every: ``p``, control periods executed from each plan before re-solving.
        learn_online: feed observed transitions to ``learner.update`` (if the learner has one).
        uncertain_indices: state components with a learned residual (default: the model's
            accelerations, ``model.dynamic_indices``).
        input_indices: state components fed to the learner: ``None`` (all), indices, or
            ``"model"`` (those the parametric nominal model's uncertain rates depend on,
            :meth:`ResidualModel.model_inputs`: fewer learner inputs, a cheaper NLP; it assumes
            the model error lies within the model's structure).
        uncertainty_radius: ``kappa`` >= 0; with obstacles and a learner, the obstacle constraint
            is ``distance >= O_r + B_r + kappa * U_r`` with ``U_r`` the one-step position
            standard deviation from the learner's predictive variance in the direction of the
            obstacle (paper, "Obstacle Avoidance using SSGP"); 0 reproduces the paper's run.
        control_at_t0: how the applied control is obtained (module docstring).
        solver: CasADi NLP solver plugin (default IPOPT). solver_options: CasADi options merged
            over quiet defaults.
        max_solve_time: wall-clock limit of one solve in seconds (IPOPT ``max_wall_time``);
            a solve that hits it counts as failed and the previous plan is used.
        max_iterations: iteration limit of one solve (IPOPT ``max_iter``), likewise.
        state_margin: fraction of each finite state range by which the plan keeps inside the
            env's state box (the box ends the episode; a plan on its edge crosses it between
            nodes or under model error). 0.05 shrinks ``[-1, 1]`` to ``[-0.95, 0.95]``.
        state_penalty: the env's state box is a hard constraint of the plan, the margin inside
            it a *soft* one: the running cost gains ``state_penalty * sum(max(0, x - ub)^2 +
            max(0, lb - x)^2)`` over the shrunk box. A hard margin would make the NLP infeasible
            whenever the measured state is already in it (e.g. a cart moving fast towards the
            track's end), and an infeasible NLP gives no useful action. ``None`` makes the
            shrunk box hard.
        obstacle_margin: metres added to obstacle radius plus body radius in the plan, for the
            same reason.
        jit: compile the NLP's functions to C with the system compiler (CasADi JIT): a few
            seconds once per agent, faster solves when the learned model dominates the cost.
        hessian: second derivatives the NLP solver gets with a learner. ``"exact"``: of the
            whole model. ``"nominal"``: of the nominal physics only (the learned residual's
            second derivatives are dropped from the Lagrangian Hessian; its values and first
            derivatives stay in the constraints and their Jacobian, so a converged plan is the
            same). The residual's Hessian is most of the cost of an iteration with a learner
            (``python -m benchmarks.profile_mpc``). No effect without a learner, nor with
            ``learned_dynamics="linearized"`` (whose residual has no second derivatives).
        learned_dynamics: how the learned residual enters the NLP. ``"exact"``: the learner's
            CasADi mean at every collocation node, with all its derivatives (the paper's OCP).
            ``"linearized"``: its first-order expansion about a reference trajectory, one per
            node, ``mean(z_k) ~ g_k + J_k [x_k - xb_k; u_k - ub_k]``, with ``g_k, J_k`` from
            the learner's numeric ``predict`` and ``predict_gradient``
            (:meth:`ResidualModel.linearize`), passed as per-node NLP parameters; the
            uncertainty radius, if any, is frozen at the reference too. The reference is the
            warm start (the previous plan shifted in time), as in a real-time iteration: the
            NLP then has the nominal model's Hessian and only a denser Jacobian, and the
            learner is evaluated once per node per solve instead of once per node per IPOPT
            iteration with its second derivatives. After each solve the
            residual is evaluated at the plan's nodes; the expansion's largest error there, as
            a fraction of ``linearization_tol`` (relative to the largest residual over the
            nodes, per output, plus an absolute 1e-3), is recorded
            (``diagnostics_arrays()["linearization_error"]``). With ``max_linearizations`` >
            1, a plan whose error exceeds 1 (or a failed solve's finite last iterate) is
            re-linearized about and re-solved, up to that many solves per replan; from a cold
            start (the first solve of an episode, or the retry from the goal guess) up to
            :data:`COLD_START_LINEARIZATIONS`, since an expansion about a straight line can
            make the NLP infeasible. A fixed point of that loop is a KKT point of the exact
            problem (model values and first derivatives agree there;
            ``tests/test_mpc.py`` checks it). No effect without a learner.
        max_linearizations: solves per replan in ``"linearized"`` mode (>= 1; default 1, one
            linearization about the warm start per control period; cold starts may take up
            to ``COLD_START_LINEARIZATIONS``).
        linearization_tol: relative tolerance of the expansion (see ``learned_dynamics``).
    """

    def __init__(self, model: ControlModel, learner: Any | None = None, *,
                 mode: Literal["receding", "episodic"] = "receding",
                 horizon: float | None = None, n_nodes: int | None = None,
                 n_intervals: int | None = None, replan_every: int = 1,
                 learn_online: bool = True, uncertain_indices: tuple[int, ...] | None = None,
                 input_indices: tuple[int, ...] | Literal["model"] | None = None,
                 uncertainty_radius: float = 0.0, control_at_t0: ControlAtT0 = "period_mean",
                 solver: str = "ipopt", solver_options: Mapping[str, Any] | None = None,
                 max_solve_time: float | None = 1.0, max_iterations: int = 500,
                 state_margin: float = 0.05, state_penalty: float | None = 1e4,
                 obstacle_margin: float = 0.1, jit: bool = False,
                 hessian: Literal["exact", "nominal"] = "exact",
                 learned_dynamics: LearnedDynamics = "exact", max_linearizations: int = 1,
                 linearization_tol: float = 0.1) -> None:
        if not isinstance(model, ControlModel):
            raise TypeError(f"model must be a gp_envs ControlModel, got {type(model).__name__}")
        if mode not in ("receding", "episodic"):
            raise ValueError(f"mode must be 'receding' or 'episodic', got {mode!r}")
        if control_at_t0 not in ("period_mean", "extrapolate", "first_node"):
            raise ValueError(f"unknown control_at_t0 {control_at_t0!r}")
        if hessian not in ("exact", "nominal"):
            raise ValueError(f"hessian must be 'exact' or 'nominal', got {hessian!r}")
        if learned_dynamics not in ("exact", "linearized"):
            raise ValueError(f"learned_dynamics must be 'exact' or 'linearized', "
                             f"got {learned_dynamics!r}")
        if int(max_linearizations) < 1:
            raise ValueError(f"max_linearizations must be >= 1, got {max_linearizations}")
        if not (np.isfinite(linearization_tol) and linearization_tol > 0):
            raise ValueError(f"linearization_tol must be > 0, got {linearization_tol}")
        if int(replan_every) < 1:
            raise ValueError(f"replan_every must be >= 1, got {replan_every}")
        if not (np.isfinite(uncertainty_radius) and uncertainty_radius >= 0):
            raise ValueError(f"uncertainty_radius must be >= 0, got {uncertainty_radius}")
        defaults = (EPISODIC_SETTINGS if mode == "episodic" else DEFAULT_SETTINGS).get(
            model.name, {})
        if mode == "episodic":
            horizon = model.task.duration if horizon is None else horizon
        horizon = defaults.get("horizon") if horizon is None else horizon
        if horizon is None or not (np.isfinite(horizon) and horizon > 0):
            raise ValueError(f"horizon must be a positive number of seconds, got {horizon}")
        self.model = model
        self.learner = learner
        self.mode = mode
        self.horizon = float(horizon)
        self.n_nodes = int(n_nodes if n_nodes is not None else defaults.get("n_nodes", 12))
        self.n_intervals = int(n_intervals if n_intervals is not None
                               else defaults.get("n_intervals", 1))
        self.replan_every = int(replan_every)
        self.learn_online = bool(learn_online)
        self.uncertainty_radius = float(uncertainty_radius)
        self.control_at_t0 = control_at_t0
        self.solver = solver
        self.solver_options = dict(solver_options or {})
        self.max_solve_time = max_solve_time
        if not (0 <= state_margin < 0.5 and obstacle_margin >= 0):
            raise ValueError("state_margin must be in [0, 0.5) and obstacle_margin >= 0")
        self.state_margin = float(state_margin)
        if state_penalty is not None and not state_penalty > 0:
            raise ValueError(f"state_penalty must be > 0 or None, got {state_penalty}")
        self.state_penalty = None if state_penalty is None else float(state_penalty)
        self.max_iterations = int(max_iterations)
        self.jit = bool(jit)
        self.hessian = hessian
        self.learned_dynamics = learned_dynamics
        self.max_linearizations = int(max_linearizations)
        self.linearization_tol = float(linearization_tol)
        self.obstacle_margin = float(obstacle_margin)
        self.residual = ResidualModel(model, uncertain_indices, input_indices)

        self._model_source: Callable[[], ControlModel] | None = None
        self._ocp: GaussPseudospectralSolver | None = None
        self._theta_size = 0
        self._buffer = _Buffer()
        self.diagnostics: list[StepRecord] = []
        """One :class:`StepRecord` per ``act`` call since the last :meth:`reset`."""
        self.n_solves = 0
        self.n_failures = 0
        self.n_fallbacks = 0
        self.n_builds = 0
        self.n_retries = 0
        self.reset()

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_env(cls, env: gym.Env, learner: Any | None = None, *, oracle: bool = False,
                 **settings: Any) -> PseudospectralMPC:
        """An MPC built from ``env``'s nominal model and task (never the truth).

        The agent follows the env's nominal model: when a reset redraws it (e.g. the Dubins
        scenario), the new nominal parameter values are used from the next ``act`` on, without
        a rebuild.

        Args:
            env: a ``gp_envs`` environment.
            learner: see the class doc.
            oracle: plan with the *true* model instead (``gp_envs.oracle_model``): the
                upper-bound baseline, for benchmarks only.
            **settings: keyword settings of the class.
        """
        base = env.unwrapped
        if not hasattr(base, "nominal_model"):
            raise TypeError("from_env needs a gp_envs environment (with a nominal_model)")
        if oracle:
            import gp_envs

            source: Callable[[], ControlModel] = lambda: gp_envs.oracle_model(env)  # noqa: E731
        else:
            source = lambda: base.nominal_model  # noqa: E731
        agent = cls(source(), learner, **settings)
        agent._model_source = source
        return agent

    def pretrain(self, data: Transitions) -> PseudospectralMPC:
        """Fit the learner on initial transitions (Algorithm 1, line 1).

        Args:
            data: observed transitions, e.g. from :func:`gp_agents.data.collect_initial_data`.
        """
        if self.learner is None:
            raise ValueError("this agent has no learner to pretrain")
        if self._model_source is not None:  # learn against the env's current nominal model
            self._set_model(self._model_source(), learner_trained=False)
        Z, Y = self.residual.targets(data.X, data.U, data.X_next)
        self.learner.fit(Z, Y)
        self._ocp = None  # the learner's parameter layout may have changed
        return self

    def reset(self, model: ControlModel | None = None) -> None:
        """Forget the current plan and diagnostics (call at every env reset).

        Args:
            model: a new model of the same system (e.g. a redrawn nominal model); only its
                parameter values are used, the NLP is not rebuilt.
        """
        if model is not None:
            self._set_model(model)
        self._plan: _Plan | None = None
        self._step = 0
        self._buffer.clear()
        self.diagnostics = []

    def _set_model(self, model: ControlModel, learner_trained: bool | None = None) -> None:
        if model.name != self.model.name or model.param_names != self.model.param_names:
            raise ValueError(f"cannot swap a {self.model.name} model for a {model.name} model")
        if dict(model.params) != dict(self.model.params):
            if learner_trained is None:
                learner_trained = self._learner_is_fitted()
            if learner_trained:
                raise RuntimeError(
                    "the nominal model changed (e.g. redrawn by env.reset) after the learner was "
                    "trained on residuals of the previous one; call agent.pretrain(...) again "
                    "after the reset (or build a new agent)")
            self.residual = ResidualModel(model, self.residual.uncertain_indices,
                                          self.residual.input_indices)
        self.model = model

    def _learner_is_fitted(self) -> bool:
        if self.learner is None:
            return False
        try:
            self.learner.casadi_param_size()
        except (ValueError, RuntimeError):
            return False
        return True

    # ------------------------------------------------------------------ the OCP
    def _learner_theta(self) -> np.ndarray:
        """The learner's CasADi parameter vector (exact mode), or an empty one.

        In linearized mode the NLP holds no learner parameters: only fittedness is checked.
        """
        if self.learner is None:
            return np.zeros(0)
        try:
            if self._linearized:
                self.learner.casadi_param_size()
                return np.zeros(0)
            return np.asarray(self.learner.casadi_param_values(), float).ravel()
        except (ValueError, RuntimeError) as err:  # not fitted
            raise RuntimeError(
                "the learner is not fitted: call agent.pretrain(collect_initial_data(env)) "
                "or fit the learner before the first act()") from err

    @property
    def _linearized(self) -> bool:
        return self.learner is not None and self.learned_dynamics == "linearized"

    @property
    def _frozen_uncertainty(self) -> bool:
        """Whether the obstacle constraint uses a per-node variance (linearized mode)."""
        unc = self.residual.uncertain_indices
        return (self._linearized and bool(self.model.task.obstacles)
                and self.uncertainty_radius > 0 and 0 in unc and 1 in unc)

    def _build(self, theta_size: int) -> None:
        model, residual, learner = self.model, self.residual, self.learner
        linearized = self._linearized
        d, cols = residual.n_outputs, list(residual.jacobian_columns)
        n_j = d * (1 + len(cols))
        n_q = n_j + (2 if self._frozen_uncertainty else 0)
        if learner is not None and not linearized:
            size = self._learned_model_size(theta_size)
            if size > MAX_LEARNED_MODEL_SIZE:
                raise ValueError(
                    f"the learned model is too large to plan with: {size:.2g} (mean instructions "
                    f"x {residual.n_inputs} inputs x {self.n_nodes * self.n_intervals} nodes) > "
                    f"MAX_LEARNED_MODEL_SIZE = {MAX_LEARNED_MODEL_SIZE:.2g}; its derivatives "
                    "would not fit in memory. Use fewer nodes (n_nodes, n_intervals), "
                    "fewer training points, an SSGP, or learned_dynamics='linearized' (the "
                    "learner then stays outside the NLP).")
        k = len(model.param_names)
        f_param = model.casadi_parametric_function()
        task = model.task
        selector = ca.DM(residual.selector)

        def split(p: Any) -> tuple[Any, Any]:
            return p[:k], p[k:k + theta_size]

        def nominal_dynamics(x: Any, u: Any, p: Any, q: Any = None) -> Any:
            return f_param(x, u, p[:k])

        def dynamics(x: Any, u: Any, p: Any, q: Any) -> Any:
            xdot = nominal_dynamics(x, u, p)
            if linearized:  # q = [c; vec(J); ...]: the residual is c + J [x; u][cols]
                jac = ca.reshape(q[d:n_j], d, len(cols))
                xu = ca.vertcat(x, u)[cols]
                xdot = xdot + ca.mtimes(selector, q[:d] + ca.mtimes(jac, xu))
            elif learner is not None:
                xdot = xdot + ca.mtimes(selector, learner.casadi_mean(residual.features(x, u),
                                                                      split(p)[1]))
            return xdot

        half = 0.5 * (model.x_ub - model.x_lb)
        shrink = np.where(np.isfinite(half), self.state_margin * half, 0.0)
        x_lb, x_ub = model.x_lb + shrink, model.x_ub - shrink
        soft = self.state_penalty is not None
        bounded = [i for i in range(model.n_states)
                   if np.isfinite(x_lb[i]) or np.isfinite(x_ub[i])]

        def running_cost(x: Any, u: Any, p: Any) -> Any:
            cost = task.stage_cost(x, u)
            if soft:
                for i in bounded:
                    if np.isfinite(x_ub[i]):
                        cost += self.state_penalty * ca.fmax(0, x[i] - x_ub[i]) ** 2
                    if np.isfinite(x_lb[i]):
                        cost += self.state_penalty * ca.fmax(0, x_lb[i] - x[i]) ** 2
            return cost

        def terminal_cost(x0: Any, xf: Any, tf: Any, p: Any) -> Any:
            return task.terminal_cost(xf)

        path = None
        if task.obstacles:
            def path(x: Any, u: Any, p: Any, q: Any) -> Any:
                out = []
                for ob in task.obstacles:
                    dist = x[:2] - ca.DM(ob.center)
                    radius = ob.radius + task.body_radius + self.obstacle_margin
                    if self._frozen_uncertainty:  # the reference's variance, q[-2:]
                        radius = radius + self.uncertainty_radius * self._radius_along(
                            dist, q[n_q - 2], q[n_q - 1])
                    elif learner is not None and self.uncertainty_radius > 0:
                        radius = radius + self.uncertainty_radius * self._sym_uncertainty(
                            x, u, split(p)[1], dist)
                    out.append(radius**2 - ca.sumsqr(dist))  # <= 0 keeps clear
                return ca.vertcat(*out)

        problem = OptimalControlProblem(
            n_states=model.n_states, n_controls=model.n_controls, dynamics=dynamics,
            n_params=k if linearized else k + theta_size,
            n_node_params=n_q if linearized else 0, running_cost=running_cost,
            terminal_cost=terminal_cost,
            t0=0.0, tf=self.horizon, x_lb=model.x_lb if soft else x_lb,
            x_ub=model.x_ub if soft else x_ub,
            u_lb=model.u_lb,
            u_ub=model.u_ub, x0=np.zeros(model.n_states), path_constraints=path,
            hessian_dynamics=(nominal_dynamics if learner is not None and not linearized
                              and self.hessian == "nominal" else None),
        )
        options = dict(self.solver_options)
        if self.solver == "ipopt":
            ipopt = dict(options.get("ipopt", {}))
            ipopt.setdefault("max_iter", self.max_iterations)
            if self.max_solve_time is not None:
                ipopt.setdefault("max_wall_time", float(self.max_solve_time))
            options["ipopt"] = ipopt
        self._ocp = GaussPseudospectralSolver(
            problem, n_nodes=self.n_nodes, n_intervals=self.n_intervals, solver=self.solver,
            solver_options=options, jit=self.jit)
        self._theta_size = theta_size
        self.n_builds += 1

    def _learned_model_size(self, theta_size: int) -> int:
        """Instructions of the learned mean at one node x learner inputs x collocation nodes."""
        z = ca.SX.sym("z", self.residual.n_inputs)
        theta = ca.SX.sym("theta", theta_size)
        ops = ca.Function("learned_mean", [z, theta],
                          [self.learner.casadi_mean(z, theta)]).n_instructions()
        return int(ops) * self.residual.n_inputs * self.n_nodes * self.n_intervals

    def _sym_uncertainty(self, x: Any, u: Any, theta: Any, d: Any) -> Any:
        """One-step position std in the direction ``d`` (paper: Sigma_x1 = Sigma_xdot dt^2)."""
        unc = self.residual.uncertain_indices
        if 0 not in unc or 1 not in unc:
            return ca.DM(0.0)
        var = self.learner.casadi_variance(self.residual.features(x, u), theta)
        return self._radius_along(d, var[unc.index(0)], var[unc.index(1)])

    def _radius_along(self, d: Any, vx: Any, vy: Any) -> Any:
        """Radius along ``d`` of the 1-sigma ellipse with axes ``sqrt(vx) dt, sqrt(vy) dt``."""
        dist2 = ca.sumsqr(d) + 1e-12
        return self.model.dt / ca.sqrt((d[0] ** 2 / vx + d[1] ** 2 / vy) / dist2)

    # ------------------------------------------------------------------ acting
    def act(self, obs: np.ndarray) -> np.ndarray:
        """The action for the current observation.

        Args:
            obs: (n,) observed state.

        Returns:
            (m,) float32 action within the model's control bounds.

        Raises:
            ValueError: wrong shape or non-finite observation.
            RuntimeError: a learner that was never fitted.
        """
        start = time.perf_counter()
        x = np.asarray(obs, dtype=float)
        if x.shape != (self.model.n_states,):
            raise ValueError(f"obs must have shape ({self.model.n_states},), got {x.shape}")
        if not np.all(np.isfinite(x)):
            raise ValueError(f"obs must be finite, got {x}")
        if self._model_source is not None:
            current = self._model_source()
            if current is not self.model:
                self._set_model(current)

        replan = self._plan is None or (
            self.mode == "receding" and self._step - self._plan.step >= self.replan_every)
        record = dict(replanned=False, success=True, status="reuse", iterations=0,
                      solve_time=0.0, fallback=False, solves=0, linearization_error=0.0)
        if replan:
            self._flush_learning()
            record.update(self._replan(x))
        plan = self._plan
        assert plan is not None
        offset = (self._step - plan.step) * self.model.dt
        u = self._applied_control(plan.solution, offset)
        u32 = np.clip(u.astype(np.float32), self.model.u_lb.astype(np.float32),
                      self.model.u_ub.astype(np.float32))
        self.diagnostics.append(StepRecord(
            step=self._step, learner_samples=self._learner_samples(),
            act_time=time.perf_counter() - start, plan_t=plan.solution.t - offset,
            plan_x=plan.solution.x, action=u32.copy(), **record))
        self._step += 1
        return u32

    def _replan(self, x: np.ndarray) -> dict[str, Any]:
        theta = self._learner_theta()
        if self._ocp is None or theta.size != self._theta_size:
            self._build(theta.size)
        assert self._ocp is not None
        if self._linearized:
            p = np.asarray(self.model.param_vector, float)
        else:
            p = np.concatenate([self.model.param_vector, theta])
        if self._plan is not None:
            elapsed = (self._step - self._plan.step) * self.model.dt
            guess = self._aligned_guess(self._plan.solution.shift(elapsed), x)
        else:
            guess = self._goal_guess(x)
        sol, info = self._solve(p, x, guess, cold=self._plan is None)
        usable = sol.success and np.all(np.isfinite(sol.u))
        if not usable and self._plan is not None:
            # the warm start may be what misled the solver: retry once from a fresh guess
            retry, retry_info = self._solve(p, x, self._goal_guess(x), cold=True)
            self.n_retries += 1
            info = {key: info[key] + retry_info[key] if key != "linearization_error"
                    else retry_info[key] for key in info}
            if retry.success and np.all(np.isfinite(retry.u)):
                sol, usable = retry, True
        fallback = False
        if usable:
            self._plan = _Plan(sol, self._step)
        else:
            self.n_failures += 1
            previous_valid = (self._plan is not None and
                              (self._step - self._plan.step) * self.model.dt < self.horizon)
            if previous_valid:
                fallback = True
                self.n_fallbacks += 1
            elif np.all(np.isfinite(sol.u)) and np.all(np.isfinite(sol.x)):
                self._plan = _Plan(sol, self._step)  # best effort: the solver's last iterate
            else:
                self._plan = _Plan(self._hold_plan(x), self._step)
                fallback = True
                self.n_fallbacks += 1
        return dict(replanned=True, success=bool(sol.success), status=sol.status,
                    iterations=info["iterations"], solve_time=info["solve_time"],
                    fallback=fallback, solves=info["solves"],
                    linearization_error=info["linearization_error"])

    def _solve(self, p: np.ndarray, x: np.ndarray, guess: Any, cold: bool = False
               ) -> tuple[OCPSolution, dict[str, Any]]:
        """One solve, or the re-linearization loop of ``learned_dynamics="linearized"``.

        In that loop a plan whose expansion error exceeds 1, or a failed solve whose last
        iterate is finite, is re-linearized about and re-solved while solves remain:
        ``max_linearizations`` of them, at least :data:`COLD_START_LINEARIZATIONS` when
        ``cold`` (the reference is the straight-line goal guess, not a previous plan; an
        expansion about it can make the NLP infeasible).

        Returns:
            The last solution and ``iterations``, ``solve_time`` (summed over the solves),
            ``solves`` and ``linearization_error`` (the last plan's largest expansion error
            relative to its tolerance; 0 in exact mode, NaN if no finite plan came out).
        """
        assert self._ocp is not None
        if not self._linearized:
            sol = self._ocp.solve(p=p, x0=x, initial_guess=guess)
            self.n_solves += 1
            return sol, dict(iterations=int(sol.iterations), solve_time=float(sol.solve_time),
                             solves=1, linearization_error=0.0)
        t_nodes = self._ocp.node_times()
        expansion = self._expand(guess.state(t_nodes), guess.control(t_nodes))
        iterations, solve_time, error = 0, 0.0, np.nan  # nan: no finite plan to check
        limit = max(self.max_linearizations, COLD_START_LINEARIZATIONS if cold else 1)
        for solves in range(1, limit + 1):
            sol = self._ocp.solve(p=p, x0=x, initial_guess=guess,
                                  node_params=expansion["node_params"])
            self.n_solves += 1
            iterations += int(sol.iterations)
            solve_time += float(sol.solve_time)
            if not (np.all(np.isfinite(sol.x)) and np.all(np.isfinite(sol.u))):
                break
            X, U = sol.x_nodes, sol.u
            mean = self.learner.predict(self.residual.inputs(X, U))
            error = _expansion_error(expansion, np.hstack([X, U]), mean, self.linearization_tol)
            if (sol.success and error <= 1.0) or solves == limit:
                break
            expansion, guess = self._expand(X, U), sol
        return sol, dict(iterations=iterations, solve_time=solve_time, solves=solves,
                         linearization_error=float(error))

    def _expand(self, X: np.ndarray, U: np.ndarray) -> dict[str, np.ndarray]:
        """The residual's first-order expansion about node states X (M, n), controls U (M, m).

        Returns:
            ``mean`` (M, d_out), ``jacobian`` (M, d_out, n + m), ``points`` (M, n + m) and
            ``node_params`` (M, n_q): per node ``[c; vec(J_c)]`` with ``c = mean - J [x; u]``
            and ``J_c`` the columns of ``J`` the learner's input depends on
            (``residual.jacobian_columns``, column-major ``vec``), then the variances of x and
            y with frozen uncertainty.
        """
        X, U = np.atleast_2d(X), np.atleast_2d(U)
        M = X.shape[0]
        mean, jac, var = self.residual.linearize(self.learner, X, U,
                                                 variance=self._frozen_uncertainty)
        points = np.hstack([X, U])
        c = mean - np.einsum("kij,kj->ki", jac, points)
        cols = list(self.residual.jacobian_columns)
        blocks = [c, jac[:, :, cols].transpose(0, 2, 1).reshape(M, -1)]
        if var is not None:
            unc = self.residual.uncertain_indices
            blocks.append(var[:, [unc.index(0), unc.index(1)]])
        return dict(mean=mean, jacobian=jac, points=points, node_params=np.hstack(blocks))

    def _goal_guess(self, x: np.ndarray) -> InitialGuess:
        """Cold-start guess: a straight line in state space from ``x`` to the task's goal.

        Reaching the goal within the horizon is what the cost asks for; starting the NLP from
        "stay where you are" lands the swing-up in a poor local minimum.
        """
        goal = self.model.task.goal.copy()
        for i in self.model.task.periodic_indices:  # head for the nearest copy of the goal
            goal[i] = x[i] - self.model.task.error(x)[i]
        t = np.linspace(0.0, self.horizon, 2 * self.n_nodes * self.n_intervals + 1)
        s = (t / self.horizon)[:, None]
        states = np.clip((1 - s) * x + s * goal, self.model.x_lb, self.model.x_ub)
        u = np.clip(self.model.task.u_ref, self.model.u_lb, self.model.u_ub)
        return InitialGuess(t=t, x=states, t_u=t, u=np.tile(u, (t.size, 1)))

    def _aligned_guess(self, guess: InitialGuess, x: np.ndarray) -> InitialGuess:
        """Shift angle trajectories of a warm start by 2 pi k to start at the measured angle."""
        if not self.model.angle_indices:
            return guess
        gx = guess.x.copy()
        for i in self.model.angle_indices:
            gx[:, i] += 2 * np.pi * np.round((x[i] - gx[0, i]) / (2 * np.pi))
        return InitialGuess(t=guess.t, x=gx, t_u=guess.t_u, u=guess.u, tf=guess.tf)

    def _hold_plan(self, x: np.ndarray) -> OCPSolution:
        """A constant plan at ``u_ref`` (used only when no solution exists at all)."""
        assert self._ocp is not None
        u = np.clip(self.model.task.u_ref, self.model.u_lb, self.model.u_ub)
        t = np.array([0.0, self.horizon])
        guess = InitialGuess(t=t, x=np.vstack([x, x]), t_u=t, u=np.vstack([u, u]))
        return _ConstantPlan(guess, self.model)  # type: ignore[return-value]

    def _applied_control(self, sol: OCPSolution, offset: float) -> np.ndarray:
        if isinstance(sol, _ConstantPlan):
            return sol.control(offset)
        if self.control_at_t0 == "period_mean":
            nodes, weights = _PERIOD_QUADRATURE
            t = offset + 0.5 * self.model.dt * (nodes + 1.0)
            u = 0.5 * weights @ np.atleast_2d(sol.control(t))
        elif self.control_at_t0 == "extrapolate":
            u = sol.control(offset)
        else:  # first_node: hold each node's value from the node before it
            idx = min(int(np.searchsorted(sol.t_nodes, offset)), len(sol.t_nodes) - 1)
            u = sol.u[idx]
        return np.clip(np.asarray(u, float).ravel(), self.model.u_lb, self.model.u_ub)

    # ------------------------------------------------------------------ learning
    def observe(self, obs: np.ndarray, action: np.ndarray, next_obs: np.ndarray) -> None:
        """Record a transition; the learner is updated before the next solve (Algorithm 1).

        Args:
            obs: (n,) state at the start of the period. action: (m,) applied action.
            next_obs: (n,) state one control period later.
        """
        x = np.asarray(obs, float)
        u = np.asarray(action, float).ravel()
        xn = np.asarray(next_obs, float)
        n, m = self.model.n_states, self.model.n_controls
        if x.shape != (n,) or xn.shape != (n,) or u.shape != (m,):
            raise ValueError(f"observe expects obs/next_obs ({n},) and action ({m},), got "
                             f"{x.shape}, {xn.shape}, {u.shape}")
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(xn)) and np.all(np.isfinite(u))):
            raise ValueError("observe got a non-finite value")
        if self.mode == "episodic" or not self.learn_online or self.learner is None:
            return
        if not hasattr(self.learner, "update"):
            return
        self._buffer.X.append(x)
        self._buffer.U.append(np.clip(u, self.model.u_lb, self.model.u_ub))
        self._buffer.X_next.append(xn)

    def _flush_learning(self) -> None:
        if not self._buffer.X:
            return
        Z, Y = self.residual.targets(np.array(self._buffer.X), np.array(self._buffer.U),
                                     np.array(self._buffer.X_next))
        self._buffer.clear()
        self.learner.update(Z, Y)

    def _learner_samples(self) -> int:
        return int(getattr(self.learner, "n_samples_seen_", 0)) if self.learner is not None else 0

    # ------------------------------------------------------------------ diagnostics
    def diagnostics_arrays(self) -> dict[str, np.ndarray]:
        """Per-step diagnostics as arrays (for ``np.savez_compressed`` and plots).

        Returns:
            dict of arrays of length T (steps): ``replanned, success, iterations, solves,
            linearization_error, solve_time, act_time, fallback, learner_samples, action (T,
            m)`` and ``status`` (strings), and
            the predicted trajectories ``plan_t (T, N)``, ``plan_x (T, N, n)``.
        """
        d = self.diagnostics
        if not d:
            return {}
        return {
            "step": np.array([r.step for r in d]),
            "replanned": np.array([r.replanned for r in d]),
            "success": np.array([r.success for r in d]),
            "status": np.array([r.status for r in d]),
            "iterations": np.array([r.iterations for r in d]),
            "solves": np.array([r.solves for r in d]),
            "linearization_error": np.array([r.linearization_error for r in d]),
            "solve_time": np.array([r.solve_time for r in d]),
            "act_time": np.array([r.act_time for r in d]),
            "fallback": np.array([r.fallback for r in d]),
            "learner_samples": np.array([r.learner_samples for r in d]),
            "action": np.array([r.action for r in d]),
            "plan_t": _stack_ragged([r.plan_t for r in d]),
            "plan_x": _stack_ragged([r.plan_x for r in d]),
        }


class _ConstantPlan:
    """Stand-in for a solution when the very first solve fails with nothing usable."""

    def __init__(self, guess: InitialGuess, model: ControlModel) -> None:
        self._guess = guess
        self.t = guess.t
        self.x = guess.x
        self.u = guess.u
        self.t_nodes = guess.t_u
        self.success = False

    def control(self, t: Any) -> np.ndarray:
        return self._guess.control(t)[0]

    def shift(self, dt: float) -> InitialGuess:
        return self._guess


def _expansion_error(expansion: Mapping[str, np.ndarray], points: np.ndarray, mean: np.ndarray,
                     rtol: float, atol: float = 1e-3) -> float:
    """Largest error of ``expansion`` at the plan's nodes, as a fraction of its tolerance.

    Args:
        expansion: from :meth:`PseudospectralMPC._expand`.
        points: (M, n + m) the plan's node states and controls.
        mean: (M, d_out) the learned residual there.
        rtol, atol: per output j, the tolerance is ``rtol * max_k |mean_j| + atol`` (units of
            the residual, a state rate).
    """
    dz = points - expansion["points"]
    predicted = expansion["mean"] + np.einsum("kij,kj->ki", expansion["jacobian"], dz)
    err = np.max(np.abs(mean - predicted), axis=0)
    tol = rtol * np.max(np.abs(mean), axis=0) + atol
    return float(np.max(err / tol))


def _stack_ragged(arrays: list[np.ndarray]) -> np.ndarray:
    shapes = {a.shape for a in arrays}
    if len(shapes) == 1:
        return np.stack(arrays)
    longest = max(a.shape[0] for a in arrays)
    out = np.full((len(arrays), longest, *arrays[0].shape[1:]), np.nan)
    for i, a in enumerate(arrays):
        out[i, : a.shape[0]] = a
    return out
