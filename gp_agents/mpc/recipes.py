"""Named MPC recipes, as ``gym.make`` is for envs: ``make_mpc(env)`` is the controller that works.

==============  ==============================================================================
``robust``      (default) nominal physics plus the learner that held across randomized, changed
                and noisy systems: :func:`~gp_agents.learners.parametric_ssgp` (an explicit
                parametric part on the parameter sensitivities, the SSGP around it, restarted on
                a change, off while worse than the nominal model), linearized per node (the
                learner itself in the NLP on an outside truth: below)
``paper``       the paper's Algorithm 1: :func:`~gp_agents.learners.online_ssgp`, the GP's mean
                inside the NLP; for reproducing the paper's tables
``nominal``     physics only (the nominal model), no learning
``oracle``      plans with the true model (:func:`gp_envs.oracle_model`): the upper bound that
                no controller can see in practice
``blackbox``    no physics prior (the GP-MPC / PILCO family's baseline): the model knows only
                the kinematics (position rates are the velocities,
                :func:`~gp_agents.mpc.blackbox.blackbox_model`) and an online SSGP learns every
                acceleration from the data, linearized per node
``parametric``  the grey-box baseline: nominal physics plus online re-identification of its
                parameters alone, :func:`~gp_agents.learners.parametric_rls` (recursive least
                squares on the parameter sensitivities, no GP), linearized per node
==============  ==============================================================================

The learning recipes' converged scheme plans with the learned term linearized per node about
the previous plan (:class:`~gp_agents.mpc.gp_linearized.LinearizedGP`: several times faster
than the learner itself in the NLP, with outcomes within the latter's intervals on the
package's systems) where the truth is the nominal model's own ODE; where it is not
(:func:`gp_envs.outside_truth`: an env given its model by :func:`gp_envs.wrap`, an outside
simulator such as MuJoCo), with the learner itself in the NLP (``term="exact"``). There a
residual the model family cannot represent (friction's kink) can bend sharply along the plan,
one expansion about the previous plan is then far from the learner at the new plan's nodes,
and the plan follows neither model. ``term=`` overrides it.

Without ``scheme=``, a recipe plans with its own scheme on the env's system
(:data:`RECIPE_SCHEMES`): the robust recipe with the SQP (:class:`~gp_agents.mpc.settings.SQP`,
the real-time iteration's QP iterated to convergence, IPOPT as its fallback) on the quadrotor
and the Dubins vehicle, where it gave IPOPT's outcomes in less act time; every other recipe
and system with the converged IPOPT solve.

Each recipe resolves its own coupled settings (the robust learner's sensitivity columns come
from the agent's own residual), so ``make_mpc(env, recipe, scheme=...)`` is all it takes; any
constructor setting of :class:`~gp_agents.mpc.controller.PseudospectralMPC` can be overridden by
keyword. The learning recipes return an unfitted agent: ``agent.pretrain(data)`` with
:func:`~gp_agents.data.collect_initial_data`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import gymnasium as gym

import gp_envs
from gp_agents.learners.recipes import online_ssgp, parametric_rls, parametric_ssgp
from gp_agents.mpc.blackbox import BlackBoxModel
from gp_agents.mpc.controller import PseudospectralMPC
from gp_agents.mpc.settings import RTI, SQP, Converged, Residual, scheme_settings
from gp_agents.mpc.tuning import RECOVERY_ITERATIONS
from gp_envs.model import ControlModel

__all__ = ["DEFAULT_RECIPE", "RECIPES", "RECIPE_SCHEMES", "OracleModel", "make_mpc",
           "recipe_settings"]

RECIPES: dict[str, str] = {
    "robust": "nominal physics + parametric SSGP on the parameter sensitivities, linearized per "
              "node (in the NLP itself on an outside truth), solved by SQP on the quadrotor and "
              "the Dubins vehicle, by IPOPT elsewhere; holds on randomized, changed and noisy "
              "systems (recommended)",
    "paper": "the paper's Algorithm 1: nominal physics + online SSGP, its mean inside the NLP",
    "nominal": "nominal physics only, no learning",
    "oracle": "the true model (gp_envs.oracle_model): an upper bound, not a controller you can "
              "deploy",
    "blackbox": "no physics prior (GP-MPC's baseline): kinematics only, an online SSGP learns "
                "every acceleration from the data, linearized per node (in the NLP itself on an "
                "outside truth)",
    "parametric": "grey-box baseline: nominal physics + recursive least squares on the parameter "
                  "sensitivities (its parameters re-identified online, no GP), linearized per "
                  "node (in the NLP itself on an outside truth)",
}
"""Every recipe name with its one-line description."""

BLACKBOX_LINEAR_FEATURES = True
"""The black-box learner's linear features (on every input: a force enters an acceleration
linearly)."""
BLACKBOX_REFIT_UNTIL = 100
"""The black-box recipe's ``Residual(refit_until=...)``: with no prior, the hyperparameters and
input scales fitted on a few samples are refitted as the data double, up to 100 samples."""

RECIPE_RTI: Mapping[str, Mapping[str, Mapping[str, Any]]] = {
    "robust": {"dubins": {"levenberg_marquardt": 1.0,
                          "recovery_iterations": RECOVERY_ITERATIONS}},
    "parametric": {"dubins": {"levenberg_marquardt": 1.0,
                              "recovery_iterations": RECOVERY_ITERATIONS}},
}
"""Real-time-iteration settings a recipe sets on a system (recipe -> system name -> fields of
:class:`~gp_agents.mpc.settings.RTI`) where the system's tuning
(:mod:`gp_agents.mpc.tuning`) does not serve it, used where the scheme leaves them unset. The
robust recipe on the Dubins vehicle: a model close to the truth moves its plan little from one
period to the next and takes a heavier damping (``mu`` = 1, which removes its rejected steps,
the controls flipping from bound to bound in the first seconds) and the recovery, which the
other recipes, whose plans must be corrected more at every period, do not. The parametric
recipe, the robust recipe's data and schemes with its parametric part alone (the Dubins rates
are the sensitivities times the parameter errors exactly), takes the same."""

RECIPE_SCHEMES: Mapping[str, Mapping[str, str]] = {
    "robust": {"quadrotor": "sqp", "dubins": "sqp"},
}
"""The scheme ``make_mpc(env, recipe)`` plans with when no ``scheme`` is given, by recipe and
system name, where the truth is the system's own ODE; ``"converged"`` (IPOPT) everywhere else.
The SQP (:class:`~gp_agents.mpc.settings.SQP`) stands in for IPOPT only where its outcomes
matched IPOPT's on the recommended and robustness trials (success equal, mean cost within 1%),
where it is the faster of the two. The cart pole keeps IPOPT: the SQP converges to the KKT point
of the learner itself in the NLP (its term re-expanded at every iterate), IPOPT to that of the
term's expansion, and on the swing-up, whose plans have several local optima, the two reach
different ones: success and mean cost differed both ways from cell to cell. Systems without
a measurement, and outside truths, keep IPOPT too."""

DEFAULT_RECIPE = "robust"
"""The recipe of ``make_mpc(env)``."""


class OracleModel:
    """The oracle recipe's model source: the env's true model (:func:`gp_envs.oracle_model`),
    read at every ``act`` (a class, not a closure, so that the agent pickles)."""

    def __init__(self, env: gym.Env) -> None:
        self.env = env

    def __call__(self) -> ControlModel:
        return gp_envs.oracle_model(self.env)


def recipe_settings(recipe: str, scheme: str | Converged | SQP | RTI | None = None,
                    system: str | None = None, *, outside: bool = False) -> dict[str, Any]:
    """The constructor settings of ``recipe`` with ``scheme`` (None: the recipe's scheme on
    the system, :data:`RECIPE_SCHEMES`, else converged) on the system called ``system`` (its
    :data:`RECIPE_RTI` entries; None: none), learner included (a
    fresh, unfitted one; None for the recipes that learn nothing); the oracle's and the
    black box's model sources are added by :func:`make_mpc`. ``outside``: the truth is not the
    nominal model's ODE (:func:`gp_envs.outside_truth`), where the converged scheme's learned
    term is the learner itself (module doc).

    Raises:
        ValueError: an unknown recipe (the message lists them) or scheme.
    """
    if recipe not in RECIPES:
        raise ValueError(f"unknown MPC recipe {recipe!r}; recipes: {', '.join(RECIPES)}")
    if scheme is None:
        scheme = ("converged" if outside
                  else RECIPE_SCHEMES.get(recipe, {}).get(system or "", "converged"))
    settings = scheme_settings(scheme)  # checks the name
    own = RECIPE_RTI.get(recipe, {}).get(system or "", {})
    if isinstance(settings, RTI) and own:
        settings = dataclasses.replace(settings, **{
            k: v for k, v in own.items() if getattr(settings, k) is None})
    out: dict[str, Any] = {"scheme": settings, "learner": None}
    if recipe == "paper":
        out["learner"] = online_ssgp()
        return out
    if recipe == "robust":
        out.update(learner=parametric_ssgp(), residual=Residual(sensitivities=True))
    elif recipe == "parametric":  # the robust recipe's data and schemes, the learner alone
        out.update(learner=parametric_rls(), residual=Residual(sensitivities=True))
    elif recipe == "blackbox":
        out.update(learner=online_ssgp(linear_features=BLACKBOX_LINEAR_FEATURES),
                   residual=Residual(refit_until=BLACKBOX_REFIT_UNTIL))
    else:
        return out
    # the RTI takes the system's tuned term; the SQP re-expands its term at every iterate
    if isinstance(settings, SQP) or (isinstance(settings, Converged) and not outside):
        out["term"] = "linearized"
    elif isinstance(settings, Converged):
        out["term"] = "exact"
    return out


def make_mpc(env: gym.Env, recipe: str = DEFAULT_RECIPE, *,
             scheme: str | Converged | SQP | RTI | None = None,
             **overrides: Any) -> PseudospectralMPC:
    """The MPC of recipe ``recipe`` (:data:`RECIPES`) for ``env``'s nominal model and task.

    Args:
        env: a ``gp_envs`` environment (``gym.make``), or any Gymnasium env given a nominal
            model by :func:`gp_envs.wrap` (found through the wrapper chain).
        recipe: ``"robust"`` (default), ``"paper"``, ``"nominal"``, ``"oracle"``,
            ``"blackbox"`` or ``"parametric"``.
        scheme: ``"converged"`` (IPOPT), ``"sqp"``, ``"rti"``, ``"rti-split"`` or a
            :class:`~gp_agents.mpc.settings.Converged` / :class:`~gp_agents.mpc.settings.SQP`
            / :class:`~gp_agents.mpc.settings.RTI`; None (default): the recipe's scheme on
            the env's system (:data:`RECIPE_SCHEMES`: the SQP for the robust recipe on the
            quadrotor and the Dubins vehicle), else converged.
        **overrides: constructor settings of
            :class:`~gp_agents.mpc.controller.PseudospectralMPC` that replace the recipe's
            (``learner=``, ``horizon=``, ``term=``, ``residual=``, ``constraints=``).

    Returns:
        The agent; unfitted for the learning recipes (call ``agent.pretrain(data)``).

    Raises:
        ValueError: an unknown recipe; a learner given to a recipe that learns nothing.
        TypeError: an env without a nominal model.

    Example::

        env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online")
        agent = make_mpc(env).pretrain(collect_initial_data(env, 200, seed=0))
    """
    model = gp_envs.nominal_model(env)  # raises TypeError, saying how to give the env a model
    settings = recipe_settings(recipe, scheme, model.name, outside=gp_envs.outside_truth(env))
    if "learner" in overrides and settings["learner"] is None and overrides["learner"] is not None:
        raise ValueError(f"recipe {recipe!r} learns nothing: it takes no learner (the learning "
                         f"recipes: 'robust', 'paper', 'blackbox', 'parametric')")
    if "config" in overrides:
        raise TypeError("make_mpc takes the settings it overrides as keywords (horizon=, "
                        "scheme=, term=, residual=, constraints=); for a whole MPCConfig, "
                        "build PseudospectralMPC.from_env(env, learner, config=...)")
    settings.update(overrides)
    learner = settings.pop("learner")
    source = (OracleModel(env) if recipe == "oracle" else BlackBoxModel(env)
              if recipe == "blackbox" else None)
    return PseudospectralMPC.from_env(env, learner, model_source=source, **settings)
