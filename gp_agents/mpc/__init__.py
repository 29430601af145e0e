"""Pseudospectral MPC with a learned residual (the paper's Algorithm 1), one piece per module.

======================  ==================================================================
``recipes``             :func:`make_mpc` and :data:`RECIPES`: the named recipes
``controller``          :class:`PseudospectralMPC`: ``from_env``, ``pretrain``, ``act``,
                        ``observe``, ``reset``, ``health``, ``diagnostics_arrays``
``config``              :class:`MPCConfig`: every setting, resolved once for a model
``settings``            the settings objects: :class:`Converged`, :class:`RTI`,
                        :class:`Residual` (and ``schedule``'s, ``ocp``'s :class:`Constraints`)
``inputs``              checks of observations, actions and initial data
``tuning``              per-system solver tuning: :class:`RTITuning`, :func:`rti_tuning`
``schedule``            when to plan: :class:`RecedingHorizon`, :class:`Episodic`
``planner``             warm start, re-linearization, retry, fallback; :class:`Plan`'s action
``ocp``                 the OCP: :class:`Mesh` (held control periods), cost, state box,
                        obstacles
``planning_model``      ``xdot = f_nominal + S r``: :class:`PlanningModel`
``learned_term``        the strategy interface, :class:`NoLearnedTerm`
``gp_in_nlp``           :class:`GPInNLP`: the GP's mean inside the NLP (the paper's OCP)
``gp_linearized``       :class:`LinearizedGP`: the GP linearized per node (real-time iteration)
``gp_pattern``          :class:`PatternLinearizedGP`: linearized on the nominal Jacobian pattern
``gp_zero_order``       :class:`ZeroOrderGP`: the GP's value frozen per node, adjoint-corrected
``diagnostics``         :class:`StepRecord`, :class:`StepStatus`, :class:`SolveCounts`
======================  ==================================================================
"""

from gp_agents.learners.recipes import online_ssgp
from gp_agents.mpc.config import LEARNED_TERMS, MPCConfig
from gp_agents.mpc.controller import PseudospectralMPC
from gp_agents.mpc.diagnostics import (
    ControllerDegradedWarning,
    SolveCounts,
    StepRecord,
    StepStatus,
)
from gp_agents.mpc.gp_in_nlp import MAX_LEARNED_MODEL_SIZE, GPInNLP
from gp_agents.mpc.gp_linearized import COLD_START_LINEARIZATIONS, LinearizedGP
from gp_agents.mpc.gp_pattern import PatternLinearizedGP
from gp_agents.mpc.gp_zero_order import ZeroOrderGP
from gp_agents.mpc.learned_term import LearnedTerm, NoLearnedTerm
from gp_agents.mpc.ocp import Constraints, Mesh, build_ocp
from gp_agents.mpc.planner import CAPPED_STATUSES, Plan, Planner
from gp_agents.mpc.planning_model import PlanningModel
from gp_agents.mpc.recipes import DEFAULT_RECIPE, RECIPES, OracleModel, make_mpc
from gp_agents.mpc.schedule import Episodic, RecedingHorizon
from gp_agents.mpc.settings import RTI, SQP, Converged, Residual
from gp_agents.mpc.tuning import RTITuning, register_rti_tuning, rti_tuning

__all__ = [
    "CAPPED_STATUSES",
    "COLD_START_LINEARIZATIONS",
    "DEFAULT_RECIPE",
    "LEARNED_TERMS",
    "MAX_LEARNED_MODEL_SIZE",
    "RECIPES",
    "RTI",
    "SQP",
    "Constraints",
    "ControllerDegradedWarning",
    "Converged",
    "Episodic",
    "GPInNLP",
    "LearnedTerm",
    "LinearizedGP",
    "MPCConfig",
    "Mesh",
    "NoLearnedTerm",
    "OracleModel",
    "PatternLinearizedGP",
    "Plan",
    "Planner",
    "PlanningModel",
    "PseudospectralMPC",
    "RTITuning",
    "RecedingHorizon",
    "Residual",
    "SolveCounts",
    "StepRecord",
    "StepStatus",
    "ZeroOrderGP",
    "build_ocp",
    "make_mpc",
    "online_ssgp",
    "register_rti_tuning",
    "rti_tuning",
]
