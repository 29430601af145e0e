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
import dataclasses
import time
import warnings
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from gp_agents.data import Transitions
from gp_agents.mpc.active_set import ActiveSetQP
from gp_agents.mpc.diagnostics import (
    DEGRADED_FRACTION,
    MIN_DEGRADED_REPLANS,
    ControllerDegradedWarning,
    StepRecord,
    records_to_arrays,
)
from gp_agents.mpc.gp_in_nlp import GPInNLP
from gp_agents.mpc.gp_linearized import LinearizedGP
from gp_agents.mpc.gp_pattern import PatternLinearizedGP
from gp_agents.mpc.gp_zero_order import ZeroOrderGP
from gp_agents.mpc.learned_term import LearnedTerm, NoLearnedTerm
from gp_agents.mpc.ocp import Constraints
from gp_agents.mpc.planner import CAPPED_STATUSES, Plan, Planner
from gp_agents.mpc.planning_model import PlanningModel
from gp_agents.mpc.rti import RTIPlanner
from gp_agents.mpc.rti_split import SplitRTIPlanner
from gp_agents.mpc.schedule import Episodic, RecedingHorizon
from gp_agents.mpc.settings import RTI, Converged, Residual, scheme_settings
from gp_agents.mpc.tuning import rti_tuning
from gp_agents.residual import ResidualModel
from gp_envs.model import ControlModel
from gp_envs.wrapper import nominal_model

LEARNED_TERMS: dict[str, type[LearnedTerm]] = {"exact": GPInNLP, "linearized": LinearizedGP,
                                               "linearized-pattern": PatternLinearizedGP,
                                               "zero-order": ZeroOrderGP}
"""``term`` names: the GP inside the NLP (the paper's OCP), linearized per node, linearized on
the nominal model's Jacobian pattern (the rest adjoint-corrected in the RTI), or its value frozen
per node (with the RTI's adjoint correction)."""

LEARNER_METHODS = ("fit", "predict", "predict_gradient", "casadi_mean", "casadi_param_size",
                   "casadi_param_values")
"""What the MPC calls on a learner (:class:`~gp_agents.learners.base.BaseGPLearner` has them)."""

LEGACY_SETTINGS: dict[str, str] = {
    "mode": "horizon=RecedingHorizon(...) or Episodic(...)",
    "n_nodes": "horizon=RecedingHorizon(n_nodes=...) (Episodic(nodes_per_period=...))",
    "n_intervals": "horizon=RecedingHorizon(n_intervals=...)",
    "replan_every": "horizon=RecedingHorizon(replan_every=...)",
    "held_nodes": "horizon=RecedingHorizon(held_nodes=...)",
    "learn_online": "residual=Residual(learn_online=...)",
    "uncertain_indices": "residual=Residual(uncertain=...)",
    "input_indices": "residual=Residual(inputs=...)",
    "sensitivities": "residual=Residual(sensitivities=...)",
    "learned_dynamics": "term=...",
    "uncertainty_radius": "constraints=Constraints(uncertainty_radius=...)",
    "state_margin": "constraints=Constraints(state_margin=...)",
    "state_penalty": "constraints=Constraints(state_penalty=...)",
    "obstacle_margin": "constraints=Constraints(obstacle_margin=...)",
    "solver": "scheme=Converged(solver=...) (RTI(fallback=Converged(...)))",
    "solver_options": "scheme=Converged(solver_options=...)",
    "max_iterations": "scheme=Converged(max_iterations=...)",
    "jit": "scheme=Converged(jit=...)",
    "warm_start_duals": "scheme=Converged(warm_start_duals=...)",
    "qp_solver": "scheme=RTI(qp_solver=...)",
    "levenberg_marquardt": "scheme=RTI(levenberg_marquardt=...)",
}
"""The constructor's former flat keywords (still accepted, with a ``DeprecationWarning``) and
where each now lives."""


