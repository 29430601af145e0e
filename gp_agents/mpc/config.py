"""The MPC's configuration, worked out once: :class:`MPCConfig` and its :meth:`~MPCConfig.resolve`.

A :class:`~gp_agents.mpc.controller.PseudospectralMPC` is configured by five groups of settings
(as do-mpc's settings and acados' solver options are grouped), each on the object it
configures:

==============================  ===========================================================
``horizon``                     :class:`~gp_agents.mpc.schedule.RecedingHorizon` (Algorithm 1)
                                or :class:`~gp_agents.mpc.schedule.Episodic` (plan once), or
                                seconds (a receding horizon of that length)
``scheme``                      :class:`~gp_agents.mpc.settings.Converged` (every plan solved to
                                convergence) or :class:`~gp_agents.mpc.settings.RTI` (one SQP
                                step per period); or ``"converged"``, ``"rti"``, ``"rti-split"``
``term``                        how the learner enters the NLP: a name of :data:`LEARNED_TERMS`
                                or a :class:`~gp_agents.mpc.learned_term.LearnedTerm`
``residual``                    :class:`~gp_agents.mpc.settings.Residual`: which states get a
                                learned residual, what the learner sees, whether it learns
``constraints``                 :class:`~gp_agents.mpc.ocp.Constraints`: state box margin,
                                obstacle margin, uncertainty radius
==============================  ===========================================================

:meth:`MPCConfig.resolve` is the one place where defaults are filled (the system's planning time
scales from :mod:`gp_agents.defaults`, its real-time-iteration tuning from
:mod:`gp_agents.mpc.tuning`, the default learned term) and where every combination is checked:
a setting that would change nothing in the chosen combination raises instead of being ignored.
The resolved configuration is frozen; the agent keeps it as ``agent.config``.
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gp_agents.mpc.gp_in_nlp import GPInNLP
from gp_agents.mpc.gp_linearized import LinearizedGP
from gp_agents.mpc.gp_pattern import PatternLinearizedGP
from gp_agents.mpc.gp_zero_order import ZeroOrderGP
from gp_agents.mpc.learned_term import LearnedTerm
from gp_agents.mpc.ocp import Constraints
from gp_agents.mpc.schedule import Episodic, RecedingHorizon
from gp_agents.mpc.settings import RTI, SQP, Converged, Residual, scheme_settings
from gp_agents.mpc.tuning import rti_tuning
from gp_envs.model import ControlModel

__all__ = ["LEARNED_TERMS", "LEARNER_METHODS", "MPCConfig", "check_learner", "default_term"]

LEARNED_TERMS: dict[str, type[LearnedTerm]] = {"exact": GPInNLP, "linearized": LinearizedGP,
                                               "linearized-pattern": PatternLinearizedGP,
                                               "zero-order": ZeroOrderGP}
"""``term`` names: the GP inside the NLP (the paper's OCP), linearized per node, linearized on
the nominal model's Jacobian pattern (the rest adjoint-corrected in the RTI), or its value frozen
per node (with the RTI's adjoint correction)."""

LEARNER_METHODS = ("fit", "predict", "predict_gradient", "casadi_mean", "casadi_param_size",
                   "casadi_param_values")
"""What the MPC calls on a learner (:class:`~gp_agents.learners.base.BaseGPLearner` has them)."""


@dataclass(frozen=True, kw_only=True)
class MPCConfig:
    """Every setting of a :class:`~gp_agents.mpc.controller.PseudospectralMPC` (module doc).

    Attributes:
        horizon: when and over what to plan; a number is a receding horizon's length (s).
            None: the system's receding horizon (:class:`gp_agents.PlanningDefaults`).
        scheme: :class:`~gp_agents.mpc.settings.Converged` or
            :class:`~gp_agents.mpc.settings.RTI`, or one of their names.
        term: how the learner enters the NLP (only with a learner). None: ``"exact"`` (the
            paper's OCP) when converged, the system's tuned term for the RTI
            (:func:`~gp_agents.mpc.tuning.rti_tuning`).
        residual: the learned residual's settings (only with a learner).
        constraints: the OCP's constraint settings.
    """

    horizon: float | RecedingHorizon | Episodic | None = None
    scheme: str | Converged | SQP | RTI = "converged"
    term: str | LearnedTerm | None = None
    residual: Residual = field(default_factory=Residual)
    constraints: Constraints = field(default_factory=Constraints)
    resolved: bool = field(default=False, compare=False)
    """Whether :meth:`resolve` made this configuration (every field concrete)."""

    def __post_init__(self) -> None:
        horizon = self.horizon
        if horizon is not None and not isinstance(horizon, RecedingHorizon | Episodic):
            if isinstance(horizon, bool) or not isinstance(horizon, int | float | np.floating):
                raise TypeError(f"horizon must be seconds, a RecedingHorizon or an Episodic, "
                                f"got {type(horizon).__name__}")
            object.__setattr__(self, "horizon", RecedingHorizon(float(horizon)))
        object.__setattr__(self, "scheme", scheme_settings(self.scheme))
        for value, kind, name in ((self.residual, Residual, "residual"),
                                  (self.constraints, Constraints, "constraints")):
            if not isinstance(value, kind):
                raise TypeError(f"{name} must be a {kind.__name__}, got {type(value).__name__}")
        term = self.term
        if isinstance(term, str) and term not in LEARNED_TERMS:
            raise ValueError(f"term must be one of {list(LEARNED_TERMS)} or a LearnedTerm, "
                             f"got {term!r}")
        if term is not None and not isinstance(term, str | LearnedTerm):
            raise TypeError(f"term must be a name or a LearnedTerm, got {type(term).__name__}")

    @property
    def schedule(self) -> RecedingHorizon | Episodic:
        """The horizon as its object (a receding horizon when none was given)."""
        return self.horizon if isinstance(self.horizon, RecedingHorizon | Episodic) else (
            RecedingHorizon())

    @property
    def learns_online(self) -> bool:
        """Whether observed transitions update the learner (a resolved configuration)."""
        return bool(self.residual.learn_online)

    def resolve(self, model: ControlModel, learner: Any | None = None) -> MPCConfig:
        """This configuration for ``model`` and ``learner`` with every default filled and every
        combination checked; frozen, ``resolved=True``. Resolving a resolved configuration
        again (for the same model) returns an equal one.

        Raises:
            TypeError: a learner without what the MPC calls (:data:`LEARNER_METHODS`).
            ValueError: a setting that does not apply to the combination (an RTI or online
                learning with an episodic plan, a learned term or residual settings without a
                learner, obstacle settings on a system without obstacles, a state penalty
                that has no margin to act on, ...).
        """
        check_learner(learner)
        schedule = self.schedule.resolve(model)
        scheme = self.scheme
        assert isinstance(scheme, Converged | SQP | RTI)
        residual = self.residual
        _check_combination(model, learner, schedule, scheme, self.term, residual,
                           self.constraints)
        tuning = rti_tuning(model) if isinstance(scheme, RTI | SQP) else None
        if isinstance(scheme, SQP):
            assert tuning is not None
            scheme = dataclasses.replace(
                scheme, qp_solver=scheme.qp_solver or tuning.qp_solver,
                levenberg_marquardt=(0.0 if scheme.levenberg_marquardt is None
                                     else scheme.levenberg_marquardt))
        if isinstance(scheme, RTI):
            assert tuning is not None
            scheme = dataclasses.replace(
                scheme, qp_solver=scheme.qp_solver or tuning.qp_solver,
                levenberg_marquardt=(tuning.levenberg_marquardt if scheme.levenberg_marquardt
                                     is None else scheme.levenberg_marquardt),
                recovery_iterations=(tuning.recovery_iterations
                                     if scheme.recovery_iterations is None
                                     else scheme.recovery_iterations))
        term: LearnedTerm | None = None
        if learner is not None:
            name = (self.term if self.term is not None else "exact" if tuning is None
                    else _tuned_term(tuning.learned_term))
            term = (LEARNED_TERMS[name]() if isinstance(name, str) else copy.deepcopy(name))
            learns = (schedule.learns and callable(getattr(learner, "update", None))
                      if residual.learn_online is None else residual.learn_online)
            residual = dataclasses.replace(residual, learn_online=bool(learns))
        return MPCConfig(horizon=schedule, scheme=scheme, term=term, residual=residual,
                         constraints=self.constraints, resolved=True)


def default_term(scheme: str, model: ControlModel | str | None = None) -> str:
    """The ``term`` name an MPC of ``scheme`` uses when given none: ``"exact"`` (the paper's
    OCP, the GP inside the NLP) for ``"converged"``; for the real-time iterations, the
    system's :func:`~gp_agents.mpc.tuning.rti_tuning` (``model``: a model or a system name;
    ``"linearized"`` without one).

    Raises:
        ValueError: the registered name is not one of :data:`LEARNED_TERMS`.
    """
    if scheme == "converged":
        return "exact"
    return _tuned_term(rti_tuning(model).learned_term if model is not None else "linearized")


def _tuned_term(name: str) -> str:
    if name not in LEARNED_TERMS:
        raise ValueError(f"the system's RTITuning.learned_term {name!r} is not one of "
                         f"{list(LEARNED_TERMS)}")
    return name


def check_learner(learner: Any) -> None:
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
                       scheme: Converged | SQP | RTI, term: Any, residual: Residual,
                       constraints: Constraints) -> None:
    """A ``ValueError`` for every setting that would change nothing in this combination."""
    if isinstance(schedule, Episodic) and isinstance(scheme, RTI | SQP):
        raise ValueError(f"scheme {scheme.name!r} iterates from the previous period's plan; an "
                         f"episodic plan is solved once: use scheme='converged' with Episodic")
    if learner is None:
        if term is not None:
            raise ValueError(f"term={term!r} configures how a learner enters the NLP; this MPC "
                             f"has no learner")
        if residual != Residual():
            raise ValueError(f"residual={residual!r} configures the learned residual; this MPC "
                             f"has no learner")
    if isinstance(scheme, Converged) and scheme.nominal_above is not None and (
            learner is None or not (isinstance(term, LinearizedGP) or (
                isinstance(term, str) and issubclass(LEARNED_TERMS.get(term, LearnedTerm),
                                                     LinearizedGP)))):
        raise ValueError("Converged(nominal_above=...) falls back from a linearized learned "
                         "term's plan to the nominal model's: it needs a learner and "
                         "term='linearized' (or another LinearizedGP; make_mpc's learning "
                         "recipes plan with term='exact' on an outside truth: pass "
                         "term='linearized' with it)")
    if learner is not None and residual.refit_until and (
            residual.learn_online is False or not schedule.learns):
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
        if constraints.state_margin == 0 and constraints.state_penalty != default.state_penalty:
            raise ValueError(f"system {model.name!r} has no obstacles and state_margin=0 keeps "
                             f"no soft band inside the state box: Constraints(state_penalty=...) "
                             f"has nothing to act on (give a state_margin > 0)")
    if constraints.uncertainty_radius > 0:
        unc = residual.uncertain if residual.uncertain is not None else model.dynamic_indices
        if learner is None or 0 not in unc or 1 not in unc:
            raise ValueError("Constraints(uncertainty_radius=...) widens the obstacle by the "
                             "learner's predictive spread of the position rates: it needs a "
                             "learner with residuals on states 0 and 1")
