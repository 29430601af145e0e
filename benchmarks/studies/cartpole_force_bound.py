"""Smallest force bound for which a cart-pole swing-up exists, true vs nominal model.

For each scenario and each swing-up time ``T``, bisect on ``f_max``: is there a control with
``|f| <= f_max`` that takes the cart pole from hanging at rest at the centre to upright at rest at
the centre in ``T`` seconds, with the cart on the track (``|x| <= 2.5`` m)? Each check is a Gauss
pseudospectral feasibility solve (minimum control energy, several cold starts). The smallest
feasible bound of the *true* model justifies the env's force bound; the nominal model's shows
how much the missing damping makes a controller underestimate the force it needs.

Run: ``OMP_NUM_THREADS=1 python benchmarks/studies/cartpole_force_bound.py``
Writes ``benchmarks/results/cartpole_force_bound.md``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import numpy as np
from tqdm import tqdm

import gp_envs
from gp_agents.pseudospectral import (
    GaussPseudospectralSolver,
    InitialGuess,
    OptimalControlProblem,
)
from gp_envs.model import ControlModel

RESULTS = Path(__file__).resolve().parents[1] / "results" / "cartpole_force_bound.md"


def feasible(model: ControlModel, f_max: float, duration: float, n_intervals: int = 8,
             n_nodes: int = 8) -> bool:
    """True if a swing-up in ``duration`` seconds with ``|f| <= f_max`` was found."""
    f = model.casadi_function()
    problem = OptimalControlProblem(
        n_states=4, n_controls=1, dynamics=lambda x, u: f(x, u),
        running_cost=lambda x, u: 1e-3 * u[0] ** 2, t0=0.0, tf=duration,
        x_lb=[-2.5, -np.inf, -10, -25], x_ub=[2.5, np.inf, 10, 25], u_lb=-f_max, u_ub=f_max,
        x0=np.zeros(4),
        xf_lb=[0.0, np.pi, 0.0, 0.0], xf_ub=[0.0, np.pi, 0.0, 0.0])
    solver = GaussPseudospectralSolver(problem, n_nodes=n_nodes, n_intervals=n_intervals,
                                       solver_options={"ipopt": {"max_iter": 1500}})
    # several cold starts: pumping with 1..4 swings
    t = np.linspace(0, duration, 50)
    for swings in (1, 2, 3, 4):
        theta = np.pi * t / duration * (1 + 0.0 * swings)
        pump = np.sin(2 * np.pi * swings * t / duration)
        x = np.column_stack([0.3 * pump, theta, np.gradient(0.3 * pump, t),
                             np.gradient(theta, t)])
        guess = InitialGuess(t=t, x=x, t_u=t, u=(0.5 * f_max * pump)[:, None])
        if solver.solve(initial_guess=guess).success:
            return True
    return False


def min_force(model: ControlModel, duration: float, lo: float = 1.0, hi: float = 80.0,
              tol: float = 0.5) -> float:
    """Bisection for the smallest feasible bound in [lo, hi] (inf if hi is infeasible)."""
    if not feasible(model, hi, duration):
        return np.inf
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if feasible(model, mid, duration):
            hi = mid
        else:
            lo = mid
    return hi


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--durations", type=float, nargs="+", default=[2.0, 3.0, 4.0, 5.0])
    args = parser.parse_args()
    rows = []
    jobs = [(s, d) for s in ("gp", "online") for d in args.durations]
    for scenario, duration in tqdm(jobs, desc="bisections"):
        env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario=scenario)
        env.reset(seed=0)
        truth = gp_envs.oracle_model(env)
        nominal = env.unwrapped.nominal_model
        bound = float(env.action_space.high[0])
        rows.append((scenario, duration, min_force(truth, duration),
                     min_force(nominal, duration), bound))
        print(rows[-1])
    lines = [
        "# Cart-pole swing-up: smallest feasible force bound",
        "",
        "Command: `OMP_NUM_THREADS=1 python benchmarks/studies/cartpole_force_bound.py`  ",
        "Swing-up from hanging at rest at the centre to upright at rest at the centre in T "
        "seconds with |x| <= 2.5 m; bisection to 0.5 N on a Gauss pseudospectral feasibility "
        "solve (8 intervals x 8 LG nodes, minimum control energy, 4 cold starts). "
        "'inf' means infeasible up to 80 N.",
        "",
        "| scenario | T (s) | min f_max, true model (N) | min f_max, nominal model (N) "
        "| env bound (N) |",
        "|---|---:|---:|---:|---:|",
        *[f"| {s} | {d:.1f} | {t:.1f} | {n:.1f} | {b:.0f} |" for s, d, t, n, b in rows],
        "",
    ]
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text("\n".join(lines))
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
