"""Pseudospectral model predictive control with an online-learned GP residual.

The paper's Algorithm 1 ("Model Predictive Pseudospectral Control with Online Learning"):

1. initialise the (sparse spectrum) GP with initial training data (:meth:`PseudospectralMPC.
   pretrain`, data from :func:`gp_agents.data.collect_initial_data`);
2. solve the Gauss pseudospectral OCP from the current state (:mod:`gp_agents.mpc.ocp`);
3. roll out the first ``p`` control periods of the plan (``replan_every``);
4. update the GP with the ``p`` new transitions (:meth:`PseudospectralMPC.observe`);
5. warm-start the next solve from the previous plan shifted in time; repeat.

The agent is thin: its settings are resolved once (:class:`~gp_agents.mpc.config.MPCConfig`),
its scheme builds the planner (:mod:`~gp_agents.mpc.planner`, :mod:`~gp_agents.mpc.rti`,
:mod:`~gp_agents.mpc.rti_split`), which owns when learning happens relative to the solve, and
what happened is counted in :mod:`~gp_agents.mpc.diagnostics`' terms. The planning model
(nominal physics plus a learned term) is :mod:`~gp_agents.mpc.planning_model`.
"""

from __future__ import annotations

import copy
import time
import warnings
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from gp_agents.data import Transitions
from gp_agents.mpc.config import MPCConfig
from gp_agents.mpc.diagnostics import (
    ControllerDegradedWarning,
    EpisodeHealth,
    SolveCounts,
    StepRecord,
    StepStatus,
    records_to_arrays,
)
from gp_agents.mpc.inputs import bind_sensitivity_columns, checked, transitions
from gp_agents.mpc.learned_term import LearnedTerm, NoLearnedTerm
from gp_agents.mpc.learning import OnlineData
from gp_agents.mpc.ocp import Constraints
from gp_agents.mpc.planner import Plan, Planner
from gp_agents.mpc.planning_model import PlanningModel
from gp_agents.mpc.schedule import Episodic, RecedingHorizon
from gp_agents.mpc.settings import RTI, SQP, Converged, Residual
from gp_envs.model import ControlModel
from gp_envs.wrapper import nominal_model