def default_learned_dynamics(scheme: str, model: ControlModel | str | None = None) -> str:
    """The ``term`` name an MPC of ``scheme`` uses when given none: ``"exact"`` (the paper's
    OCP, the GP inside the NLP) for ``"converged"``; for the real-time iterations, the
    system's :func:`~gp_agents.mpc.tuning.rti_tuning` (``model``: a model or a system name;
    ``"linearized"`` without one).

    Raises:
        ValueError: the registered name is not one of :data:`LEARNED_TERMS`.
    """
    if scheme == "converged":
        return "exact"
    name = rti_tuning(model).learned_term if model is not None else "linearized"
    if name not in LEARNED_TERMS:
        raise ValueError(f"the system's RTITuning.learned_term {name!r} is not one of "
                         f"{list(LEARNED_TERMS)}")
    return name


class EnvNominalModel:
    """The model source of :meth:`PseudospectralMPC.from_env`: the env's current nominal model
    (a class, not a closure, so that an agent pickles with its env)."""

    def __init__(self, env: gym.Env) -> None:
        self.env = env

    def __call__(self) -> ControlModel:
        return nominal_model(self.env)


class PseudospectralMPC:
    """Gauss pseudospectral MPC on nominal physics plus an optional learned residual.

    The named recipes (:func:`gp_agents.make_mpc`) build it with settings that work together;
    this constructor is for changing one piece. Each group of settings is one object
    (:mod:`gp_agents.mpc.settings`), and a setting that would change nothing in the chosen
    combination raises instead of being ignored.

    Args:
        model: the model the controller plans with: an env's ``nominal_model`` (or, for an
            upper-bound baseline, the true model the benchmark hands in).
        learner: a residual learner (:class:`~gp_agents.learners.IncrementalSSGP`,
            :class:`~gp_agents.learners.SSGP`, :class:`~gp_agents.learners.ExactGP`) or None
            (pure physics). It must be fitted before the first ``act`` (:meth:`pretrain`;
            ``pretrain(None)``: no initial data, learned from the first step).
        horizon: when and over what to plan: a
            :class:`~gp_agents.mpc.schedule.RecedingHorizon` (Algorithm 1; a number is its
            length in seconds) or an :class:`~gp_agents.mpc.schedule.Episodic` (plan once over
            the task, run open loop, no learning). None: the system's receding horizon
            (:class:`gp_envs.PlanningDefaults`).
        scheme: :class:`~gp_agents.mpc.settings.Converged` (every plan solved to convergence)
            or :class:`~gp_agents.mpc.settings.RTI` (one SQP step per period; ``split=True``
            separates preparation and feedback); or ``"converged"``, ``"rti"``,
            ``"rti-split"``.
        term: how the learner enters the NLP (only with a learner): ``"exact"``
            (:class:`GPInNLP`, the paper's OCP), ``"linearized"`` (:class:`LinearizedGP`),
            ``"linearized-pattern"`` (:class:`~gp_agents.mpc.gp_pattern.PatternLinearizedGP`),
            ``"zero-order"`` (:class:`ZeroOrderGP`), or a configured
            :class:`~gp_agents.mpc.learned_term.LearnedTerm` (copied). None: ``"exact"`` when
            converged, the system's tuned term for the RTI
            (:func:`~gp_agents.mpc.tuning.rti_tuning`).
        residual: :class:`~gp_agents.mpc.settings.Residual` (only with a learner): which
            states get a residual, what the learner sees, whether it learns online.
        constraints: :class:`~gp_agents.mpc.ocp.Constraints` (state box margin and penalty,
            obstacle margin, uncertainty radius ``kappa``; 0 reproduces the paper's run).
        **legacy: the former flat keywords (:data:`LEGACY_SETTINGS`), mapped onto these
            objects with a ``DeprecationWarning``.

    Raises:
        TypeError: a learner without what the MPC calls (:data:`LEARNER_METHODS`); a legacy
            keyword together with the object it belongs to; an unknown keyword.
        ValueError: a setting that does not apply to the combination (an RTI or online learning
            with an episodic plan, a learned term or residual settings without a learner, an
            obstacle margin or uncertainty radius on a system without obstacles, ...).
    """

    def __init__(self, model: ControlModel, learner: Any | None = None, *,
                 horizon: float | RecedingHorizon | Episodic | None = None,
                 scheme: str | Converged | RTI = "converged",
                 term: str | LearnedTerm | None = None, residual: Residual | None = None,
                 constraints: Constraints | None = None, **legacy: Any) -> None:
        if not isinstance(model, ControlModel):
            raise TypeError(f"model must be a gp_envs ControlModel, got {type(model).__name__}")
        if legacy:
            horizon, scheme, term, residual, constraints = _from_legacy(
                legacy, horizon, scheme, term, residual, constraints)
        schedule = _schedule(horizon).resolve(model)
        scheme = scheme_settings(scheme)
        residual = Residual() if residual is None else residual
        constraints = Constraints() if constraints is None else constraints
        for value, kind, name in ((residual, Residual, "residual"),
                                  (constraints, Constraints, "constraints")):
            if not isinstance(value, kind):
                raise TypeError(f"{name} must be a {kind.__name__}, got {type(value).__name__}")
        _check_learner(learner)
        _check_combination(model, learner, schedule, scheme, term, residual, constraints)
        if isinstance(scheme, RTI):
            tuning = rti_tuning(model)
            scheme = dataclasses.replace(
                scheme, qp_solver=scheme.qp_solver or tuning.qp_solver,
                levenberg_marquardt=(tuning.levenberg_marquardt if scheme.levenberg_marquardt
                                     is None else scheme.levenberg_marquardt),
                recovery_iterations=(tuning.recovery_iterations
                                     if scheme.recovery_iterations is None
                                     else scheme.recovery_iterations))
        self.schedule: RecedingHorizon | Episodic = schedule
        self.scheme_settings: Converged | RTI = scheme
        self.residual_settings = residual
        self.mesh = self.schedule.mesh(model.dt)  # validates horizon against the held periods
        self.constraints = constraints
        self.model, self.learner = model, learner
        self.learned_dynamics = _term(term, scheme, model)
        self.learn_online = (schedule.learns and learner is not None
                             and hasattr(learner, "update")
                             if residual.learn_online is None else residual.learn_online)
        self.residual = ResidualModel(model, residual.uncertain, residual.inputs,
                                      residual.sensitivities)
        _bind_sensitivity_columns(learner, self.residual)
        self.term: LearnedTerm = (copy.deepcopy(self.learned_dynamics) if learner is not None
                                  else NoLearnedTerm())
        self._attach()
        self.planner: Planner | None = None
        self._model_source: Callable[[], ControlModel] | None = None
        self._buffer: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        # every transition learned (initial data, then online), for the refits of
        # Residual.refit_until and the first fit of a learner with no initial data
        self._learned: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._fitted_on = 0
        self._start_empty = False  # pretrain(None): plan with the model alone until data come
        self._no_term = NoLearnedTerm()  # what an unfitted learner's MPC plans with
        self._no_term.attach(self.residual, None)
        self.n_builds = 0
        self.reset()

    # the former flat settings, read from the settings objects
    @property
    def mode(self) -> str:
        """``"receding"`` or ``"episodic"``."""
        return self.schedule.name

    @property
    def scheme(self) -> str:
        """``"converged"``, ``"rti"`` or ``"rti-split"``."""
        return self.scheme_settings.name

    @property
    def qp_solver(self) -> str | ActiveSetQP | None:
        """The RTI's QP solver (None for a converged scheme)."""
        s = self.scheme_settings
        return s.qp_solver if isinstance(s, RTI) else None

    @property
    def levenberg_marquardt(self) -> float | None:
        """The RTI's Levenberg-Marquardt ``mu`` (None for a converged scheme)."""
        s = self.scheme_settings
        return s.levenberg_marquardt if isinstance(s, RTI) else None

    @property
    def solver_settings(self) -> Converged:
        """The converged solves' settings (the RTI's fallback for an RTI scheme)."""
        s = self.scheme_settings
        return s.fallback if isinstance(s, RTI) else s

    def settings(self) -> dict[str, Any]:
        """The settings this MPC was built with, resolved (scikit-learn's ``get_params``):
        ``horizon``, ``scheme``, ``term``, ``residual``, ``constraints`` as their objects."""
        return {"horizon": self.schedule, "scheme": self.scheme_settings,
                "term": self.learned_dynamics if self.learner is not None else None,
                "residual": self.residual_settings, "constraints": self.constraints}

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
                the env's nominal model (a benchmark's oracle passes
                ``lambda: gp_envs.oracle_model(env)``).
            **settings: keyword settings of the class.
        """
        nominal_model(env)  # raises TypeError, saying how to give the env a model
        source = model_source or EnvNominalModel(env)
        agent = cls(source(), learner, **settings)
        agent._model_source = source
        return agent

    def pretrain(self, data: Transitions | tuple[np.ndarray, np.ndarray, np.ndarray] | None
                 ) -> PseudospectralMPC:
        """Fit the learner on initial transitions (Algorithm 1, line 1); returns ``self``.

        Args:
            data: :class:`~gp_agents.data.Transitions` (from
                :func:`~gp_agents.data.collect_initial_data`), or a tuple ``(X, U, X_next)`` of
                arrays (N, n), (N, m), (N, n) in the model's units; or None: no initial data,
                learn from the first step (the MPC plans with its model alone until the first
                observed transition, on which the learner is then fitted; every later one
                updates it, or refits it as :class:`~gp_agents.mpc.settings.Residual`'s
                ``refit_until`` says).

        Raises:
            ValueError: no learner; no transitions; shapes that do not match the model;
                non-finite values.
            TypeError: ``data`` is neither.
        """
        if self.learner is None:
            raise ValueError("this agent has no learner to pretrain")
        if data is None:
            if not self.learn_online:
                raise ValueError("pretrain(None) learns from the first step: it needs online "
                                 "learning (a receding horizon, a learner with update())")
            if self._model_source is not None:
                self._set_model(self._model_source(), learner_trained=False)
            self._start_empty, self._learned, self._fitted_on = True, [], 0
            self.planner = None
            return self
        X, U, X_next = _transitions(data, self.model)
        if self._model_source is not None:  # learn against the env's current nominal model
            self._set_model(self._model_source(), learner_trained=False)
        self._start_empty = False
        self.learner.fit(*self.residual.targets(X, U, X_next))
        self._learned = [(X.copy(), U.copy(), X_next.copy())]
        self._fitted_on = len(X)
        self.planner = None  # the learner's parameter layout may have changed
        return self

    def reset(self) -> None:
        """Forget the current plan, buffered transitions and diagnostics (at every env reset)."""
        self._plan: Plan | None = None
        self._step = 0
        self._buffer.clear()
        self.diagnostics: list[StepRecord] = []
        self._health = dict.fromkeys(("replans", "rti_steps", "rti_recovered",
                                      "rti_recovery_iterations", "rti_rejected", "failed",
                                      "capped", "fallbacks", "degraded_replans"), 0)
        self._warned = False

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
        """The planner, (re)built if the learned term's parameter layout changed.

        A learner with no data yet (never pretrained, nothing observed) is not in the plan:
        the MPC plans with the model alone until its first transitions are learned (then
        the planner is rebuilt with the learned term)."""
        unfitted = (self._start_empty and self.learner is not None
                    and not self._learner_fitted())
        term = self._no_term if unfitted else self.term
        size = term.param_values().size  # raises RuntimeError for an unfitted learner
        planning = self.planner.planning if self.planner is not None else None
        if (planning is None or planning.term is not term
                or size != planning.n_params - planning.n_nominal):
            previous = self.planner
            settings = self.scheme_settings
            if isinstance(settings, RTI):
                planner: type[Planner] = SplitRTIPlanner if settings.split else RTIPlanner
                extra: dict[str, Any] = {"qp_solver": settings.qp_solver,
                                         "levenberg_marquardt": settings.levenberg_marquardt,
                                         "recovery_iterations": settings.recovery_iterations,
                                         **settings.fallback.planner_settings()}
            else:
                planner, extra = Planner, settings.planner_settings()
            self.planner = planner(PlanningModel(self.model, self.residual, term),
                                   self.mesh, self.constraints, **extra)
            self.n_builds += 1
            if previous is not None and previous.planning.term is self._no_term:
                for count in ("n_solves", "n_failures", "n_fallbacks", "n_retries", "n_capped"):
                    setattr(self.planner, count, getattr(self.planner, count)
                            + getattr(previous, count))
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
            residual_on=self.learner is not None and bool(getattr(self.learner,
                                                                  "residual_on_", True)),
            act_time=time.perf_counter() - start, plan_t=plan.solution.t - offset,
            plan_x=plan.solution.x, **record))
        if record["replanned"]:
            self._count(record)
        self._step += 1
        return u

    def health(self) -> dict[str, int | bool]:
        """How this episode's replans went (since the last :meth:`reset`): ``replans``,
        ``rti_steps`` (RTI steps taken), ``rti_recovered`` (RTI steps whose constraint
        violation was too large and that further SQP iterations within the
        ``recovery_iterations`` budget made acceptable; ``rti_recovery_iterations``: those
        iterations), ``rti_rejected`` (RTI steps replaced by a converged solve, the last
        resort), ``failed`` (replans whose solve failed), ``capped`` (ending at the iteration
        cap), ``fallbacks`` (an older or constant plan kept), ``degraded_replans`` (replans with
        any of the last four) and ``degraded`` (more than :data:`~gp_agents.mpc.diagnostics.
        DEGRADED_FRACTION` of the replans, and at least :data:`~gp_agents.mpc.diagnostics.
        MIN_DEGRADED_REPLANS`; a :class:`~gp_agents.mpc.diagnostics.ControllerDegradedWarning`
        is issued once per episode when that first holds)."""
        counts: dict[str, int | bool] = dict(self._health)
        counts["degraded"] = _degraded(self._health)
        return counts

    def _count(self, record: dict[str, Any]) -> None:
        status = str(record["status"])
        rejected = status.startswith("RTI rejected")
        failed, fallback = not record["success"], bool(record["fallback"])
        capped = status.rsplit(", ", 1)[-1] in CAPPED_STATUSES
        h = self._health
        h["replans"] += 1
        h["rti_steps"] += int(status.startswith("RTI"))
        recovered = status.startswith("RTI recovered")
        h["rti_recovered"] += int(recovered)
        h["rti_recovery_iterations"] += int(record["iterations"]) - 1 if recovered else 0
        h["rti_rejected"] += int(rejected)
        h["failed"] += int(failed)
        h["capped"] += int(capped)
        h["fallbacks"] += int(fallback)
        h["degraded_replans"] += int(rejected or failed or capped or fallback)
        if not self._warned and _degraded(h):
            self._warned = True
            warnings.warn(ControllerDegradedWarning(
                f"PseudospectralMPC ({self.scheme}): {h['degraded_replans']} of {h['replans']} "
                f"replans so far this episode took a fallback path (RTI steps rejected "
                f"{h['rti_rejected']}, failed {h['failed']}, capped {h['capped']}, older plan "
                f"kept {h['fallbacks']}); agent.health() has the counts"), stacklevel=3)

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
        if not self._buffer:
            return
        X, U, Xn = (np.array(a) for a in zip(*self._buffer, strict=True))
        self._buffer.clear()
        self._learned.append((X, U, Xn))
        seen = sum(len(x) for x, _, _ in self._learned)
        refit = (self._fitted_on < self.residual_settings.refit_until
                 and seen >= 2 * self._fitted_on)
        if refit or not self._learner_fitted():
            # the first fit of a learner without initial data, or a refit (Residual.refit_until)
            X, U, Xn = (np.concatenate(a) for a in zip(*self._learned, strict=True))
            self.learner.fit(*self.residual.targets(X, U, Xn))
            self._fitted_on = seen
        else:
            self.learner.update(*self.residual.targets(X, U, Xn))

    @property
    def n_learned(self) -> int:
        """Transitions the learner has been given (initial data and online), 0 without one."""
        return sum(len(x) for x, _, _ in self._learned) + len(self._buffer)

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


def _transitions(data: Any, model: ControlModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``data``'s ``(X, U, X_next)`` checked against ``model`` (see :meth:`PseudospectralMPC.
    pretrain`)."""
    if isinstance(data, Transitions):
        arrays = (data.X, data.U, data.X_next)
    elif isinstance(data, tuple | list) and len(data) == 3:
        arrays = tuple(data)
    else:
        raise TypeError(f"pretrain takes Transitions (gp_agents.collect_initial_data(env, n, "
                        f"seed=...)) or a tuple (X, U, X_next), got {type(data).__name__}")
    n, m = model.n_states, model.n_controls
    out = []
    for name, value, width in zip(("X", "U", "X_next"), arrays, (n, m, n), strict=True):
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise TypeError(f"pretrain: {name} must be an array of numbers") from None
        if arr.ndim != 2 or arr.shape[1] != width:
            raise ValueError(f"pretrain: {name} must have shape (N, {width}) for the "
                             f"{model.name} model, got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"pretrain: {name} has non-finite values")
        out.append(arr)
    if out[0].shape[0] < 1:
        raise ValueError("pretrain needs at least one transition, got none")
    if not out[0].shape[0] == out[1].shape[0] == out[2].shape[0]:
        raise ValueError(f"pretrain: X, U, X_next must have as many rows, got "
                         f"{[a.shape[0] for a in out]}")
    return out[0], out[1], out[2]


def _degraded(h: dict[str, int]) -> bool:
    bad = h["degraded_replans"]
    return bad >= MIN_DEGRADED_REPLANS and bad > DEGRADED_FRACTION * h["replans"]


def _checked(value: Any, shape: tuple[int, ...], name: str) -> np.ndarray:
    """``value`` as a float array of ``shape``, finite, else a ``ValueError``."""
    arr = np.asarray(value, dtype=float)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr}")
    return arr


