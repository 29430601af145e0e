"""Which QP solver the real-time iteration's step should use, per system (``RTI_QP_SOLVER``).

The nominal MPC with ``scheme="rti"``, one agent per QP solver, all in lockstep on envs reset
with the same seed (so a change of the machine's load slows them alike): closed-loop cost,
rejected steps and the median RTI step. Run (one core)::

    OMP_NUM_THREADS=1 python -m benchmarks.rti_qp_solvers
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym
import numpy as np

import gp_envs  # noqa: F401  (registers the envs)
from gp_agents import PseudospectralMPC
from gp_agents.agent import rollout_lockstep

SOLVERS = ("osqp", "proxqp", "qrqp")
ENVS = (("gp_envs/CartPoleSwingUp-v0", "gp"), ("gp_envs/Quadrotor-v0", "gp"),
        ("gp_envs/DubinsObstacle-v0", "paper"))


def main() -> None:
    print("| env | QP solver | cost | rejected steps | median RTI step (ms) |")
    print("|---|---|---:|---:|---:|")
    for env_id, scenario in ENVS:
        pairs = []
        for qp in SOLVERS:
            env = gym.make(env_id, scenario=scenario)
            pairs.append((env, PseudospectralMPC.from_env(env, scheme="rti", qp_solver=qp)))
        for qp, (_, agent), ep in zip(SOLVERS, pairs, rollout_lockstep(pairs, 0), strict=True):
            d = agent.diagnostics_arrays()
            step = d["solve_time"][d["status"] == "RTI"]
            print(f"| {env_id} | {qp} | {ep.cost:.3f} | {agent.planner.n_rti_rejected} | "
                  f"{1e3 * np.median(step):.2f} |", flush=True)


if __name__ == "__main__":
    main()
