"""Per-system tuning of this package's solvers, keyed by system name.

A system's time scales (horizon and resolution) are the controllers' defaults of
:mod:`gp_agents.defaults`. How *this* controller's real-time iteration solves its QPs on that
system is solver tuning and lives here:
:class:`RTITuning`, registered with :func:`register_rti_tuning` and read by
:func:`rti_tuning` when an MPC with ``scheme=RTI(...)`` is built without an explicit setting.

The built-in systems' entries were chosen by measurement on tuning seeds (the studies
``rti_qp_solvers``, ``rti_levenberg_marquardt`` and ``rti_learned_term``; their decision records
are in the documentation):

- QP solver: the active-set solve from the shifted plan's active set
  (:class:`~gp_agents.mpc.active_set.ActiveSetQP`) halves the median RTI step or better on every
  system at the same closed-loop costs. Its fallback plugin is proxqp (cart pole, quadrotor), and
  piqp on the Dubins vehicle (whose soft obstacle margin makes the Hessian indefinite near the
  obstacle, where proxqp is slow or fails) and the pendulum. hpipm cannot take the
  pseudospectral NLP's structure (one dense LG interval is no stage-wise OCP); daqp needs a
  positive definite Hessian.
- Levenberg-Marquardt ``mu``: 0.01 on the Dubins vehicle, where the plain step of the split SSGP
  RTI alternates between turning left and right near ``v = 0`` (0.01 reaches the goal on every
  tuning seed and cuts the rejected steps, 0.03 loses a nominal episode), and on the cart pole
  (fewer rejected SSGP RTI steps at the same outcomes). Other systems: 0. The robust recipe on
  the Dubins vehicle: 1, which removes its rejected steps (the controls flipping from bound to
  bound in the first seconds) at the converged recipe's cost; the nominal and black-box
  recipes, whose plans must be corrected more at every period, lose tuning seeds from 0.3 on
  (``RTITuning.recipe_levenberg_marquardt``).
- Learned term: the residual linearized per node, except on the quadrotor, where the entries on
  the nominal Jacobian's pattern only (the nominal QP's sparsity) give the lower split-RTI
  latency at the same outcomes.

- Recovery iterations (a rejected step's feasibility projections and SQP iterations before
  the converged fallback): 3, which keeps every system's rejected steps within a few percent
  at the converged recipe's outcomes (decision record ``docs/studies/rti_recovery.md``, tuning
  seeds). On the Dubins vehicle only the robust recipe recovers (with its ``mu`` = 1): the
  other recipes' lightly damped steps, recovered, follow plans the converged solve would not
  take (higher costs, a lost tuning seed), and keep the converged fallback alone
  (``RTITuning.recipe_recovery_iterations``).

A system without an entry gets :class:`RTITuning`'s defaults; a model of no registered system at
all gets the plain ``"osqp"`` QP solver.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from gp_agents.defaults import is_registered
from gp_envs.model import ControlModel

__all__ = ["RTI_TUNING", "RTITuning", "register_rti_tuning", "rti_tuning"]


RECOVERY_ITERATIONS = 3
"""Recovery QP solves of the RTI (the study ``rti_recovery``; the Dubins vehicle: the robust
recipe's only)."""


@dataclass(frozen=True)
class RTITuning:
    """How the real-time iteration solves on one system (module docstring).

    Attributes:
        qp_solver: a CasADi ``conic`` plugin name, or ``"active-set:<plugin>"`` (the active-set
            solve from the shifted plan, that plugin as its fallback).
        levenberg_marquardt: ``mu`` >= 0 on the QP Hessian's diagonal; 0: plain Gauss-Newton.
        learned_term: how a learned residual enters the QP when the MPC names none: a name of
            :data:`gp_agents.mpc.controller.LEARNED_TERMS` (``"linearized"``,
            ``"linearized-pattern"``, ``"zero-order"``).
        recovery_iterations: further SQP iterations a step with a too large constraint
            violation may take before the converged fallback (:class:`~gp_agents.mpc.settings.
            RTI`'s ``recovery_iterations``).
        recipe_levenberg_marquardt: ``mu`` of the named recipes of :func:`gp_agents.make_mpc`
            where it differs from ``levenberg_marquardt`` (recipe name -> ``mu``): a model
            close to the truth moves its plan little from one period to the next and takes a
            heavier damping that a wrong model, whose plan must be corrected at every
            period, does not.
        recipe_recovery_iterations: ``recovery_iterations`` of the named recipes where it
            differs from the system's (recipe name -> budget).
    """

    qp_solver: str = "active-set:proxqp"
    levenberg_marquardt: float = 0.0
    learned_term: str = "linearized"
    recovery_iterations: int = RECOVERY_ITERATIONS
    recipe_levenberg_marquardt: Mapping[str, float] = field(default_factory=dict)
    recipe_recovery_iterations: Mapping[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not (isinstance(self.qp_solver, str) and self.qp_solver):
            raise ValueError(f"RTITuning: qp_solver must be a plugin name, got "
                             f"{self.qp_solver!r}")
        if not (np.isfinite(self.levenberg_marquardt) and self.levenberg_marquardt >= 0):
            raise ValueError(f"RTITuning: levenberg_marquardt must be a finite number >= 0, "
                             f"got {self.levenberg_marquardt!r}")
        if isinstance(self.recovery_iterations, bool) or int(self.recovery_iterations) < 0:
            raise ValueError(f"RTITuning: recovery_iterations must be an int >= 0, got "
                             f"{self.recovery_iterations!r}")
        for recipe, mu in self.recipe_levenberg_marquardt.items():
            if not (isinstance(recipe, str) and np.isfinite(mu) and mu >= 0):
                raise ValueError(f"RTITuning: recipe_levenberg_marquardt must map recipe names "
                                 f"to finite numbers >= 0, got {recipe!r}: {mu!r}")
        for recipe, budget in self.recipe_recovery_iterations.items():
            if not (isinstance(recipe, str) and isinstance(budget, int | np.integer)
                    and not isinstance(budget, bool) and budget >= 0):
                raise ValueError(f"RTITuning: recipe_recovery_iterations must map recipe names "
                                 f"to ints >= 0, got {recipe!r}: {budget!r}")
        if not (isinstance(self.learned_term, str) and self.learned_term):
            raise ValueError(f"RTITuning: learned_term must be a learned-term name, got "
                             f"{self.learned_term!r}")


RTI_TUNING: dict[str, RTITuning] = {
    "cartpole": RTITuning(levenberg_marquardt=1e-2),
    "quadrotor": RTITuning(learned_term="linearized-pattern"),
    "dubins": RTITuning(qp_solver="active-set:piqp", levenberg_marquardt=1e-2,
                        recipe_levenberg_marquardt={"robust": 1.0}, recovery_iterations=0,
                        recipe_recovery_iterations={"robust": RECOVERY_ITERATIONS}),
    "pendulum": RTITuning(qp_solver="active-set:piqp"),
}
"""The registered tuning by system name (the built-in systems'; module docstring)."""

UNREGISTERED = RTITuning(qp_solver="osqp")
"""The tuning of a model whose system is not registered at all."""


def register_rti_tuning(system: str, tuning: RTITuning) -> RTITuning:
    """Register (or replace) the RTI tuning of the system called ``system``; returns it.

    Raises:
        TypeError: ``tuning`` is not an :class:`RTITuning`.
    """
    if not isinstance(tuning, RTITuning):
        raise TypeError(f"tuning must be an RTITuning, got {type(tuning).__name__}")
    RTI_TUNING[str(system)] = tuning
    return tuning


def rti_tuning(model: ControlModel | str) -> RTITuning:
    """The RTI tuning of ``model``'s system (a model, or a system name): its registered entry,
    else the defaults (a registered system) or :data:`UNREGISTERED` (no registered system)."""
    name = model if isinstance(model, str) else model.name
    if name in RTI_TUNING:
        return RTI_TUNING[name]
    return RTITuning() if is_registered(name) else UNREGISTERED