# ---------------------------------------------------------------------- settings resolution
def _schedule(horizon: float | RecedingHorizon | Episodic | None) -> RecedingHorizon | Episodic:
    if horizon is None:
        return RecedingHorizon()
    if isinstance(horizon, RecedingHorizon | Episodic):
        return horizon
    if isinstance(horizon, bool) or not isinstance(horizon, int | float | np.floating):
        raise TypeError(f"horizon must be seconds, a RecedingHorizon or an Episodic, got "
                        f"{type(horizon).__name__}")
    return RecedingHorizon(float(horizon))


def _take(legacy: dict[str, Any], keys: tuple[str, ...], owner: str, given: bool
          ) -> dict[str, Any]:
    """Pop ``keys`` from ``legacy``; a TypeError if the object ``owner`` was given too."""
    found = {k: legacy.pop(k) for k in keys if k in legacy}
    if found and given:
        raise TypeError(f"PseudospectralMPC: {sorted(found)} and {owner}= both given; set them "
                        f"on the {owner} object ({'; '.join(LEGACY_SETTINGS[k] for k in found)})")
    return found


def _from_legacy(legacy: dict[str, Any], horizon: Any, scheme: Any, term: Any, residual: Any,
                 constraints: Any) -> tuple[Any, Any, Any, Any, Any]:
    """Map the former flat keywords onto the settings objects (:data:`LEGACY_SETTINGS`)."""
    legacy = dict(legacy)
    unknown = sorted(set(legacy) - set(LEGACY_SETTINGS))
    if unknown:
        raise TypeError(f"PseudospectralMPC got unexpected keyword(s) {unknown}; settings are "
                        f"horizon=, scheme=, term=, residual=, constraints= "
                        f"(gp_agents.mpc.settings)")
    warnings.warn("PseudospectralMPC: the flat keyword(s) " + ", ".join(sorted(legacy))
                  + " are deprecated; use " + "; ".join(LEGACY_SETTINGS[k] for k in legacy),
                  DeprecationWarning, stacklevel=4)
    is_object = isinstance(horizon, RecedingHorizon | Episodic)
    h = _take(legacy, ("mode", "n_nodes", "n_intervals", "replan_every", "held_nodes"),
              "horizon", is_object)
    if h:
        mode = h.pop("mode", "receding")
        seconds = None if horizon is None else float(horizon)
        if mode == "receding":
            horizon = RecedingHorizon(seconds, h.get("n_nodes"), h.get("n_intervals"),
                                      h.get("replan_every", 1), h.get("held_nodes", 3))
        elif mode == "episodic":
            wrong = sorted(set(h) - {"n_nodes"})
            if wrong:
                raise ValueError(f"{wrong} do not apply to an episodic plan (mode='episodic')")
            horizon = Episodic(seconds, h.get("n_nodes"))
        else:
            raise ValueError(f"mode must be 'receding' or 'episodic', got {mode!r}")
    solver_keys = ("solver", "solver_options", "max_iterations", "jit", "warm_start_duals")
    s = _take(legacy, (*solver_keys, "qp_solver", "levenberg_marquardt"), "scheme",
              isinstance(scheme, Converged | RTI))
    if s:
        chosen = scheme_settings(scheme)
        converged = {k: s[k] for k in solver_keys if k in s and s[k] is not None}
        if isinstance(chosen, Converged):
            wrong = sorted(set(s) & {"qp_solver", "levenberg_marquardt"})
            if wrong:
                raise ValueError(f"{wrong} configure the real-time iteration's QP; they do not "
                                 f"apply to scheme='converged'")
            scheme = Converged(**converged)
        else:
            converged.setdefault("warm_start_duals", converged.get("solver", "ipopt") == "ipopt")
            scheme = RTI(split=chosen.split, qp_solver=s.get("qp_solver"),
                         levenberg_marquardt=s.get("levenberg_marquardt"),
                         fallback=Converged(**converged))
    t = _take(legacy, ("learned_dynamics",), "term", term is not None)
    if t:
        term = t["learned_dynamics"]
    r = _take(legacy, ("learn_online", "uncertain_indices", "input_indices", "sensitivities"),
              "residual", residual is not None)
    if r:
        residual = Residual(r.get("uncertain_indices"), r.get("input_indices"),
                            bool(r.get("sensitivities", False)), r.get("learn_online"))
    c = _take(legacy, ("uncertainty_radius", "state_margin", "state_penalty", "obstacle_margin"),
              "constraints", constraints is not None)
    if c:
        constraints = Constraints(**{k: (float(v) if k == "uncertainty_radius" else v)
                                     for k, v in c.items()})
    return horizon, scheme, term, residual, constraints


