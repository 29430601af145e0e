"""Benchmark of the Gauss pseudospectral core: solve time and iterations vs K and mesh intervals.

Run from the repository root::

    python benchmarks/studies/bench_pseudospectral.py [--repeats 5] [--quick]

Problems (paper section "Gauss Pseudospectral Optimal Control"; analytic optima from the tests):

* Hager: min 1/2 int_0^1 (u^2 + 2 y^2) dt, ydot = y/2 + u. Re-solved for y(0) = 1 -> 1.1
  (J* scales with y0^2).
* Brachistochrone, free final time, target (x, y) an NLP parameter: (10, 5) -> (10.5, 5); the
  optimum is the cycloid time.
* Bryson-Denham with the state limit x <= l as a parametric path constraint: l = 1/9 -> 1/8,
  J* = 4 / (9 l).
* Cart-pole swing-up OCP on the nominal model of ``gp_envs/CartPoleSwingUp-v0`` (scenario
  "online"), horizon 2 s, the env task's Q, R, Qf; re-solved one control period later from the
  state the nominal model reaches under the first solution's control at t0.

"cold" solves the re-solve problem from the default straight-line guess; "warm" from the first
solution (the analytic problems) or from the first solution shifted by one control period
(cart-pole). "warm+dual" additionally passes the previous multipliers with
``IPOPT_WARM_START_OPTIONS`` (analytic problems; their warm guess has the same structure).
"jit" rows use CasADi JIT compilation (build time includes compiling). Times are medians over
``--repeats`` solves of the same NLP; iterations are IPOPT's count. Nothing here is asserted.

Writes ``benchmarks/results/pseudospectral/bench_pseudospectral.{csv,md}``.
"""

from __future__ import annotations

import os

os.environ["OMP_NUM_THREADS"] = "1"  # before numpy / casadi are imported

import argparse
import csv
import platform
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
from scipy.optimize import brentq

from gp_agents.pseudospectral import (
    IPOPT_WARM_START_OPTIONS,
    GaussPseudospectralSolver,
    OCPSolution,
    OptimalControlProblem,
)

RESULTS_DIR = Path(__file__).resolve().parents[1] / "results" / "pseudospectral"
G = 9.80665


@dataclass
class Case:
    """One benchmark problem: how to build it, its nominal and re-solve inputs, its optimum."""

    name: str
    problem: Callable[[], OptimalControlProblem]
    first: dict[str, Any]  # solve() kwargs of the first (nominal) solve
    second: Callable[[OCPSolution], dict[str, Any]]  # solve() kwargs of the re-solve
    shift: float  # time shift of the warm guess (0: the first solution as is)
    exact: float | None  # optimal cost of the re-solve problem, if known
    grid: list[tuple[int, int]]  # (K, S) pairs


# --------------------------------------------------------------------------- problems


def hager() -> OptimalControlProblem:
    return OptimalControlProblem(
        n_states=1,
        n_controls=1,
        dynamics=lambda x, u: 0.5 * x + u,
        running_cost=lambda x, u: 0.5 * (u**2 + 2.0 * x**2),
        tf=1.0,
    )


def brachistochrone() -> OptimalControlProblem:
    return OptimalControlProblem(
        n_states=3,
        n_controls=1,
        n_params=2,
        dynamics=lambda x, u: ca.vertcat(
            x[2] * ca.sin(u[0]), -x[2] * ca.cos(u[0]), G * ca.cos(u[0])
        ),
        terminal_cost=lambda x0, xf, tf: tf,
        boundary_constraints=lambda x0, xf, tf, p: xf[:2] - p,
        tf=None,
        tf_bounds=(0.1, 10.0),
        tf_guess=2.0,
        u_lb=0.0,
        u_ub=np.pi,
    )


def cycloid_time(dx: float, dy: float) -> float:
    phi = brentq(lambda f: (f - np.sin(f)) / (1 - np.cos(f)) - dx / dy, 1e-3, 2 * np.pi - 1e-3)
    return float(phi * np.sqrt(dy / (1 - np.cos(phi)) / G))


