"""The study variants of the controller registry: the offline GP, the episodic plans, the speed
and residual variants of the paper's recipe, the RTI's other learned terms and the warm-dual
converged references, each under its own name with its own settings of
:class:`gp_agents.PseudospectralMPC` (not recipes; earlier studies decided on them).

:func:`benchmarks.controllers.load_study_variants` imports this module the first time the
registry is asked for a name it does not hold yet or for its whole list (a preset or a
``--controllers`` name of a study variant, ``--list-controllers``); the module registers each
variant through :func:`benchmarks.controllers.register_controller`. The engine never imports it
when it is imported. Their names key committed results (the ``speed-options``, ``linearized``,
``rti``, ``robustness`` presets and the studies' reports), so they stay.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from benchmarks.controllers import CONTROLLERS, ControllerRecipe, register_controller
from gp_agents.mpc import Converged, Episodic, GPInNLP, Residual

__all__ = ["RTI_VARIANTS", "SPEED_VARIANTS", "STUDY_VARIANTS"]


def _variant(name: str, label: str, description: str, learner: str | None = "ssgp",
             oracle: bool = False, mode: str = "receding",
             **settings: Any) -> tuple[str, ControllerRecipe]:
    """A study variant: its own settings of :class:`gp_agents.PseudospectralMPC`."""
    return name, ControllerRecipe(name, label, "mpc", description, learner=learner,
                                  oracle=oracle, mode=mode,
                                  learn_online=learner is not None and mode == "receding",
                                  settings=tuple(settings.items()))


def _episodic(base: str, label: str, desc: str, learner: str | None,
              oracle: bool = False) -> tuple[str, ControllerRecipe]:
    return _variant(f"{base}-episodic", f"{label} episodic",
                    f"{desc}; planned once over the episode, open loop", learner, oracle,
                    mode="episodic", horizon=Episodic())


_SENS = Residual(sensitivities=True)
STUDY_VARIANTS: dict[str, ControllerRecipe] = dict([
    _variant("gp-mpc", "offline GP MPC", "nominal + exact GP fitted once on the initial data, "
             "no online learning; receding-horizon MPC", learner="exact"),
    _episodic("nominal", "nominal", "nominal physics", None),
    _episodic("oracle", "oracle", "true model (upper bound)", None, oracle=True),
    _episodic("gp", "offline GP", "nominal + exact GP fitted once on the initial data",
              "exact"),
    _episodic("ssgp", "SSGP", "nominal + incremental SSGP (r=50, lambda=0.995)", "ssgp"),
    # speed variants of the paper's recipe (presets speed-options, linearized)
    _variant("ssgp-mpc-nominal-hessian", "SSGP MPC, nominal Hessian",
             "ssgp-mpc with the GP's second derivatives dropped from the Lagrangian Hessian "
             "(term=GPInNLP(hessian='nominal'))", term=GPInNLP(hessian="nominal")),
    _variant("ssgp-mpc-model-inputs", "SSGP MPC, model inputs",
             "ssgp-mpc whose learner sees only the states the nominal model's accelerations "
             "depend on (Residual(inputs='model'))", residual=Residual(inputs="model")),
    _variant("ssgp-mpc-linearized", "SSGP MPC, linearized",
             "ssgp-mpc planning with the GP residual linearized per node about the warm start "
             "(term='linearized')", term="linearized"),
    _variant("ssgp-mpc-linearized-model-inputs", "SSGP MPC, linearized, model inputs",
             "ssgp-mpc-linearized whose learner sees only the states the nominal model's "
             "accelerations depend on (Residual(inputs='model'))", term="linearized",
             residual=Residual(inputs="model")),
    # residual variants on the way to the robust recipe (preset robustness)
    _variant("ssgp-mpc-sensitivities", "SSGP MPC, sensitivities",
             "ssgp-mpc whose learner also sees the nominal model's parameter sensitivities "
             "d f_p/d p (Residual(sensitivities=True)) and has linear features "
             "(online_ssgp(linear_features=True))", learner="ssgp-linear", residual=_SENS),
    _variant("ssgp-mpc-linearized-sensitivities", "SSGP MPC, linearized, sensitivities",
             "ssgp-mpc-sensitivities planning with the GP residual linearized per node",
             learner="ssgp-linear", residual=_SENS, term="linearized"),
    _variant("ssgp-mpc-adaptive", "SSGP MPC, adaptive",
             "ssgp-mpc-sensitivities whose learner also restarts from the new regime's samples "
             "when its one-step prediction errors show that the system changed "
             "(ChangeDetector)", learner="ssgp-adaptive", residual=_SENS),
    _variant("ssgp-mpc-linearized-adaptive", "SSGP MPC, linearized, adaptive",
             "ssgp-mpc-adaptive planning with the GP residual linearized per node",
             learner="ssgp-adaptive", residual=_SENS, term="linearized"),
    _variant("ssgp-mpc-linearized-guarded", "SSGP MPC, linearized, guarded",
             "ssgp-mpc-linearized-adaptive whose residual is switched off while it predicts the "
             "newest samples worse than the nominal model (NominalFallback)",
             learner="ssgp-guarded", residual=_SENS, term="linearized"),
    _variant("ssgp-mpc-linearized-saturated", "SSGP MPC, linearized, saturated",
             "ssgp-mpc-linearized-guarded whose learner saturates its standardized inputs at "
             "INPUT_SATURATION standard deviations", learner="ssgp-saturated", residual=_SENS,
             term="linearized"),
    # the plan-level nominal fallback and the learned term on outside truths (study plan_guard)
    _variant("robust-mpc-guarded", "robust MPC, nominal guard",
             "robust-mpc@converged planning beside the nominal model at every replan and acting on "
             "the "
             "nominal plan where the learned plan's linearization error exceeds its tolerance "
             "(Converged(nominal_above=1))", learner="ssgp-parametric", residual=_SENS,
             term="linearized", scheme=Converged(nominal_above=1.0)),
    _variant("robust-mpc-linearized", "robust MPC, linearized term",
             "robust-mpc@converged with the learned residual linearized per node about the "
             "previous plan on every env (term='linearized'), as it plans on the package's "
             "systems",
             learner="ssgp-parametric", residual=_SENS, term="linearized"),
    _variant("robust-mpc-exact", "robust MPC, exact term",
             "robust-mpc@converged with the learned residual itself in the NLP (term='exact') "
             "instead of its expansion about the previous plan", learner="ssgp-parametric",
             residual=_SENS, term="exact"),
    # the RTI's other learned terms (preset rti)
    _variant("ssgp-mpc-rti-linearized", "SSGP MPC, RTI linearized",
             "paper-mpc@rti with the GP linearized per node at the shifted plan on every system "
             "(term='linearized': its full Jacobian in the QP)", scheme="rti",
             term="linearized"),
    _variant("ssgp-mpc-rti-zero-order", "SSGP MPC, RTI zero-order",
             "paper-mpc@rti with the GP's value frozen per node (term='zero-order': the nominal "
             "QP structure, the gradient corrected with the previous multipliers)",
             scheme="rti", term="zero-order"),
    _variant("ssgp-mpc-rti-pattern", "SSGP MPC, RTI pattern",
             "paper-mpc@rti with the GP's Jacobian kept only on the nominal model's Jacobian "
             "pattern (term='linearized-pattern')", scheme="rti", term="linearized-pattern"),
    # the converged references warm-started with the previous multipliers (preset rti)
    _variant("nominal-mpc-warm-duals", "nominal MPC, warm duals",
             "nominal-mpc whose converged IPOPT solves also start from the previous solve's "
             "multipliers (Converged(warm_start_duals=True)): the fastest converged reference "
             "for the RTI's step-time ratios", learner=None,
             scheme=Converged(warm_start_duals=True)),
    _variant("oracle-mpc-warm-duals", "oracle MPC, warm duals",
             "oracle-mpc whose converged IPOPT solves also start from the previous solve's "
             "multipliers (Converged(warm_start_duals=True))", learner=None, oracle=True,
             scheme=Converged(warm_start_duals=True)),
])
for _name in ("ssgp-mpc-rti-linearized", "ssgp-mpc-rti-zero-order", "ssgp-mpc-rti-pattern"):
    _base = STUDY_VARIANTS[_name]
    STUDY_VARIANTS[f"{_name}-split"] = dataclasses.replace(
        _base, name=f"{_name}-split", label=f"{_base.label}, split",
        description=f"{_name} split into a preparation and a feedback phase "
                    "(scheme='rti-split')",
        settings=tuple((k, "rti-split" if k == "scheme" else v) for k, v in _base.settings))
"""The study variants (not recipes; earlier studies decided on them): each with its own
settings."""
for _name, _recipe in STUDY_VARIANTS.items():
    register_controller(_name, _recipe)

RTI_VARIANTS = {name: r for name, r in CONTROLLERS.items() if r.family == "mpc" and (
    r.scheme in ("rti", "rti-split") or dict(r.settings).get("scheme") in ("rti", "rti-split"))}
"""Every real-time-iteration controller (composed names, aliases, study variants)."""
SPEED_VARIANTS = {k: v for k, v in STUDY_VARIANTS.items() if k in (
    "ssgp-mpc-nominal-hessian", "ssgp-mpc-model-inputs", "ssgp-mpc-linearized",
    "ssgp-mpc-linearized-model-inputs")}
"""The paper recipe's speed variants (presets ``speed-options`` and ``linearized``)."""