def _check_learner(learner: Any) -> None:
    """A ``TypeError`` naming what a learner lacks (:data:`LEARNER_METHODS`)."""
    if learner is None:
        return
    if isinstance(learner, type):
        raise TypeError(f"learner must be a learner instance, got the class {learner.__name__}; "
                        f"e.g. learner={learner.__name__}(...) or gp_agents.online_ssgp()")
    missing = [m for m in LEARNER_METHODS if not callable(getattr(learner, m, None))]
    if missing:
        raise TypeError(f"learner {type(learner).__name__} lacks {missing}, which the MPC calls: "
                        f"give a residual learner (gp_agents.online_ssgp(), "
                        f"gp_agents.parametric_ssgp(), SSGP, IncrementalSSGP, ExactGP); "
                        f"training data go to agent.pretrain(data), not to learner=")


def _check_combination(model: ControlModel, learner: Any, schedule: RecedingHorizon | Episodic,
                       scheme: Converged | RTI, term: Any, residual: Residual,
                       constraints: Constraints) -> None:
    """A ``ValueError`` for every setting that would change nothing in this combination."""
    if isinstance(schedule, Episodic) and isinstance(scheme, RTI):
        raise ValueError("the real-time iteration refines a plan every period; an episodic plan "
                         "is solved once: use scheme='converged' with Episodic")
    if learner is None:
        if term is not None:
            raise ValueError(f"term={term!r} configures how a learner enters the NLP; this MPC "
                             f"has no learner")
        if residual != Residual():
            raise ValueError(f"residual={residual!r} configures the learned residual; this MPC "
                             f"has no learner")
    elif residual.refit_until and (residual.learn_online is False or not schedule.learns):
        raise ValueError("Residual(refit_until=...) refits the learner on the transitions it "
                         "learns online: it does not apply without online learning")
    if learner is not None and residual.learn_online:
        if not schedule.learns:
            raise ValueError("an episodic plan is run open loop and learns nothing: "
                             "residual=Residual(learn_online=True) does not apply")
        if not callable(getattr(learner, "update", None)):
            raise ValueError(f"learner {type(learner).__name__} has no update(): it cannot "
                             f"learn online (Residual(learn_online=True))")
    default = Constraints()
    if not model.task.obstacles:
        if constraints.obstacle_margin != default.obstacle_margin:
            raise ValueError(f"system {model.name!r} has no obstacles: "
                             f"Constraints(obstacle_margin=...) does not apply")
        if constraints.uncertainty_radius > 0:
            raise ValueError(f"system {model.name!r} has no obstacles: "
                             f"Constraints(uncertainty_radius=...) does not apply")
    if constraints.uncertainty_radius > 0:
        unc = residual.uncertain if residual.uncertain is not None else model.dynamic_indices
        if learner is None or 0 not in unc or 1 not in unc:
            raise ValueError("Constraints(uncertainty_radius=...) widens the obstacle by the "
                             "learner's predictive spread of the position rates: it needs a "
                             "learner with residuals on states 0 and 1")


