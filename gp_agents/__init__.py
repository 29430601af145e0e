"""Controllers for the ``gp_envs`` environments.

- :class:`Agent` (``reset``, ``act``, ``observe``) and :func:`rollout`, the closed loop every
  controller here runs in.
- :func:`make_mpc`: the MPC of a named recipe (:data:`RECIPES`; ``make_mpc(env)`` is the
  recommended ``"robust"`` one), as ``gym.make`` is for envs.
- :class:`PseudospectralMPC`: Gauss pseudospectral MPC on nominal physics plus a learned GP
  residual (the paper's Algorithm 1), its settings grouped in :class:`RecedingHorizon` /
  :class:`Episodic`, :class:`Converged` / :class:`RTI`, :class:`Residual`, :class:`Constraints`.
- Residual learners: :class:`ExactGP`, :class:`SSGP`, :class:`IncrementalSSGP`.
- :func:`collect_initial_data`: initial data from a system's crude tracking controller (or
  uniform random controls, or your own policy).
- :func:`register_defaults`: a system's planning time scales and data controller, by its
  model's name (:mod:`gp_agents.defaults`).
- :class:`RLAgent` (needs the ``rl`` extra): stable-baselines3 policies with the same
  ``act(obs)`` interface, imported lazily so the rest works without torch.

Layers: ``pseudospectral`` (knows no env, no GP) and ``learners`` (know no MPC) sit below
``mpc``; benchmarks sit above.
"""

from __future__ import annotations

from typing import Any

from gp_agents.agent import Agent, Episode, rollout
from gp_agents.data import Transitions, collect_initial_data
from gp_agents.defaults import PlanningDefaults, SystemDefaults, register_defaults
from gp_agents.learners import SSGP, ExactGP, IncrementalSSGP, online_ssgp, parametric_ssgp
from gp_agents.mpc import (
    RECIPES,
    RTI,
    SQP,
    Constraints,
    ControllerDegradedWarning,
    Converged,
    Episodic,
    GPInNLP,
    LinearizedGP,
    PseudospectralMPC,
    RecedingHorizon,
    Residual,
    make_mpc,
)
from gp_agents.residual import ResidualModel
from gp_envs.systems import load_system_plugins

__all__ = [
    "RECIPES",
    "RTI",
    "SQP",
    "SSGP",
    "Agent",
    "Constraints",
    "ControllerDegradedWarning",
    "Converged",
    "Episode",
    "Episodic",
    "ExactGP",
    "GPInNLP",
    "IncrementalSSGP",
    "LinearizedGP",
    "PlanningDefaults",
    "PseudospectralMPC",
    "RLAgent",
    "RecedingHorizon",
    "Residual",
    "ResidualModel",
    "SystemDefaults",
    "Transitions",
    "collect_initial_data",
    "make_mpc",
    "online_ssgp",
    "parametric_ssgp",
    "register_defaults",
    "rollout",
]


PLUGIN_GROUP = "gp_agents.systems"
"""Entry-point group of installed packages' modules that register controller defaults
(:func:`register_defaults`) for their systems; loaded on ``import gp_agents``."""
load_system_plugins(PLUGIN_GROUP)


def __getattr__(name: str) -> Any:
    if name == "RLAgent":  # lazy: stable-baselines3 and torch are an optional extra
        from gp_agents.rl import RLAgent

        return RLAgent
    raise AttributeError(f"module 'gp_agents' has no attribute {name!r}")
