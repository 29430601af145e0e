"""When an MPC plans and over what mesh: receding horizon (Algorithm 1) or one episodic plan.

Both make every period they execute from a plan a held interval of its mesh
(:mod:`gp_agents.mpc.ocp`), so the action sent to the env is a decision of the plan.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from gp_agents.defaults import default_planning
from gp_agents.mpc.ocp import Mesh
from gp_agents.mpc.planner import Plan
from gp_envs.model import ControlModel

__all__ = ["Episodic", "RecedingHorizon"]


@dataclass(frozen=True)
class RecedingHorizon:
    """Re-plan every ``replan_every`` periods over a fixed horizon (paper, Algorithm 1).

    The first ``replan_every`` periods of each plan are held (they are executed), the rest of
    the horizon is polynomial control on ``n_intervals`` LG intervals of ``n_nodes`` nodes.

    Args:
        horizon: seconds (None: the system's
            :class:`~gp_agents.defaults.PlanningDefaults`, or
            :func:`~gp_agents.defaults.default_planning`'s for a system without them).
        n_nodes, n_intervals: the LG part (None: the system's defaults; 12 nodes on one
            interval for a system without them). replan_every: ``p`` >= 1.
        held_nodes: LG nodes in each held period.
    """

    horizon: float | None = None
    n_nodes: int | None = None
    n_intervals: int | None = None
    replan_every: int = 1
    held_nodes: int = 3

    name = "receding"
    learns = True

    def __post_init__(self) -> None:
        if isinstance(self.replan_every, bool) or int(self.replan_every) < 1:
            raise ValueError(f"replan_every must be >= 1, got {self.replan_every}")
        if self.horizon is not None and not (np.isfinite(self.horizon) and self.horizon > 0):
            raise ValueError(f"horizon must be a positive number of seconds, got {self.horizon}")
        for name in ("n_nodes", "n_intervals", "held_nodes"):
            value = getattr(self, name)
            if value is not None and (isinstance(value, bool) or int(value) < 1):
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")

    def resolve(self, model: ControlModel) -> RecedingHorizon:
        """This horizon with every unset field from ``model``'s planning defaults
        (:func:`gp_agents.defaults.default_planning`: its system's, or the defaults for a
        system without an entry)."""
        defaults = default_planning(model)
        return replace(
            self, horizon=float(defaults.horizon if self.horizon is None else self.horizon),
            n_nodes=int(defaults.n_nodes if self.n_nodes is None else self.n_nodes),
            n_intervals=int(defaults.n_intervals if self.n_intervals is None
                            else self.n_intervals),
            replan_every=int(self.replan_every), held_nodes=int(self.held_nodes))

    def mesh(self, dt: float) -> Mesh:
        """The receding mesh for control period ``dt`` (s) (a resolved horizon)."""
        if self.horizon is None or self.n_nodes is None or self.n_intervals is None:
            raise ValueError("an unresolved RecedingHorizon has no mesh: call resolve(model)")
        return Mesh.receding(self.horizon, dt, self.n_nodes, self.n_intervals,
                             held_periods=self.replan_every, held_nodes=self.held_nodes)

    def due(self, step: int, plan: Plan | None) -> bool:
        """Whether to plan at period ``step``."""
        return plan is None or step - plan.step >= self.replan_every


@dataclass(frozen=True)
class Episodic:
    """Plan once over the whole task at the first ``act``, then execute it open loop (no
    learning during the episode).

    Args:
        duration: seconds (None: the task's duration). nodes_per_period: LG nodes per held
            period (None: the system's default, 3 for an unregistered system).
    """

    duration: float | None = None
    nodes_per_period: int | None = None

    name = "episodic"
    learns = False

    def __post_init__(self) -> None:
        if self.duration is not None and not (np.isfinite(self.duration) and self.duration > 0):
            raise ValueError(f"duration must be a positive number of seconds, "
                             f"got {self.duration}")
        if self.nodes_per_period is not None and (isinstance(self.nodes_per_period, bool)
                                                  or int(self.nodes_per_period) < 1):
            raise ValueError(f"nodes_per_period must be an integer >= 1, "
                             f"got {self.nodes_per_period!r}")

    @property
    def horizon(self) -> float:
        """The planned duration, seconds (a resolved schedule)."""
        if self.duration is None:
            raise ValueError("an unresolved Episodic has no horizon: call resolve(model)")
        return float(self.duration)

    def resolve(self, model: ControlModel) -> Episodic:
        """This schedule with every unset field from ``model``'s task and system defaults."""
        defaults = default_planning(model)
        return Episodic(float(model.task.duration if self.duration is None else self.duration),
                        int(defaults.nodes_per_period if self.nodes_per_period is None
                            else self.nodes_per_period))

    def mesh(self, dt: float) -> Mesh:
        """Every period of the task held (a resolved schedule)."""
        return Mesh.episodic(self.horizon, dt, int(self.nodes_per_period or 3))

    def due(self, step: int, plan: Plan | None) -> bool:
        """Only the first period."""
        return plan is None
