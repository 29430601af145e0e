"""Pseudospectral MPC with a learned residual (the paper's Algorithm 1), one piece per module.

======================  ==================================================================
``controller``          :class:`PseudospectralMPC`: ``from_env``, ``pretrain``, ``act``,
                        ``observe``, ``reset``, ``diagnostics_arrays``
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
``diagnostics``         :class:`StepRecord`
======================  ==================================================================
"""

from gp_agents.learners.recipes import online_ssgp
from gp_agents.mpc.controller import LEARNED_TERMS, PseudospectralMPC
from gp_agents.mpc.diagnostics import StepRecord
from gp_agents.mpc.gp_in_nlp import MAX_LEARNED_MODEL_SIZE, GPInNLP
from gp_agents.mpc.gp_linearized import COLD_START_LINEARIZATIONS, LinearizedGP
from gp_agents.mpc.gp_pattern import PatternLinearizedGP
from gp_agents.mpc.gp_zero_order import ZeroOrderGP
from gp_agents.mpc.learned_term import LearnedTerm, NoLearnedTerm
from gp_agents.mpc.ocp import Constraints, Mesh, build_ocp
from gp_agents.mpc.planner import CAPPED_STATUSES, Plan, Planner
from gp_agents.mpc.planning_model import PlanningModel
from gp_agents.mpc.schedule import Episodic, RecedingHorizon, planning_defaults

__all__ = [
    "CAPPED_STATUSES",
    "COLD_START_LINEARIZATIONS",
    "LEARNED_TERMS",
    "MAX_LEARNED_MODEL_SIZE",
    "Constraints",
    "Episodic",
    "GPInNLP",
    "LearnedTerm",
    "LinearizedGP",
    "Mesh",
    "NoLearnedTerm",
    "PatternLinearizedGP",
    "Plan",
    "Planner",
    "PlanningModel",
    "PseudospectralMPC",
    "RecedingHorizon",
    "StepRecord",
    "ZeroOrderGP",
    "build_ocp",
    "online_ssgp",
    "planning_defaults",
]