def bryson_denham() -> OptimalControlProblem:
    return OptimalControlProblem(
        n_states=2,
        n_controls=1,
        n_params=1,
        dynamics=lambda x, u: ca.vertcat(x[1], u[0]),
        running_cost=lambda x, u: 0.5 * u[0] ** 2,
        path_constraints=lambda x, u, p: x[0] - p[0],  # x <= l, l a parameter
        x0=[0.0, 1.0],
        xf=[0.0, -1.0],
        tf=1.0,
    )


def cartpole_case(grid: list[tuple[int, int]]) -> Case | None:
    """The cart-pole swing-up OCP from the public gp_envs API (None if gp_envs is missing)."""
    try:
        import gymnasium as gym

        import gp_envs  # noqa: F401  (registers the envs)
    except ImportError:
        return None
    env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online")
    model = env.unwrapped.nominal_model
    obs, _ = env.reset(seed=0)
    env.close()
    x0 = np.asarray(obs, dtype=float)
    task = model.task
    goal = np.asarray(task.goal, dtype=float)
    Q, R, Qf = ca.DM(task.Q), ca.DM(task.R), ca.DM(task.Qf)

    def problem() -> OptimalControlProblem:
        return OptimalControlProblem(
            n_states=model.n_states,
            n_controls=model.n_controls,
            dynamics=model.casadi_function(),
            running_cost=lambda x, u: ca.bilin(Q, x - goal, x - goal) + ca.bilin(R, u, u),
            terminal_cost=lambda x0_, xf: ca.bilin(Qf, xf - goal, xf - goal),
            x_lb=model.x_lb,
            x_ub=model.x_ub,
            u_lb=model.u_lb,
            u_ub=model.u_ub,
            tf=2.0,
        )

    def second(first: OCPSolution) -> dict[str, Any]:
        x1 = model.step(x0, first.initial_control())
        return {"x0": x1}

    return Case(
        name="cartpole",
        problem=problem,
        first={"x0": x0},
        second=second,
        shift=float(model.dt),
        exact=None,
        grid=grid,
    )


def cases(quick: bool) -> list[Case]:
    ks = [4, 8, 16] if quick else [4, 8, 12, 16, 24, 32]
    out = [
        Case(
            "hager",
            hager,
            {"x0": [1.0]},
            lambda _: {"x0": [1.1]},
            0.0,
            1.21 * (np.exp(3) - 1) / (np.exp(3) + 2),
            [(k, 1) for k in ks] + [(8, 2), (8, 4)],
        ),
        Case(
            "brachistochrone",
            brachistochrone,
            {"p": [10.0, 5.0], "x0": [0.0, 10.0, 0.0]},
            lambda _: {"p": [10.5, 5.0], "x0": [0.0, 10.0, 0.0]},
            0.0,
            cycloid_time(10.5, 5.0),
            [(k, 1) for k in ks if k >= 8] + [(8, 2), (8, 4), (16, 4)],
        ),
        Case(
            "bryson_denham",
            bryson_denham,
            {"p": [1.0 / 9.0]},
            lambda _: {"p": [1.0 / 8.0]},
            0.0,
            4.0 / (9.0 * (1.0 / 8.0)),
            [(10, 1), (20, 1), (8, 3), (8, 4), (8, 8), (16, 8)]
            if not quick
            else [(10, 1), (8, 4), (8, 8)],
        ),
    ]
    cp = cartpole_case(
        [(10, 1), (20, 1), (30, 1), (10, 2), (10, 4), (15, 4)]
        if not quick
        else [(10, 1), (20, 1), (10, 4)]
    )
    if cp is None:
        print("gp_envs not importable: cart-pole rows skipped")
    else:
        out.append(cp)
    return out


# --------------------------------------------------------------------------- measurement


def timed_solves(
    solver: GaussPseudospectralSolver, kwargs: dict[str, Any], repeats: int
) -> tuple[OCPSolution, float]:
    """Solve ``repeats`` times with the same inputs; return the last solution and median time."""
    times, sol = [], None
    for _ in range(repeats):
        sol = solver.solve(**kwargs)
        times.append(sol.solve_time)
    assert sol is not None
    return sol, statistics.median(times)