__all__ = ["EnvNominalModel", "PseudospectralMPC"]


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
    this constructor is for changing one piece. The settings are one
    :class:`~gp_agents.mpc.config.MPCConfig`, given whole (``config=``) or by its fields as
    keywords, resolved for the model at construction (``agent.config``, frozen); a setting that
    would change nothing in the chosen combination raises instead of being ignored.

    Args:
        model: the model the controller plans with: an env's ``nominal_model`` (or, for an
            upper-bound baseline, the true model the benchmark hands in).
        learner: a residual learner (:class:`~gp_agents.learners.IncrementalSSGP`,
            :class:`~gp_agents.learners.SSGP`, :class:`~gp_agents.learners.ExactGP`) or None
            (pure physics). The agent learns on its own copy (``agent.learner``); the one
            passed in is never changed. It must be fitted before the first ``act``
            (:meth:`pretrain`; ``pretrain(None)``: no initial data, learned from the first
            step).
        config: every setting at once (not together with the keywords below).
        horizon, scheme, term, residual, constraints: the fields of
            :class:`~gp_agents.mpc.config.MPCConfig` (when to plan; ``"converged"``,
            ``"rti"``, ``"rti-split"`` or a :class:`~gp_agents.mpc.settings.Converged` /
            :class:`~gp_agents.mpc.settings.RTI`; how the learner enters the NLP; the
            learned residual; the OCP's constraints).

    Attributes:
        config: the resolved settings (:meth:`~gp_agents.mpc.config.MPCConfig.resolve`).
        model: the model planned with now (a ``from_env`` agent follows the env's).
        learner: the agent's learner (a copy of the one given), or None.
        counts: what the planners did since construction
            (:class:`~gp_agents.mpc.diagnostics.SolveCounts`).
        planner: the current planner (None until the first ``act``; rebuilt when the
            learned term's parameter layout changes).
        diagnostics: this episode's :class:`~gp_agents.mpc.diagnostics.StepRecord` list.

    Raises:
        TypeError: a learner without what the MPC calls; ``config=`` and keywords together.
        ValueError: a setting that does not apply (:meth:`~gp_agents.mpc.config.MPCConfig.
            resolve`).
    """

    def __init__(self, model: ControlModel, learner: Any | None = None, *,
                 config: MPCConfig | None = None,
                 horizon: float | RecedingHorizon | Episodic | None = None,
                 scheme: str | Converged | SQP | RTI | None = None,
                 term: str | LearnedTerm | None = None, residual: Residual | None = None,
                 constraints: Constraints | None = None) -> None:
        if not isinstance(model, ControlModel):
            raise TypeError(f"model must be a gp_envs ControlModel, got {type(model).__name__}")
        fields = {"horizon": horizon, "scheme": scheme, "term": term, "residual": residual,
                  "constraints": constraints}
        if config is None:
            config = MPCConfig(**{k: v for k, v in fields.items() if v is not None})
        elif not isinstance(config, MPCConfig):
            raise TypeError(f"config must be an MPCConfig, got {type(config).__name__}")
        elif any(v is not None for v in fields.values()):
            raise TypeError(f"give the settings as config= or as keywords, not both (got config= "
                            f"and {sorted(k for k, v in fields.items() if v is not None)})")
        self.config: MPCConfig = config.resolve(model, learner)
        self.model, self.learner = model, copy.deepcopy(learner)
        self.counts = SolveCounts()
        self.planner: Planner | None = None
        self._mesh = self.config.schedule.mesh(model.dt)  # validates the horizon's periods
        self._residual = self.config.residual.model(model)
        bind_sensitivity_columns(self.learner, self._residual)
        self._term: LearnedTerm = (copy.deepcopy(self.config.term) if self.learner is not None
                                   and self.config.term is not None else NoLearnedTerm())
        self._attach()
        self._model_source: Callable[[], ControlModel] | None = None
        self._data = OnlineData(self.config.residual.refit_until)
        self._start_empty = False  # pretrain(None): plan with the model alone until data come
        self._no_term = NoLearnedTerm()  # what an unfitted learner's MPC plans with
        self._no_term.attach(self._residual, None)
        self.reset()

    @classmethod
    def from_env(cls, env: gym.Env, learner: Any | None = None, *,
                 model_source: Callable[[], ControlModel] | None = None,
                 **settings: Any) -> PseudospectralMPC:
        """An MPC of ``env``'s nominal model and task (never the truth).

        The agent follows the env's nominal model: when a reset redraws it (the Dubins
        scenario), the new parameter values are used from the next ``act`` on, without a
        rebuild.

        Args:
            env: a ``gp_envs`` environment, or one given a model by :func:`gp_envs.wrap`.
            learner: as for the class. settings: ``config=`` or its fields, as for the class.
            model_source: where the model comes from at each ``act`` instead of the env's
                nominal model (the oracle recipe's: the env's true model).
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
            ValueError: no learner; no transitions; wrong shapes; non-finite values.
            TypeError: ``data`` is neither.
        """
        if self.learner is None:
            raise ValueError("this agent has no learner to pretrain")
        if data is None:
            if not self.config.learns_online:
                raise ValueError("pretrain(None) learns from the first step: it needs online "
                                 "learning (a receding horizon, a learner with update())")
            if self._model_source is not None:
                self._set_model(self._model_source(), learner_trained=False)
            self._start_empty = True
            self._data.start(None)
            self.planner = None
            return self
        X, U, X_next = transitions(data, self.model)
        if self._model_source is not None:  # learn against the env's current nominal model
            self._set_model(self._model_source(), learner_trained=False)
        self._start_empty = False
        self.learner.fit(*self._residual.targets(X, U, X_next))
        self._data.start((X, U, X_next))
        self.planner = None  # the learner's parameter layout may have changed
        return self

    def reset(self) -> None:
        """Forget the current plan, buffered transitions and this episode's diagnostics and
        health (at every env reset); :attr:`counts` keep counting."""
        self._plan: Plan | None = None
        self._step = 0
        self._data.clear_pending()
        self.diagnostics: list[StepRecord] = []
        schedule, periods = self.config.schedule, self.model.task.duration / self.model.dt
        self._health = EpisodeHealth(
            periods / schedule.replan_every if isinstance(schedule, RecedingHorizon) else 1)

    @property
    def plan(self) -> Plan | None:
        """The plan the current actions come from (None before the first ``act``)."""
        return self._plan

    # ------------------------------------------------------------------ acting
    def act(self, obs: np.ndarray) -> np.ndarray:
        """The (m,) float32 action for the (n,) observation, within the control bounds.

        Raises:
            ValueError: wrong shape or non-finite observation.
            RuntimeError: a learner that was never fitted.
        """
        start = time.perf_counter()
        x = checked(obs, (self.model.n_states,), "obs")
        if self._model_source is not None and self._model_source() is not self.model:
            self._set_model(self._model_source())
        record: dict[str, Any] = dict(
            replanned=False, success=True, status=StepStatus.REUSE, solver_status="",
            capped=False, iterations=0, solve_time=0.0, fallback=False, solves=0,
            linearization_error=0.0, preparation_time=0.0)
        if self.config.schedule.due(self._step, self._plan):
            self._plan, solved = self._planner().replan(x, self._plan, self._step, self._learn)
            record.update(replanned=True, **solved)
        plan = self._plan
        assert plan is not None
        lb, ub = self.model.u_lb.astype(np.float32), self.model.u_ub.astype(np.float32)
        u = np.clip(plan.action(self._step, self.model.u_lb, self.model.u_ub).astype(np.float32),
                    lb, ub)
        if record["replanned"]:
            assert self.planner is not None
            record.update(self.planner.after_action(plan, record, self._learn))
        offset = (self._step - plan.step) * self.model.dt
        self.diagnostics.append(StepRecord(
            step=self._step, learner_samples=self._learner_samples(), action=u.copy(),
            residual_on=self.learner is not None and not record.get("nominal_plan", False)
            and bool(getattr(self.learner, "residual_on_", True)),
            act_time=time.perf_counter() - start, plan_t=plan.solution.t - offset,
            plan_x=plan.solution.x, **record))
        if record["replanned"]:
            self._count(record)
        self._step += 1
        return u

    def health(self) -> dict[str, int | bool]:
        """How this episode's replans went (since the last :meth:`reset`): the counts of
        :class:`~gp_agents.mpc.diagnostics.EpisodeHealth` and ``degraded`` (more than
        :data:`~gp_agents.mpc.diagnostics.DEGRADED_FRACTION` of the replans, and at least
        :data:`~gp_agents.mpc.diagnostics.MIN_DEGRADED_REPLANS`, took a fallback path; a
        :class:`~gp_agents.mpc.diagnostics.ControllerDegradedWarning` is issued once per
        episode when that holds over a meaningful share of the task)."""
        counts: dict[str, int | bool] = dict(self._health.counts)
        counts["degraded"] = self._health.degraded
        return counts

    def diagnostics_arrays(self) -> dict[str, np.ndarray]:
        """Per-step diagnostics (:class:`~gp_agents.mpc.diagnostics.StepRecord` fields) as
        arrays of length T: ``replanned, success, status, iterations, solves,
        linearization_error, solve_time, act_time, fallback, learner_samples, action (T, m),
        plan_t (T, N), plan_x (T, N, n)``, ..."""
        return records_to_arrays(self.diagnostics)

    def __getstate__(self) -> dict[str, Any]:
        """Pickle everything but the compiled NLP, which is rebuilt at the next ``act`` (the
        learner, the current plan and the diagnostics travel; so does the env of a
        ``from_env`` agent, whose nominal model it follows)."""
        state = self.__dict__.copy()
        state["planner"] = None
        return state

    # ------------------------------------------------------------------ internals
    def _count(self, record: dict[str, Any]) -> None:
        if self._health.count(record["status"], bool(record["success"]),
                              bool(record["capped"]), bool(record["fallback"]),
                              int(record["iterations"])):
            warnings.warn(ControllerDegradedWarning(
                self._health.message(f"PseudospectralMPC ({self.config.scheme.name})")),
                stacklevel=3)

    def _attach(self) -> None:
        unc = self._residual.uncertain_indices
        variance = (self.learner is not None and self.config.constraints.uncertainty_radius > 0
                    and bool(self.model.task.obstacles) and 0 in unc and 1 in unc)
        self._term.attach(self._residual, self.learner, variance)

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
            self._residual = self.config.residual.model(model)
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
        term = self._no_term if unfitted else self._term
        size = term.param_values().size  # raises RuntimeError for an unfitted learner
        planning = self.planner.planning if self.planner is not None else None
        if (planning is None or planning.term is not term
                or size != planning.n_params - planning.n_nominal):
            self.planner = self.config.scheme.planner(
                PlanningModel(self.model, self._residual, term), self._mesh,
                self.config.constraints, self.counts)
        return self.planner

    def _learn(self) -> Planner:
        """The planners' learning hook (:data:`~gp_agents.mpc.planner.Learn`): learn the
        pending transitions; the planner to go on with."""
        if self.learner is not None:
            self._data.learn(self.learner, self._residual, self._learner_fitted())
        return self._planner()

    def observe(self, obs: np.ndarray, action: np.ndarray, next_obs: np.ndarray) -> None:
        """Record a transition; the learner learns it when the planner says (before the next
        solve, Algorithm 1; in the split RTI's preparation, after the next action).

        Args:
            obs: (n,) state at the start of the period. action: (m,) applied action.
            next_obs: (n,) state one control period later.
        """
        n, m = self.model.n_states, self.model.n_controls
        x, xn = checked(obs, (n,), "obs"), checked(next_obs, (n,), "next_obs")
        u = checked(np.asarray(action, float).reshape(-1), (m,), "action")
        if self.config.learns_online:
            self._data.add(x, np.clip(u, self.model.u_lb, self.model.u_ub), xn)

    def _learner_samples(self) -> int:
        return int(getattr(self.learner, "n_samples_seen_", 0)) if self.learner is not None else 0
