"""The MPC's settings objects, grouped by what they configure: the scheme (:class:`Converged`,
:class:`RTI`) and the learned residual (:class:`Residual`); the horizon's are in
:mod:`~gp_agents.mpc.schedule`, the constraints' in :mod:`~gp_agents.mpc.ocp`. Each option lives
on the object it configures, so a setting that does not apply to a combination cannot be passed;
:meth:`gp_agents.mpc.config.MPCConfig.resolve` raises for one that could be passed but would
change nothing. A scheme builds its planner (:meth:`Converged.planner`, :meth:`RTI.planner`): the
planner class is chosen once, here.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from gp_agents.mpc.active_set import ActiveSetQP
from gp_agents.mpc.diagnostics import SolveCounts
from gp_agents.mpc.guard import NominalGuardPlanner, check_nominal_above
from gp_agents.mpc.ocp import Constraints, Mesh
from gp_agents.mpc.planner import Planner
from gp_agents.mpc.planning_model import PlanningModel
from gp_agents.mpc.rti import RTIPlanner, check_levenberg_marquardt
from gp_agents.mpc.rti_split import SplitRTIPlanner
from gp_agents.mpc.sqp import SQPPlanner
from gp_agents.residual import ResidualModel
from gp_envs.model import ControlModel

__all__ = ["RTI", "SCHEME_NAMES", "SQP", "Converged", "Residual", "scheme_settings"]


@dataclass(frozen=True)
class Converged:
    """Every plan solved to convergence by a CasADi NLP solver (the paper's scheme).

    Attributes:
        solver: a CasADi ``nlpsol`` plugin (``"ipopt"``; ``"sqpmethod"`` ...).
        solver_options: the plugin's options (e.g. ``{"ipopt": {"tol": 1e-8}}``).
        max_iterations: IPOPT's iteration cap of one solve (``max_iter``), >= 1; None: 500.
            The only cap (no wall-clock limit, so outcomes never depend on machine load).
            Another plugin's cap goes in its ``solver_options`` (setting this for one
            raises), and IPOPT's ``max_iter`` goes here, not in ``solver_options``.
        jit: compile the NLP's functions to C at build (slower build, faster solves).
        warm_start_duals: a warm solve also starts from the previous solve's multipliers, with
            IPOPT's warm-start options (IPOPT only). Off by default: on the oracle cart pole it
            stays in the previous plan's basin of the swing-up and costs more.
        nominal_above: with a linearized learned term, also plan with the nominal model at
            every replan and act on its plan where the learned plan's expansion error exceeds
            this many tolerances (:class:`~gp_agents.mpc.guard.NominalGuardPlanner`: one more
            solve per replan); None: off. Not for an RTI's or SQP's fallback solves.
    """

    solver: str = "ipopt"
    solver_options: Mapping[str, Any] | None = None
    max_iterations: int | None = None
    jit: bool = False
    warm_start_duals: bool = False
    nominal_above: float | None = None

    name = "converged"

    def __post_init__(self) -> None:
        if not (isinstance(self.solver, str) and self.solver):
            raise ValueError(f"Converged: solver must be a CasADi nlpsol plugin name, got "
                             f"{self.solver!r}")
        if self.max_iterations is not None and (
                isinstance(self.max_iterations, bool)
                or not isinstance(self.max_iterations, int | np.integer)
                or self.max_iterations < 1):
            raise ValueError(f"Converged: max_iterations must be an int >= 1, got "
                             f"{self.max_iterations!r}")
        if self.max_iterations is not None and self.solver != "ipopt":
            raise ValueError(f"Converged: max_iterations is IPOPT's max_iter; solver "
                             f"{self.solver!r} takes its own cap in solver_options (e.g. "
                             f"solver_options={{'max_iter': ...}} for sqpmethod)")
        if self.solver_options is not None and not isinstance(self.solver_options, Mapping):
            raise TypeError(f"Converged: solver_options must be a mapping, got "
                            f"{type(self.solver_options).__name__}")
        ipopt = (self.solver_options or {}).get("ipopt", {})
        if self.solver == "ipopt" and isinstance(ipopt, Mapping) and "max_iter" in ipopt:
            raise ValueError("Converged: IPOPT's iteration cap is max_iterations=..., not "
                             "solver_options={'ipopt': {'max_iter': ...}}")
        if self.warm_start_duals and self.solver != "ipopt":
            raise ValueError(f"Converged: warm_start_duals uses IPOPT's warm-start options; "
                             f"it does not apply to solver {self.solver!r}")
        check_nominal_above(self.nominal_above)

    def planner_settings(self) -> dict[str, Any]:
        """Keyword settings of :class:`~gp_agents.mpc.planner.Planner`."""
        return {"solver": self.solver, "solver_options": dict(self.solver_options or {}),
                "max_iterations": int(500 if self.max_iterations is None
                                      else self.max_iterations),
                "jit": bool(self.jit), "warm_start_duals": bool(self.warm_start_duals)}

    def planner(self, planning: PlanningModel, mesh: Mesh, constraints: Constraints,
                counts: SolveCounts | None = None) -> Planner:
        """The planner of this scheme: every plan a converged solve (beside the nominal
        model's with ``nominal_above``)."""
        if self.nominal_above is not None:
            return NominalGuardPlanner(planning, mesh, constraints, above=self.nominal_above,
                                       counts=counts, **self.planner_settings())
        return Planner(planning, mesh, constraints, counts=counts, **self.planner_settings())


@dataclass(frozen=True)
class RTI:
    """The real-time iteration: a converged solve at a cold start, then one Gauss-Newton SQP
    step per replan from the shifted plan (:class:`~gp_agents.mpc.rti.RTIPlanner`); a step whose
    constraint violation is too large is rejected and replaced by a converged solve.

    Attributes:
        split: split each step into a preparation (after the action is sent, together with the
            learner update) and a feedback phase (the QP with the measured state):
            :class:`~gp_agents.mpc.rti_split.SplitRTIPlanner`. Each step's record then has its
            ``preparation_time``; the rest of ``act_time`` is the latency.
        qp_solver: a CasADi ``conic`` plugin, ``"active-set:<plugin>"`` or an
            :class:`~gp_agents.mpc.active_set.ActiveSetQP`; None: the system's tuning
            (:func:`gp_agents.mpc.tuning.rti_tuning`).
        levenberg_marquardt: ``mu`` >= 0 on the QP Hessian's diagonal; None: the system's
            tuning.
        recovery_iterations: further QP solves (an iteration budget, >= 0) a step whose
            constraint violation is too large may take inside the real-time scheme, from the
            step's own point with the measured X(t0) and the learned term re-expanded at each
            iterate: feasibility projections and SQP iterations, the step recovered only by
            an SQP iteration within tolerance, else rejected and replaced by the converged
            fallback (:meth:`~gp_agents.mpc.rti.RTIPlanner._recover`); 0: reject at once.
            None: the system's tuning.
        fallback: the converged solves (cold start, rejected steps); by default warm-started
            with the previous multipliers.
    """

    split: bool = False
    qp_solver: str | ActiveSetQP | None = None
    levenberg_marquardt: float | None = None
    recovery_iterations: int | None = None
    fallback: Converged = field(default_factory=lambda: Converged(warm_start_duals=True))

    def __post_init__(self) -> None:
        if not isinstance(self.split, bool):
            raise TypeError(f"RTI: split must be a bool, got {self.split!r}")
        if self.levenberg_marquardt is not None:
            check_levenberg_marquardt(self.levenberg_marquardt)
        if self.recovery_iterations is not None and (
                isinstance(self.recovery_iterations, bool)
                or not isinstance(self.recovery_iterations, int | np.integer)
                or self.recovery_iterations < 0):
            raise ValueError(f"RTI: recovery_iterations must be an int >= 0 or None, got "
                             f"{self.recovery_iterations!r}")
        if not isinstance(self.fallback, Converged):
            raise TypeError(f"RTI: fallback must be a Converged, got "
                            f"{type(self.fallback).__name__}")
        if self.fallback.nominal_above is not None:
            raise ValueError("RTI: the fallback's nominal_above does not apply (the fallback "
                             "solves one plan at a time); use scheme=Converged(nominal_above=...)")

    @property
    def name(self) -> str:
        """``"rti"`` or ``"rti-split"``."""
        return "rti-split" if self.split else "rti"

    def planner(self, planning: PlanningModel, mesh: Mesh, constraints: Constraints,
                counts: SolveCounts | None = None) -> RTIPlanner:
        """The planner of this scheme: :class:`~gp_agents.mpc.rti.RTIPlanner`, or
        :class:`~gp_agents.mpc.rti_split.SplitRTIPlanner` with ``split`` (settings resolved:
        :meth:`gp_agents.mpc.config.MPCConfig.resolve`)."""
        if self.qp_solver is None or self.levenberg_marquardt is None or (
                self.recovery_iterations is None):
            raise ValueError("an unresolved RTI has no planner: resolve it with "
                             "MPCConfig(scheme=...).resolve(model)")
        kind = SplitRTIPlanner if self.split else RTIPlanner
        return kind(planning, mesh, constraints, counts=counts, qp_solver=self.qp_solver,
                    levenberg_marquardt=self.levenberg_marquardt,
                    recovery_iterations=self.recovery_iterations,
                    **self.fallback.planner_settings())


@dataclass(frozen=True)
class SQP:
    """Every plan solved to convergence by SQP iterations on the real-time iteration's QP
    machinery (:class:`~gp_agents.mpc.sqp.SQPPlanner`): from the shifted plan, Gauss-Newton
    QP steps with the learned term re-expanded at every iterate, a merit line search, a
    convergence test on the step and the constraint violation; IPOPT at the cold start and
    when a plan does not converge within the budget.

    Attributes:
        max_iterations: SQP iterations of one plan, >= 1 (a count, never a time).
        tolerance: convergence tolerance on the full step (infinity norm, in the NLP
            variables' units) and on the constraint violation, > 0; not below the QP solver's
            own accuracy (about 1e-6 for the tuned solvers).
        qp_solver: the QP's, as for :class:`RTI`; None: the system's tuning
            (:func:`gp_agents.mpc.tuning.rti_tuning`).
        levenberg_marquardt: ``mu`` >= 0 on the QP Hessian's diagonal, as for :class:`RTI`;
            None: 0, whatever the system's RTI tuning. The RTI's damping steadies one step
            per period; iterated to convergence it only shortens every step (the fixed points
            are the same), and the iteration then converges linearly and slowly, often not
            within its budget, where the line search already makes each step a descent.
        fallback: the converged IPOPT solves (cold start, no convergence).
    """

    max_iterations: int = 30
    tolerance: float = 1e-4
    qp_solver: str | ActiveSetQP | None = None
    levenberg_marquardt: float | None = None
    fallback: Converged = field(default_factory=lambda: Converged(warm_start_duals=True))

    name = "sqp"

    def __post_init__(self) -> None:
        if (isinstance(self.max_iterations, bool)
                or not isinstance(self.max_iterations, int | np.integer)
                or self.max_iterations < 1):
            raise ValueError(f"SQP: max_iterations must be an int >= 1, got "
                             f"{self.max_iterations!r}")
        if not (np.isfinite(self.tolerance) and self.tolerance > 0):
            raise ValueError(f"SQP: tolerance must be a positive number, got {self.tolerance!r}")
        if self.levenberg_marquardt is not None:
            check_levenberg_marquardt(self.levenberg_marquardt)
        if not isinstance(self.fallback, Converged):
            raise TypeError(f"SQP: fallback must be a Converged, got "
                            f"{type(self.fallback).__name__}")
        if self.fallback.nominal_above is not None:
            raise ValueError("SQP: the fallback's nominal_above does not apply (the fallback "
                             "solves one plan at a time); use scheme=Converged(nominal_above=...)")

    def planner(self, planning: PlanningModel, mesh: Mesh, constraints: Constraints,
                counts: SolveCounts | None = None) -> SQPPlanner:
        """The planner of this scheme (settings resolved:
        :meth:`gp_agents.mpc.config.MPCConfig.resolve`)."""
        if self.qp_solver is None or self.levenberg_marquardt is None:
            raise ValueError("an unresolved SQP has no planner: resolve it with "
                             "MPCConfig(scheme=...).resolve(model)")
        return SQPPlanner(planning, mesh, constraints, counts=counts,
                          sqp_iterations=self.max_iterations, tolerance=self.tolerance,
                          qp_solver=self.qp_solver,
                          levenberg_marquardt=self.levenberg_marquardt,
                          **self.fallback.planner_settings())


SCHEME_NAMES = ("converged", "sqp", "rti", "rti-split")
"""The scheme shortcuts of :func:`scheme_settings`."""


def scheme_settings(scheme: str | Converged | SQP | RTI) -> Converged | SQP | RTI:
    """The settings object of ``scheme``: ``"converged"`` -> :class:`Converged`, ``"rti"`` ->
    :class:`RTI`, ``"rti-split"`` -> ``RTI(split=True)``; an object is returned as it is.

    Raises:
        ValueError: an unknown name. TypeError: neither a name nor a settings object.
    """
    if isinstance(scheme, Converged | SQP | RTI):
        return scheme
    if isinstance(scheme, str):
        if scheme == "converged":
            return Converged()
        if scheme == "sqp":
            return SQP()
        if scheme in ("rti", "rti-split"):
            return RTI(split=scheme == "rti-split")
        raise ValueError(f"scheme must be one of {list(SCHEME_NAMES)} or a Converged / SQP / "
                         f"RTI, got {scheme!r}")
    raise TypeError(f"scheme must be a name or a Converged / SQP / RTI, got "
                    f"{type(scheme).__name__}")


@dataclass(frozen=True)
class Residual:
    """The learned residual: which states get one, what the learner sees, whether it learns
    online (:class:`~gp_agents.residual.ResidualModel`). Only for an MPC with a learner.

    Attributes:
        uncertain: state components with a learned residual; None: the model's accelerations
            (``dynamic_indices``).
        inputs: state components fed to the learner: indices, None (all), or ``"model"`` (those
            the nominal model's uncertain rates depend on).
        sensitivities: the learner also sees the nominal model's parameter sensitivities
            ``d f_p / d p`` (with linear features on them, an explicit parametric part of the
            residual: :func:`gp_agents.parametric_ssgp`).
        learn_online: feed each observed transition to the learner's ``update`` before the next
            plan (Algorithm 1). None: when the horizon is receding and the learner has an
            ``update``; True where neither holds raises.
        refit_until: while the learner was last fitted on fewer transitions than this, refit
            it (hyperparameters, standardization, frequencies: ``fit``) on every transition
            learned so far, its initial data included, each time their number has doubled
            since that fit, instead of only updating its weights. 0 (the default): never refit.
            A learner fitted on a handful of samples keeps that handful's input scales and
            length scales for good otherwise. Whatever this is, a learner with no initial data
            (never pretrained) is fitted on the first transitions it sees, and until then the
            MPC plans with the model alone.
    """

    uncertain: tuple[int, ...] | None = None
    inputs: tuple[int, ...] | Literal["model"] | None = None
    sensitivities: bool = False
    learn_online: bool | None = None
    refit_until: int = 0

    def __post_init__(self) -> None:
        if self.uncertain is not None:
            object.__setattr__(self, "uncertain", tuple(int(i) for i in self.uncertain))
        if self.inputs is not None and not isinstance(self.inputs, str):
            object.__setattr__(self, "inputs", tuple(int(i) for i in self.inputs))
        if not isinstance(self.sensitivities, bool):
            raise TypeError(f"Residual: sensitivities must be a bool, got {self.sensitivities!r}")
        if self.learn_online is not None and not isinstance(self.learn_online, bool):
            raise TypeError(f"Residual: learn_online must be a bool or None, got "
                            f"{self.learn_online!r}")
        if (isinstance(self.refit_until, bool) or not isinstance(self.refit_until, int)
                or self.refit_until < 0):
            raise ValueError(f"Residual: refit_until must be an integer >= 0, got "
                             f"{self.refit_until!r}")

    def model(self, model: ControlModel) -> ResidualModel:
        """The residual these settings give on ``model``: what the learner is fitted on
        (``targets``) and which of its inputs are parameter sensitivities
        (``sensitivity_columns``)."""
        return ResidualModel(model, self.uncertain, self.inputs, self.sensitivities)