def run_case(case: Case, K: int, S: int, repeats: int, jit: bool = False) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    variants: list[tuple[str, dict[str, Any] | None, bool]] = [
        ("cold", None, jit),
        ("warm", None, jit),
    ]
    if case.shift == 0.0 and not jit:
        variants.append(("warm+dual", IPOPT_WARM_START_OPTIONS, False))
    built: dict[tuple[bool, bool], tuple[GaussPseudospectralSolver, float, OCPSolution]] = {}
    for mode, opts, use_jit in variants:
        key = (opts is not None, use_jit)
        if key not in built:
            t = time.perf_counter()
            solver = GaussPseudospectralSolver(
                case.problem(), n_nodes=K, n_intervals=S, solver_options=opts, jit=use_jit
            )
            build = time.perf_counter() - t
            first = solver.solve(**case.first)
            built[key] = (solver, build, first)
        solver, build, first = built[key]
        kwargs = dict(case.second(first))
        if mode != "cold":
            kwargs["initial_guess"] = first.shift(case.shift) if case.shift > 0 else first
        sol, t_med = timed_solves(solver, kwargs, repeats)
        rows.append(
            {
                "problem": case.name,
                "K": K,
                "S": S,
                "n_var": solver.n_variables,
                "n_con": solver.n_constraints,
                "mode": mode + ("+jit" if use_jit else ""),
                "build_s": round(build, 4),
                "solve_ms": round(1e3 * t_med, 3),
                "iters": sol.iterations,
                "success": sol.success,
                "cost": sol.cost,
                "abs_err": abs(sol.cost - case.exact) if case.exact is not None else float("nan"),
            }
        )
    return rows


def fmt(v: Any) -> str:
    if isinstance(v, float):
        if np.isnan(v):
            return "-"
        return f"{v:.3e}" if (v != 0 and (abs(v) < 1e-2 or abs(v) >= 1e4)) else f"{v:.4g}"
    return str(v)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="solves per timing (median)")
    parser.add_argument("--quick", action="store_true", help="smaller grid")
    parser.add_argument("--no-jit", action="store_true", help="skip the JIT rows")
    args = parser.parse_args()

    rows: list[dict[str, Any]] = []
    for case in cases(args.quick):
        for K, S in case.grid:
            rows.extend(run_case(case, K, S, args.repeats))
        if case.name == "cartpole" and not args.no_jit:
            rows.extend(run_case(case, 20, 1, args.repeats, jit=True))

    header = list(rows[0].keys())
    widths = [max(len(h), *(len(fmt(r[h])) for r in rows)) for h in header]
    line = "  ".join(h.rjust(w) for h, w in zip(header, widths, strict=True))
    print(line)
    print("-" * len(line))
    for r in rows:
        print("  ".join(fmt(r[h]).rjust(w) for h, w in zip(header, widths, strict=True)))

    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    with open(RESULTS_DIR / "bench_pseudospectral.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=header)
        writer.writeheader()
        writer.writerows(rows)
    env = (
        f"python {platform.python_version()}, casadi {ca.__version__}, numpy {np.__version__}, "
        f"{platform.machine()}, OMP_NUM_THREADS=1, median of {args.repeats} solves"
    )
    with open(RESULTS_DIR / "bench_pseudospectral.md", "w") as fh:
        fh.write("# Gauss pseudospectral core: solve time and iterations\n\n")
        fh.write(f"Generated by `python benchmarks/studies/bench_pseudospectral.py`; {env}.\n")
        fh.write(
            "Modes: cold = default guess; warm = previous solution (cart-pole: shifted by one "
            "control period); warm+dual = also previous multipliers with "
            "IPOPT_WARM_START_OPTIONS; +jit = CasADi JIT (build_s includes compilation). "
            "abs_err = |J - J*| against the analytic optimum of the re-solved problem.\n\n"
        )
        fh.write("| " + " | ".join(header) + " |\n")
        fh.write("|" + "|".join("---" for _ in header) + "|\n")
        for r in rows:
            fh.write("| " + " | ".join(fmt(r[h]) for h in header) + " |\n")
    print(f"\nwrote {RESULTS_DIR / 'bench_pseudospectral.csv'} and .md")


if __name__ == "__main__":
    main()
