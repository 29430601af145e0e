"""Which QP solver the real-time iteration's step should use, per system (the ``qp_solver`` of
each system's :class:`gp_agents.mpc.tuning.RTITuning`).

The nominal MPC with ``scheme="rti"``, one agent per QP solver, all in lockstep on envs reset
with the same seed (so a change of the machine's load slows them alike), on tuning seeds
(default 100-102, disjoint from every preset's evaluation seeds): closed-loop cost, the steps
the safety net rejected (a failed or inaccurate QP: each costs a converged solve), the median
accepted RTI step and the 90th percentile of every replanning ``act`` (rejections included).
A median alone hides a solver that is fast on easy QPs and slow or failing on the hard ones.
Run (one core)::

    OMP_NUM_THREADS=1 python -m benchmarks.studies.rti_qp_solvers [--systems dubins] \
        [--seeds 100,101]

``--residual-tols 1e-9,1e-7`` runs every ``active-set:<plugin>`` solver once per value of its
``residual_tol`` (the linear solves' accuracy below which one refinement step, a second
factorization, follows; :class:`gp_agents.mpc.active_set.ActiveSetQP`).
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym
import numpy as np

import gp_envs
from gp_agents import RTI, PseudospectralMPC
from gp_agents.agent import rollout_lockstep
from gp_agents.mpc import StepStatus
from gp_agents.mpc.active_set import ActiveSetQP
from gp_agents.mpc.rti import ACTIVE_SET_PREFIX, QP_SOLVER_OPTIONS, resolve_qp_solver

SOLVERS = ("osqp", "proxqp", "qrqp", "piqp", "qpoases", "active-set:proxqp", "active-set:piqp",
           "active-set:qrqp")
"""CasADi conic plugins, and the active-set solve from the shifted plan's active set with one of
them as its fallback (:class:`gp_agents.mpc.active_set.ActiveSetQP`)."""
SCENARIOS = {"cartpole": "gp", "quadrotor": "gp", "dubins": "paper"}
"""Scenario per system (the peers' cart-pole scenario; others: the system's default)."""
TUNING_SEEDS = (100, 101, 102)


def main(argv: list[str] | None = None) -> None:
    """Print the Markdown table for the chosen systems (default: every registered one)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--systems", default=",".join(gp_envs.SYSTEMS),
                        help="comma-separated system names (default: all registered)")
    parser.add_argument("--seeds", default=",".join(map(str, TUNING_SEEDS)),
                        help="comma-separated env seeds (default: the tuning seeds 100-102)")
    parser.add_argument("--solvers", default=",".join(SOLVERS),
                        help=f"comma-separated CasADi QP plugins (default: {','.join(SOLVERS)})")
    parser.add_argument("--residual-tols", default="",
                        help="comma-separated residual_tol values for the active-set solvers "
                             "(default: the solver's own)")
    args = parser.parse_args(argv)
    names = [n for n in args.systems.split(",") if n]
    unknown = sorted(set(names) - set(gp_envs.SYSTEMS))
    if unknown or not names:
        parser.error(f"unknown or no system(s) {unknown}; registered: {list(gp_envs.SYSTEMS)}")
    try:
        seeds = [int(s) for s in args.seeds.split(",") if s]
    except ValueError:
        parser.error(f"--seeds must be comma-separated integers, got {args.seeds!r}")
    solvers = [s for s in args.solvers.split(",") if s]
    missing = []
    for s in solvers:
        try:
            resolve_qp_solver(s)
        except ValueError:
            missing.append(s)
    if missing or not solvers:
        parser.error(f"QP solver(s) not available in this CasADi: {missing}")
    try:
        tols = [float(t) for t in args.residual_tols.split(",") if t]
    except ValueError:
        parser.error(f"--residual-tols must be comma-separated numbers, got "
                     f"{args.residual_tols!r}")
    if any(not (np.isfinite(t) and t > 0) for t in tols):
        parser.error(f"--residual-tols must be > 0, got {tols}")
    variants: dict[str, str | ActiveSetQP] = {}
    for s in solvers:
        if s.startswith(ACTIVE_SET_PREFIX) and tols:
            fallback = s[len(ACTIVE_SET_PREFIX):]
            for t in tols:
                variants[f"{s}, residual_tol {t:g}"] = ActiveSetQP(
                    fallback, QP_SOLVER_OPTIONS.get(fallback, {}), residual_tol=t)
        else:
            variants[s] = s
    print(f"Seeds {', '.join(map(str, seeds))}; cost: mean over the seeds; steps pooled.\n")
    print("| env | QP solver | cost | rejected / RTI steps | QP fallbacks | median RTI step (ms) | "
          "p90 replanning act (ms) |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for name in names:
        system = gp_envs.SYSTEMS[name]
        env_id, scenario = system.env_id, SCENARIOS.get(name, system.default_scenario)
        rows = {qp: dict(cost=[], rejected=0, steps=0, fallbacks=0, rti=[], act=[])
                for qp in variants}
        for seed in seeds:
            pairs = []
            for solver in variants.values():
                env = gym.make(env_id, scenario=scenario)
                pairs.append((env, PseudospectralMPC.from_env(
                    env, scheme=RTI(qp_solver=solver))))
            for qp, (_, agent), ep in zip(variants, pairs, rollout_lockstep(pairs, seed),
                                          strict=True):
                d, row = agent.diagnostics_arrays(), rows[qp]
                row["cost"].append(ep.cost)
                row["rejected"] += agent.counts.rti_rejected
                row["steps"] += agent.counts.rti_steps
                row["fallbacks"] += agent.counts.qp_fallbacks
                row["rti"].extend(d["solve_time"][d["status"] == StepStatus.RTI])
                row["act"].extend(ep.act_times[1:])  # the first act builds the NLP
        for qp, row in rows.items():
            print(f"| {env_id} | {qp} | {np.mean(row['cost']):.3f} | "
                  f"{row['rejected']} / {row['steps']} | "
                  f"{row['fallbacks'] if qp.startswith(ACTIVE_SET_PREFIX) else '-'} | "
                  f"{1e3 * np.median(row['rti']):.2f} | "
                  f"{1e3 * np.quantile(row['act'], 0.9):.2f} |", flush=True)


if __name__ == "__main__":
    main()
