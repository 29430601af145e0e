"""Which QP solver the real-time iteration's step should use, per system (the ``qp_solver`` of
each system's :class:`gp_envs.systems.PlanningDefaults`).

The nominal MPC with ``scheme="rti"``, one agent per QP solver, all in lockstep on envs reset
with the same seed (so a change of the machine's load slows them alike): closed-loop cost,
rejected steps and the median RTI step. Run (one core)::

    OMP_NUM_THREADS=1 python -m benchmarks.rti_qp_solvers [--systems cartpole,dubins]
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym
import numpy as np

import gp_envs
from gp_agents import PseudospectralMPC
from gp_agents.agent import rollout_lockstep

SOLVERS = ("osqp", "proxqp", "qrqp")
SCENARIOS = {"cartpole": "gp", "quadrotor": "gp", "dubins": "paper"}
"""Scenario per system (the peers' cart-pole scenario; others: the system's default)."""


def main(argv: list[str] | None = None) -> None:
    """Print the Markdown table for the chosen systems (default: every registered one)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--systems", default=",".join(gp_envs.SYSTEMS),
                        help="comma-separated system names (default: all registered)")
    args = parser.parse_args(argv)
    names = [n for n in args.systems.split(",") if n]
    unknown = sorted(set(names) - set(gp_envs.SYSTEMS))
    if unknown or not names:
        parser.error(f"unknown or no system(s) {unknown}; registered: {list(gp_envs.SYSTEMS)}")
    print("| env | QP solver | cost | rejected steps | median RTI step (ms) |")
    print("|---|---|---:|---:|---:|")
    for name in names:
        system = gp_envs.SYSTEMS[name]
        env_id, scenario = system.env_id, SCENARIOS.get(name, system.default_scenario)
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
