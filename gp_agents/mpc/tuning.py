"""Per-system tuning of this package's real-time iteration, keyed by system name: data only.

A system's time scales (horizon and resolution) are the controllers' defaults of
:mod:`gp_agents.defaults`. How *this* controller's real-time iteration solves its QPs on that
system is solver tuning and lives here: :class:`RTITuning`, registered with
:func:`register_rti_tuning` and read by :meth:`gp_agents.mpc.config.MPCConfig.resolve` when an
MPC with ``scheme=RTI(...)`` leaves a setting unset. A recipe that needs other values on a system
keeps them itself (:mod:`gp_agents.mpc.recipes`).

What the built-in entries hold, and why:

- QP solver: the active-set solve from the shifted plan's active set
  (:class:`~gp_agents.mpc.active_set.ActiveSetQP`), with proxqp as its fallback plugin; piqp on
  the Dubins vehicle, whose soft obstacle margin makes the Hessian indefinite near the obstacle
  (where proxqp is slow or fails), and on the pendulum. hpipm cannot take the pseudospectral
  NLP's structure (one dense LG interval is no stage-wise OCP); daqp needs a positive definite
  Hessian.
- Levenberg-Marquardt ``mu`` on the QP Hessian: 0.01 on the Dubins vehicle, where the plain step
  can alternate between turning left and right near ``v = 0``, and on the cart pole; 0 elsewhere.
- Learned term: the residual linearized per node, except on the quadrotor, where the entries on
  the nominal Jacobian's pattern only keep the nominal QP's sparsity.
- Recovery iterations (a rejected step's feasibility projections and SQP iterations before the
  converged fallback): 3; none on the Dubins vehicle, where lightly damped recovered steps
  follow plans the converged solve would not take.

A system without an entry gets :class:`RTITuning`'s defaults; a model of no registered system at
all gets the plain ``"osqp"`` QP solver.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gp_agents.defaults import is_registered
from gp_envs.model import ControlModel

__all__ = ["RTI_TUNING", "RTITuning", "register_rti_tuning", "rti_tuning"]


RECOVERY_ITERATIONS = 3
"""Recovery QP solves of the RTI on a system without its own entry."""


@dataclass(frozen=True)
class RTITuning:
    """How the real-time iteration solves on one system (module docstring).

    Attributes:
        qp_solver: a CasADi ``conic`` plugin name, or ``"active-set:<plugin>"`` (the active-set
            solve from the shifted plan, that plugin as its fallback).
        levenberg_marquardt: ``mu`` >= 0 on the QP Hessian's diagonal; 0: plain Gauss-Newton.
        learned_term: how a learned residual enters the QP when the MPC names none: a name of
            :data:`gp_agents.mpc.config.LEARNED_TERMS` (``"linearized"``,
            ``"linearized-pattern"``, ``"zero-order"``).
        recovery_iterations: further SQP iterations a step with a too large constraint
            violation may take before the converged fallback (:class:`~gp_agents.mpc.settings.
            RTI`'s ``recovery_iterations``).
    """

    qp_solver: str = "active-set:proxqp"
    levenberg_marquardt: float = 0.0
    learned_term: str = "linearized"
    recovery_iterations: int = RECOVERY_ITERATIONS

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
        if not (isinstance(self.learned_term, str) and self.learned_term):
            raise ValueError(f"RTITuning: learned_term must be a learned-term name, got "
                             f"{self.learned_term!r}")


RTI_TUNING: dict[str, RTITuning] = {
    "cartpole": RTITuning(levenberg_marquardt=1e-2),
    "quadrotor": RTITuning(learned_term="linearized-pattern"),
    "dubins": RTITuning(qp_solver="active-set:piqp", levenberg_marquardt=1e-2,
                        recovery_iterations=0),
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
