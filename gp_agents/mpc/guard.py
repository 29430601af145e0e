"""A plan-level nominal fallback: plan with the nominal model beside the learned one, and use its
plan where the learned plan follows neither model.

A linearized learned term (:class:`~gp_agents.mpc.gp_linearized.LinearizedGP`) makes the plan
optimal for its expansion about the previous plan, not for the learner; the expansion's error
at the new plan's nodes is the step's ``linearization_error`` (in tolerances). Where the learned
mean bends sharply along the plan (a smooth fit of a kink such as Coulomb friction's sign), one
linearization is far from it at the plan's own nodes, and the plan follows neither the learned
model nor the nominal one. The learner's own check (:class:`~gp_agents.learners.NominalFallback`)
compares predictions of the newest samples and cannot see this: the learned model can predict
them better than the nominal one and still bend where the plan goes.

:class:`NominalGuardPlanner` keeps two chains of plans, each warm-started from its own previous
plan: the learned one (the scheme's converged planner) and the nominal model's (the same mesh,
constraints and solver, no learned term). At every replan it solves both and acts on the learned
plan unless its expansion error exceeds ``above`` tolerances (or the learned solve gave no usable
plan) and the nominal solve succeeded; such a step records ``nominal_plan`` and counts in
:attr:`~gp_agents.mpc.diagnostics.SolveCounts.nominal_plans`. A nominal chain of its own matters:
a nominal solve started from the learned plan stays in that plan's basin. It costs one more
converged solve per replan. The decision depends only on the solves' results, never on time.

It is a trade, not a free guard, and off by default: where the nominal model is far from the
truth, or after the system changed, the nominal plans it takes on the steps whose expansion is
off do not know what the learner knows, and they cost more than the learned plans they replace
or miss the task.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from gp_agents.mpc.diagnostics import SolveCounts
from gp_agents.mpc.learned_term import NoLearnedTerm
from gp_agents.mpc.ocp import Constraints, Mesh
from gp_agents.mpc.planner import Plan, Planner
from gp_agents.mpc.planning_model import PlanningModel

__all__ = ["NominalGuardPlanner", "check_nominal_above"]

_SUMMED = ("iterations", "solve_time", "solves")


def check_nominal_above(value: Any, owner: str = "Converged") -> None:
    """Raise ``ValueError`` unless ``value`` is None or a finite number > 0."""
    if value is None:
        return
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating) \
            or not (np.isfinite(value) and value > 0):
        raise ValueError(f"{owner}: nominal_above must be a finite number > 0 (tolerances of "
                         f"the linearized term's expansion error) or None, got {value!r}")


class NominalGuardPlanner(Planner):
    """A converged :class:`~gp_agents.mpc.planner.Planner` with the nominal model's plan as the
    fallback of a learned plan too far from its learner (module doc).

    Args:
        planning, mesh, constraints, counts, settings: as :class:`Planner` (``settings`` its
            keyword settings); ``planning``'s term is the learned one.
        above: expansion error (in the term's tolerances, > 0) above which the nominal plan is
            used.
    """

    def __init__(self, planning: PlanningModel, mesh: Mesh, constraints: Constraints, *,
                 above: float, counts: SolveCounts | None = None, **settings: Any) -> None:
        check_nominal_above(above, "NominalGuardPlanner")
        super().__init__(planning, mesh, constraints, counts=counts, **settings)
        self.above = float(above)
        nominal = PlanningModel(planning.model, planning.residual, NoLearnedTerm())
        self.nominal = Planner(nominal, mesh, constraints, counts=self.counts, **settings)
        self._chains: dict[str, Plan | None] = {"learned": None, "nominal": None}

    def plan(self, x: np.ndarray, previous: Plan | None, step: int) -> tuple[Plan, dict[str, Any]]:
        """Both plans from ``x``, each warm-started from its own chain (from ``previous`` when
        the chain has none, e.g. after a rebuild; cold when ``previous`` is None); the learned
        plan unless it is too far from its learner (module doc)."""
        if previous is None:
            self._chains = {"learned": None, "nominal": None}
        warm = {k: previous if v is None else v for k, v in self._chains.items()}
        self.nominal.planning.model = self.planning.model  # follows a swapped nominal model
        learned, record = super().plan(x, warm["learned"], step)
        nominal, other = self.nominal.plan(x, warm["nominal"], step)
        self._chains = {"learned": learned, "nominal": nominal}
        error = float(record["linearization_error"])
        too_far = not np.isfinite(error) or error > self.above or bool(record["fallback"])
        use = too_far and bool(other["success"]) and not other["fallback"]
        out = dict(other if use else record)
        out.update({k: record[k] + other[k] for k in _SUMMED},
                   linearization_error=error, nominal_plan=use)
        self.counts.nominal_plans += int(use)
        return (nominal if use else learned), out
