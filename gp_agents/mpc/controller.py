"""Pseudospectral model predictive control with an online-learned GP residual.

The paper's Algorithm 1 ("Model Predictive Pseudospectral Control with Online Learning"):

1. initialise the (sparse spectrum) GP with initial training data (:meth:`PseudospectralMPC.
   pretrain`, data from :func:`gp_agents.data.collect_initial_data`);
2. solve the Gauss pseudospectral OCP from the current state (:mod:`gp_agents.mpc.ocp`);
3. roll out the first ``p`` control periods of the plan (``replan_every``);
4. update the GP with the ``p`` new transitions (:meth:`PseudospectralMPC.observe`);
5. warm-start the next solve from the previous plan shifted in time; repeat.

The pieces, one file each: the planning model (:mod:`~gp_agents.mpc.planning_model`: nominal
physics plus a learned term), how the learner enters the NLP (:mod:`~gp_agents.mpc.gp_in_nlp`,
:mod:`~gp_agents.mpc.gp_linearized`), the OCP and the plan/plant interface
(:mod:`~gp_agents.mpc.ocp`: held control periods), solving it robustly
(:mod:`~gp_agents.mpc.planner`) and when to plan (:mod:`~gp_agents.mpc.schedule`).
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable, Mapping
from typing import Any, Literal

import gymnasium as gym
import numpy as np

from gp_agents.data import Transitions
from gp_agents.mpc.active_set import ActiveSetQP
from gp_agents.mpc.diagnostics import StepRecord, records_to_arrays
from gp_agents.mpc.gp_in_nlp import GPInNLP
from gp_agents.mpc.gp_linearized import LinearizedGP
from gp_agents.mpc.gp_pattern import PatternLinearizedGP
from gp_agents.mpc.gp_zero_order import ZeroOrderGP
from gp_agents.mpc.learned_term import LearnedTerm, NoLearnedTerm
from gp_agents.mpc.ocp import Constraints
from gp_agents.mpc.planner import Plan, Planner
from gp_agents.mpc.planning_model import PlanningModel
from gp_agents.mpc.rti import RTIPlanner, check_levenberg_marquardt
from gp_agents.mpc.rti_split import SplitRTIPlanner
from gp_agents.mpc.schedule import Episodic, RecedingHorizon, planning_defaults
from gp_agents.residual import ResidualModel
from gp_envs.model import ControlModel
from gp_envs.systems import PlanningDefaults

SCHEMES: dict[str, type[Planner]] = {"converged": Planner, "rti": RTIPlanner,
                                     "rti-split": SplitRTIPlanner}
"""``scheme`` names and their planners."""

LEARNED_TERMS: dict[str, type[LearnedTerm]] = {"exact": GPInNLP, "linearized": LinearizedGP,
                                               "linearized-pattern": PatternLinearizedGP,
                                               "zero-order": ZeroOrderGP}
"""``learned_dynamics`` names: the GP inside the NLP (the paper's OCP), linearized per node,
linearized on the nominal model's Jacobian pattern (the rest adjoint-corrected in the RTI), or
its value frozen per node (with the RTI's adjoint correction)."""


def default_learned_dynamics(scheme: str, defaults: PlanningDefaults | None) -> str:
    """The ``learned_dynamics`` name an MPC of ``scheme`` uses when given none: ``"exact"`` (the
    paper's OCP, the GP inside the NLP) for ``"converged"``; for the real-time iterations, the
    system's registered ``rti_learned_dynamics`` (``"linearized"`` for an unregistered system).

    Raises:
        ValueError: the registered name is not one of :data:`LEARNED_TERMS`.
    """
    if scheme == "converged":
        return "exact"
    name = defaults.rti_learned_dynamics if defaults is not None else "linearized"
    if name not in LEARNED_TERMS:
        raise ValueError(f"the system's PlanningDefaults.rti_learned_dynamics {name!r} is not "
                         f"one of {list(LEARNED_TERMS)}")
    return name


class EnvNominalModel:
    """The model source of :meth:`PseudospectralMPC.from_env`: the env's current nominal model
    (a class, not a closure, so that an agent pickles with its env)."""

    def __init__(self, env: gym.Env) -> None:
        self.env = env

    def __call__(self) -> ControlModel:
        return self.env.unwrapped.nominal_model


class PseudospectralMPC:
    """Gauss pseudospectral MPC on nominal physics plus an optional learned residual.

    Args:
        model: the model the controller plans with: an env's ``nominal_model`` (or, for an
            upper-bound baseline, a true model the benchmark hands in).
        learner: a residual learner (``IncrementalSSGP``, ``SSGP``, ``ExactGP``) or None (pure
            physics). It must be fitted before the first ``act`` (:meth:`pretrain`).
        mode: ``"receding"`` (Algorithm 1) or ``"episodic"`` (plan once over the task's whole
            duration at the first ``act``, execute open loop; no learning).
        horizon: receding horizon in seconds (default: the system's registered
            :class:`gp_envs.systems.PlanningDefaults`, as for ``n_nodes``, ``n_intervals``,
            the episodic nodes per period and ``qp_solver``; required for an unregistered
            system).
        n_nodes, n_intervals: LG nodes per interval and intervals after the held periods.
        replan_every: ``p``, periods executed from each plan (all held in the plan).
        held_nodes: LG nodes of each held period (episodic: of every period).
        learn_online: feed observed transitions to ``learner.update`` (if it has one).
        uncertain_indices: state components with a learned residual (default: the model's
            accelerations). input_indices: components fed to the learner (None: all;
            ``"model"``: those the parametric nominal model's uncertain rates depend on).
        sensitivities: the learner also sees the nominal model's parameter sensitivities
            (:class:`~gp_agents.residual.ResidualModel`): with a learner with linear features
            the residual gets an explicit parametric part.
        uncertainty_radius: ``kappa`` >= 0 of the obstacle constraint (:mod:`~gp_agents.mpc.
            ocp`); 0 reproduces the paper's run.
        learned_dynamics: how the learner enters the NLP: ``"exact"`` (:class:`GPInNLP`),
            ``"linearized"`` (:class:`LinearizedGP`), ``"linearized-pattern"``
            (:class:`~gp_agents.mpc.gp_pattern.PatternLinearizedGP`: the linearization's
            entries on the nominal Jacobian pattern only, the nominal QP structure),
            ``"zero-order"`` (:class:`ZeroOrderGP`: the value frozen per node, the nominal QP
            structure; both meant for ``scheme="rti"``, whose steps correct their gradient
            with the multipliers), or a configured term
            instance (e.g.
            ``LinearizedGP(max_linearizations=3)``, ``GPInNLP(hessian="nominal")``; copied).
            None: :func:`default_learned_dynamics` (``"exact"`` when converged; the system's
            registered ``rti_learned_dynamics`` for the RTI schemes).
        solver, solver_options, jit: the NLP solver (:class:`~gp_agents.mpc.planner.Planner`).
        max_iterations: iteration cap of one solve; the only cap (no wall-clock limit).
        state_margin, state_penalty, obstacle_margin: :class:`~gp_agents.mpc.ocp.Constraints`.
        scheme: ``"converged"`` (every plan solved to convergence), ``"rti"`` (a converged
            solve at a cold start, then one Gauss-Newton SQP step per replan:
            :class:`~gp_agents.mpc.rti.RTIPlanner`) or ``"rti-split"`` (the same step split
            into a preparation, done in ``act`` after the action is known together with the
            learner update, and a feedback phase, the QP with the measured state:
            :class:`~gp_agents.mpc.rti_split.SplitRTIPlanner`; each step's record has its
            ``preparation_time``, the rest of ``act_time`` is the latency).
        qp_solver: the RTI step's QP solver: a CasADi conic plugin name,
            ``"active-set:<plugin>"`` or an :class:`~gp_agents.mpc.active_set.ActiveSetQP`
            (:class:`~gp_agents.mpc.rti.RTIPlanner`; default per system, chosen by
            measurement: :func:`~gp_agents.mpc.schedule.planning_defaults`).
        levenberg_marquardt: the RTI step's ``mu`` >= 0 on the QP Hessian's diagonal
            (:class:`~gp_agents.mpc.rti.RTIPlanner`; default per system, 0 where none is
            registered: :func:`~gp_agents.mpc.schedule.planning_defaults`).
        warm_start_duals: a warm IPOPT solve also starts from the previous solve's multipliers
            with IPOPT's warm-start options (:class:`~gp_agents.mpc.planner.Planner`). None: off
            for ``"converged"``, on for the RTI's fallback solves. Measured (``rti`` preset,
            ``benchmarks/results/rti/report.md``): 0.55-0.75x the converged step on the
            quadrotor and Dubins vehicle at the same outcomes, but a 2.5% higher cost for the
            oracle cart pole (13.32 vs 12.99, intervals disjoint: it stays in the previous
            plan's basin of the swing-up), so the converged default stays off.
    """

    def __init__(self, model: ControlModel, learner: Any | None = None, *,
                 mode: Literal["receding", "episodic"] = "receding",
                 horizon: float | None = None, n_nodes: int | None = None,
                 n_intervals: int | None = None, replan_every: int = 1, held_nodes: int = 3,
                 learn_online: bool = True, uncertain_indices: tuple[int, ...] | None = None,
                 input_indices: tuple[int, ...] | Literal["model"] | None = None,
                 sensitivities: bool = False, uncertainty_radius: float = 0.0,
                 learned_dynamics: str | LearnedTerm | None = None, solver: str = "ipopt",
                 solver_options: Mapping[str, Any] | None = None, max_iterations: int = 500,
                 state_margin: float = 0.05, state_penalty: float | None = 1e4,
                 obstacle_margin: float = 0.1, jit: bool = False,
                 scheme: Literal["converged", "rti", "rti-split"] = "converged",
                 qp_solver: str | ActiveSetQP | None = None,
                 levenberg_marquardt: float | None = None,
                 warm_start_duals: bool | None = None) -> None:
        if not isinstance(model, ControlModel):
            raise TypeError(f"model must be a gp_envs ControlModel, got {type(model).__name__}")
        defaults = planning_defaults(model)
        if mode == "receding":
            if horizon is None:
                if defaults is None:
                    raise ValueError(f"system {model.name!r} is not registered "
                                     f"(gp_envs.register_system): pass horizon=")
                horizon = defaults.horizon
            if not (np.isfinite(horizon) and horizon > 0):
                raise ValueError(f"horizon must be a positive number of seconds, got {horizon}")
            self.schedule: RecedingHorizon | Episodic = RecedingHorizon(
                horizon, (defaults.n_nodes if defaults else 12) if n_nodes is None else n_nodes,
                (defaults.n_intervals if defaults else 1) if n_intervals is None
                else n_intervals, replan_every, held_nodes)
        elif mode == "episodic":
            self.schedule = Episodic(model.task.duration if horizon is None else horizon,
                                     (defaults.nodes_per_period if defaults else held_nodes)
                                     if n_nodes is None else n_nodes)
        else:
            raise ValueError(f"mode must be 'receding' or 'episodic', got {mode!r}")
        if scheme not in SCHEMES:
            raise ValueError(f"scheme must be one of {list(SCHEMES)}, got {scheme!r}")
        self.scheme = scheme
        self.qp_solver = qp_solver or (defaults.qp_solver if defaults else "osqp")
        if levenberg_marquardt is None:
            levenberg_marquardt = defaults.levenberg_marquardt if defaults else 0.0
        self.levenberg_marquardt = check_levenberg_marquardt(levenberg_marquardt)
        self.warm_start_duals = None if warm_start_duals is None else bool(warm_start_duals)
        if learned_dynamics is None:
            learned_dynamics = default_learned_dynamics(scheme, defaults)
        if isinstance(learned_dynamics, str):
            if learned_dynamics not in LEARNED_TERMS:
                raise ValueError(f"learned_dynamics must be one of {list(LEARNED_TERMS)} or a "
                                 f"LearnedTerm, got {learned_dynamics!r}")
            learned_dynamics = LEARNED_TERMS[learned_dynamics]()
        elif not isinstance(learned_dynamics, LearnedTerm):
            raise TypeError(f"learned_dynamics must be a name or a LearnedTerm, got "
                            f"{type(learned_dynamics).__name__}")
        self.mesh = self.schedule.mesh(model.dt)  # validates horizon against the held periods
        self.constraints = Constraints(state_margin, state_penalty, obstacle_margin,
                                       float(uncertainty_radius))
        self.model, self.learner, self.mode = model, learner, mode
        self.learned_dynamics = learned_dynamics
        self.learn_online = bool(learn_online)
        self.solver, self.solver_options = solver, dict(solver_options or {})
        self.max_iterations, self.jit = int(max_iterations), bool(jit)
        self.residual = ResidualModel(model, uncertain_indices, input_indices, sensitivities)
        self.term: LearnedTerm = (copy.deepcopy(learned_dynamics) if learner is not None
                                  else NoLearnedTerm())
        self._attach()
        self.planner: Planner | None = None
        self._model_source: Callable[[], ControlModel] | None = None
        self._buffer: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self.n_builds = 0
        self.reset()

    def __getstate__(self) -> dict[str, Any]:
        """Pickle everything but the compiled NLP, which is rebuilt at the next ``act`` (the
        learner, the current plan and the diagnostics travel; so does the env of a
        ``from_env`` agent, whose nominal model it follows)."""
        state = self.__dict__.copy()
        state["planner"] = None
        return state

    @property
    def horizon(self) -> float:
        """Planning horizon in seconds."""
        return self.mesh.horizon

    @property
    def plan(self) -> Plan | None:
        """The plan the current actions come from (None before the first ``act``)."""
        return self._plan

    @classmethod
    def from_env(cls, env: gym.Env, learner: Any | None = None, *,
                 model_source: Callable[[], ControlModel] | None = None,
                 **settings: Any) -> PseudospectralMPC:
        """An MPC of ``env``'s nominal model and task (never the truth).

        The agent follows the env's nominal model: when a reset redraws it (the Dubins
        scenario), the new parameter values are used from the next ``act`` on, without a
        rebuild.

        Args:
            env: a ``gp_envs`` environment.
            learner: see the class doc.
            model_source: where the model comes from at each ``act`` instead of
                ``env.unwrapped.nominal_model`` (a benchmark's oracle passes
                ``lambda: gp_envs.oracle_model(env)``).
            **settings: keyword settings of the class.
        """
        base = env.unwrapped
        if not hasattr(base, "nominal_model"):
            raise TypeError("from_env needs a gp_envs environment (with a nominal_model)")
        source = model_source or EnvNominalModel(env)
        agent = cls(source(), learner, **settings)
        agent._model_source = source
        return agent

    def pretrain(self, data: Transitions) -> PseudospectralMPC:
        """Fit the learner on initial transitions (Algorithm 1, line 1)."""
        if self.learner is None:
            raise ValueError("this agent has no learner to pretrain")
        if len(data) < 1:
            raise ValueError("pretrain needs at least one transition, got none")
        if self._model_source is not None:  # learn against the env's current nominal model
            self._set_model(self._model_source(), learner_trained=False)
        self.learner.fit(*self.residual.targets(data.X, data.U, data.X_next))
        self.planner = None  # the learner's parameter layout may have changed
        return self

    def reset(self) -> None:
        """Forget the current plan, buffered transitions and diagnostics (at every env reset)."""
        self._plan: Plan | None = None
        self._step = 0
        self._buffer.clear()
        self.diagnostics: list[StepRecord] = []

    def _attach(self) -> None:
        unc = self.residual.uncertain_indices
        variance = (self.learner is not None and self.constraints.uncertainty_radius > 0
                    and bool(self.model.task.obstacles) and 0 in unc and 1 in unc)
        self.term.attach(self.residual, self.learner, variance)

    def _set_model(self, model: ControlModel, learner_trained: bool | None = None) -> None:
        if model.name != self.model.name or model.param_names != self.model.param_names:
            raise ValueError(f"cannot swap a {self.model.name} model for a {model.name} model")
        if dict(model.params) != dict(self.model.params):
            trained = self._learner_fitted() if learner_trained is None else learner_trained
            if trained:
                raise RuntimeError(
                    "the nominal model changed (e.g. redrawn by env.reset) after the learner was "
                    "trained on residuals of the previous one; call agent.pretrain(...) again "
                    "after the reset (or build a new agent)")
            self.residual = ResidualModel(model, self.residual.uncertain_indices,
                                          self.residual.input_indices,
                                          self.residual.sensitivities)
            self._attach()
        self.model = model
        if self.planner is not None:
            self.planner.planning.model = model

    def _learner_fitted(self) -> bool:
        try:
            return self.learner is not None and self.learner.casadi_param_size() >= 0
        except (ValueError, RuntimeError):
            return False

    def _planner(self) -> Planner:
        """The planner, (re)built if the learned term's parameter layout changed."""
        size = self.term.param_values().size  # raises RuntimeError for an unfitted learner
        planning = self.planner.planning if self.planner is not None else None
        if planning is None or size != planning.n_params - planning.n_nominal:
            planner = SCHEMES[self.scheme]
            extra: dict[str, Any] = ({"qp_solver": self.qp_solver,
                                      "levenberg_marquardt": self.levenberg_marquardt}
                                     if issubclass(planner, RTIPlanner) else {})
            if self.warm_start_duals is not None:
                extra["warm_start_duals"] = self.warm_start_duals
            self.planner = planner(
                PlanningModel(self.model, self.residual, self.term), self.mesh,
                self.constraints, solver=self.solver, solver_options=self.solver_options,
                max_iterations=self.max_iterations, jit=self.jit, **extra)
            self.n_builds += 1
        return self.planner

    # ------------------------------------------------------------------ acting
    def act(self, obs: np.ndarray) -> np.ndarray:
        """The (m,) float32 action for the (n,) observation, within the control bounds.

        Raises:
            ValueError: wrong shape or non-finite observation.
            RuntimeError: a learner that was never fitted.
        """
        start = time.perf_counter()
        x = _checked(obs, (self.model.n_states,), "obs")
        if self._model_source is not None and self._model_source() is not self.model:
            self._set_model(self._model_source())
        record: dict[str, Any] = dict(replanned=False, success=True, status="reuse",
                                      iterations=0, solve_time=0.0, fallback=False, solves=0,
                                      linearization_error=0.0, preparation_time=0.0)
        split = self.scheme == "rti-split"
        if self.schedule.due(self._step, self._plan):
            if not split:
                self._flush_learning()
            self._plan, solved = self._planner().plan(x, self._plan, self._step)
            record.update(replanned=True, **solved)
        plan = self._plan
        assert plan is not None
        u = plan.action(self._step, self.model.u_lb, self.model.u_ub).astype(np.float32)
        u = np.clip(u, self.model.u_lb.astype(np.float32), self.model.u_ub.astype(np.float32))
        if split and record["replanned"]:  # the preparation of the next replan, after u
            prepared = time.perf_counter()
            self._flush_learning()
            planner = self._planner()
            assert isinstance(planner, SplitRTIPlanner)
            info = planner.prepare(plan, plan.step + self.mesh.held_periods)
            if record["status"] == "RTI":
                record["linearization_error"] = info["linearization_error"]
            record["preparation_time"] = time.perf_counter() - prepared
        offset = (self._step - plan.step) * self.model.dt
        self.diagnostics.append(StepRecord(
            step=self._step, learner_samples=self._learner_samples(), action=u.copy(),
            act_time=time.perf_counter() - start, plan_t=plan.solution.t - offset,
            plan_x=plan.solution.x, **record))
        self._step += 1
        return u

    # ------------------------------------------------------------------ learning
    def observe(self, obs: np.ndarray, action: np.ndarray, next_obs: np.ndarray) -> None:
        """Record a transition; the learner is updated before the next solve (Algorithm 1).

        Args:
            obs: (n,) state at the start of the period. action: (m,) applied action.
            next_obs: (n,) state one control period later.
        """
        n, m = self.model.n_states, self.model.n_controls
        x, xn = _checked(obs, (n,), "obs"), _checked(next_obs, (n,), "next_obs")
        u = _checked(np.asarray(action, float).reshape(-1), (m,), "action")
        if (self.schedule.learns and self.learn_online and self.learner is not None
                and hasattr(self.learner, "update")):
            self._buffer.append((x, np.clip(u, self.model.u_lb, self.model.u_ub), xn))

    def _flush_learning(self) -> None:
        if self._buffer:
            X, U, Xn = (np.array(a) for a in zip(*self._buffer, strict=True))
            self._buffer.clear()
            self.learner.update(*self.residual.targets(X, U, Xn))

    def _learner_samples(self) -> int:
        return int(getattr(self.learner, "n_samples_seen_", 0)) if self.learner is not None else 0

    # ------------------------------------------------------------------ diagnostics
    @property
    def n_solves(self) -> int:
        """NLP solves since construction (retries and re-linearizations included)."""
        return self.planner.n_solves if self.planner is not None else 0

    @property
    def n_failures(self) -> int:
        """Replans whose solves all failed."""
        return self.planner.n_failures if self.planner is not None else 0

    @property
    def n_fallbacks(self) -> int:
        """Replans that kept an older (or a constant) plan."""
        return self.planner.n_fallbacks if self.planner is not None else 0

    @property
    def n_capped(self) -> int:
        """Solves that ran into the iteration cap."""
        return self.planner.n_capped if self.planner is not None else 0

    def diagnostics_arrays(self) -> dict[str, np.ndarray]:
        """Per-step diagnostics (:class:`~gp_agents.mpc.diagnostics.StepRecord` fields) as
        arrays of length T: ``replanned, success, status, iterations, solves,
        linearization_error, solve_time, act_time, fallback, learner_samples, action (T, m),
        plan_t (T, N), plan_x (T, N, n)``."""
        return records_to_arrays(self.diagnostics)


def _checked(value: Any, shape: tuple[int, ...], name: str) -> np.ndarray:
    """``value`` as a float array of ``shape``, finite, else a ``ValueError``."""
    arr = np.asarray(value, dtype=float)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr}")
    return arr