def _term(term: str | LearnedTerm | None, scheme: Converged | RTI,
          model: ControlModel) -> LearnedTerm:
    if term is None:
        term = default_learned_dynamics(scheme.name, model)
    if isinstance(term, str):
        if term not in LEARNED_TERMS:
            raise ValueError(f"term must be one of {list(LEARNED_TERMS)} or a LearnedTerm, "
                             f"got {term!r}")
        return LEARNED_TERMS[term]()
    if not isinstance(term, LearnedTerm):
        raise TypeError(f"term must be a name or a LearnedTerm, got {type(term).__name__}")
    return term


def _bind_sensitivity_columns(learner: Any, residual: ResidualModel) -> None:
    """Give a learner whose linear features are on ``"sensitivities"``
    (:func:`gp_agents.parametric_ssgp` without columns) this MPC's sensitivity columns, and check
    explicit linear-feature columns against the learner's input width."""
    features = getattr(learner, "linear_features", None)
    if isinstance(features, str):
        if features != "sensitivities":
            raise ValueError(f"learner.linear_features {features!r}: only 'sensitivities' "
                             f"names columns")
        if not residual.sensitivities:
            raise TypeError("this learner's linear features are on the parameter sensitivities "
                            "(parametric_ssgp()): build the MPC with "
                            "residual=Residual(sensitivities=True), as make_mpc(env, 'robust') "
                            "does")
        learner.linear_features = residual.sensitivity_columns
        return
    if features is None or isinstance(features, bool | np.bool_ | np.ndarray):
        return
    width = len(residual.input_names)
    bad = [int(c) for c in features if not -width <= int(c) < width]
    if bad:
        hint = ("" if residual.sensitivities else "; columns of parameter sensitivities need "
                "residual=Residual(sensitivities=True)")
        raise TypeError(f"learner.linear_features names input column(s) {bad}, but this MPC's "
                        f"learner has {width} inputs ({', '.join(residual.input_names)}){hint}; "
                        f"parametric_ssgp() without columns takes the MPC's own")
