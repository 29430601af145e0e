"""When an MPC plans and over what mesh: receding horizon (Algorithm 1) or one episodic plan.

Both make every period they execute from a plan a held interval of its mesh
(:mod:`gp_agents.mpc.ocp`), so the action sent to the env is a decision of the plan.
"""

from __future__ import annotations

from gp_agents.mpc.ocp import Mesh
from gp_agents.mpc.planner import Plan
from gp_envs.model import ControlModel
from gp_envs.systems import SYSTEMS, PlanningDefaults

__all__ = ["Episodic", "RecedingHorizon", "planning_defaults"]


def planning_defaults(model: ControlModel) -> PlanningDefaults | None:
    """The registered defaults of ``model``'s system (:class:`gp_envs.systems.PlanningDefaults`:
    horizon, LG nodes and intervals, nodes per episodic period, the RTI step's QP solver and
    Levenberg-Marquardt term), or None for a model of an unregistered system (then the horizon
    must be given).

    The QP solver defaults were chosen by measurement on tuning seeds 100-102
    (``python -m benchmarks.rti_qp_solvers``, ``benchmarks/results/rti_qp_solvers.md``): the
    active-set solve from the shifted plan's active set
    (:class:`~gp_agents.mpc.active_set.ActiveSetQP`) halves the median RTI step or better on
    every system at the same closed-loop costs, and has the shortest 90th percentile on the
    cart pole and the quadrotor. Its fallback plugin: proxqp (cart pole, quadrotor), piqp on
    the Dubins vehicle, whose soft obstacle margin makes the Hessian indefinite near the
    obstacle, where proxqp is slow or fails and piqp's 90th percentile of the step is the
    shortest (other systems: their registration). hpipm cannot take the
    pseudospectral NLP's structure (one dense LG interval is no stage-wise OCP); daqp needs a
    positive definite Hessian.

    The RTI's Levenberg-Marquardt term (``python -m benchmarks.rti_levenberg_marquardt``,
    ``benchmarks/results/rti_levenberg_marquardt.md``, tuning seeds 100-115): 0.01 on the
    Dubins vehicle, where the plain step of the split SSGP RTI alternates between turning left
    and right near ``v = 0`` and misses the goal on one seed; 0.01 reaches the goal on all 16
    seeds with every RTI recipe and cuts the rejected steps, 0.03 loses a nominal episode.
    Other systems: 0 (not measured).
    """
    name = model.name
    return SYSTEMS[name].planning if name in SYSTEMS else None


class RecedingHorizon:
    """Re-plan every ``replan_every`` periods over a fixed horizon (paper, Algorithm 1).

    The first ``replan_every`` periods of each plan are held (they are executed), the rest of
    the horizon is polynomial control on ``n_intervals`` LG intervals of ``n_nodes`` nodes.

    Args:
        horizon: seconds. n_nodes, n_intervals: the LG part. replan_every: ``p`` >= 1.
        held_nodes: LG nodes in each held period.
    """

    name = "receding"
    learns = True

    def __init__(self, horizon: float, n_nodes: int, n_intervals: int = 1,
                 replan_every: int = 1, held_nodes: int = 3) -> None:
        if int(replan_every) < 1:
            raise ValueError(f"replan_every must be >= 1, got {replan_every}")
        self.horizon = float(horizon)
        self.n_nodes, self.n_intervals = int(n_nodes), int(n_intervals)
        self.replan_every, self.held_nodes = int(replan_every), int(held_nodes)

    def mesh(self, dt: float) -> Mesh:
        """The receding mesh for control period ``dt`` (s)."""
        return Mesh.receding(self.horizon, dt, self.n_nodes, self.n_intervals,
                             held_periods=self.replan_every, held_nodes=self.held_nodes)

    def due(self, step: int, plan: Plan | None) -> bool:
        """Whether to plan at period ``step``."""
        return plan is None or step - plan.step >= self.replan_every


class Episodic:
    """Plan once over the whole task at the first ``act``, then execute it open loop.

    Args:
        duration: the task's duration (s). nodes_per_period: LG nodes per held period.
    """

    name = "episodic"
    learns = False

    def __init__(self, duration: float, nodes_per_period: int = 3) -> None:
        self.horizon, self.nodes_per_period = float(duration), int(nodes_per_period)

    def mesh(self, dt: float) -> Mesh:
        """Every period of the task held."""
        return Mesh.episodic(self.horizon, dt, self.nodes_per_period)

    def due(self, step: int, plan: Plan | None) -> bool:
        """Only the first period."""
        return plan is None
