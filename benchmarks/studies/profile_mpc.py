"""Where an MPC step's time goes: IPOPT iterations and time in each NLP function.

Run: ``OMP_NUM_THREADS=1 python -m benchmarks.studies.profile_mpc`` (under a minute). For every env
(default scenario, seed 0) it runs the nominal, oracle and SSGP MPC recipes of the benchmark
suite (:mod:`benchmarks.controllers`) for ``--steps`` closed-loop steps and records, per solve,
CasADi's statistics of the IPOPT call: iterations and the wall time spent evaluating the
objective, constraints, their Jacobian and the Lagrangian Hessian. What remains of the ``act``
time is IPOPT's own work (mostly the sparse KKT factorization) plus Python overhead (learning
update, warm start, parameter packing).

It answers one question about the SSGP-MPC's speed: is the learned model's extra cost in
evaluating the GP (more NLP function time per iteration) or in solving a harder NLP (more
iterations, denser KKT systems)? Writes ``benchmarks/results/profile/README.md``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import platform
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from benchmarks.controllers import ENVS, build_controller, make_env
from gp_agents.pseudospectral import GaussPseudospectralSolver

RESULTS = Path(__file__).resolve().parents[1] / "results" / "profile" / "README.md"
CONTROLLERS = ("nominal-mpc", "oracle-mpc", "ssgp-mpc", "ssgp-mpc-linearized",
               "ssgp-mpc-linearized-model-inputs")
FUNCTIONS = ("nlp_f", "nlp_grad_f", "nlp_g", "nlp_jac_g", "nlp_hess_l")
"""CasADi's names of the NLP functions IPOPT calls (objective, its gradient, constraints,
constraint Jacobian, Lagrangian Hessian)."""


class _StatsRecorder:
    """Wraps :meth:`GaussPseudospectralSolver.solve` to keep every solve's CasADi statistics."""

    def __init__(self) -> None:
        self.records: list[dict[str, Any]] = []
        self._original = GaussPseudospectralSolver.solve

    def __enter__(self) -> _StatsRecorder:
        original, records = self._original, self.records

        def solve(solver: GaussPseudospectralSolver, *args: Any, **kwargs: Any) -> Any:
            solution = original(solver, *args, **kwargs)
            records.append(dict(solution.stats))
            return solution

        GaussPseudospectralSolver.solve = solve  # type: ignore[method-assign]
        return self

    def __exit__(self, *exc: object) -> None:
        GaussPseudospectralSolver.solve = self._original  # type: ignore[method-assign]


def profile(env_name: str, controller: str, steps: int, seed: int = 0) -> dict[str, float]:
    """Medians over the solves of one closed-loop run.

    Returns:
        ``act_ms`` (median act time), ``iterations`` (median per solve), ``<fn>_ms`` (median
        per-solve wall time in each of :data:`FUNCTIONS`), ``functions_ms`` (their sum),
        ``per_iteration_ms`` (median of solve time / iterations), ``outside_ms`` (median of act
        time minus solve time: learning update, linearization, warm start), ``solves``.
    """
    env = make_env(env_name, ENVS[env_name].default_scenario)
    built = build_controller(controller, env, env_name, seed)
    agent, obs = built.agent, built.obs
    with _StatsRecorder() as rec:
        first_solves = 0
        for step in range(steps):
            action = agent.act(obs)
            if step == 0:  # the first act builds the NLP: left out of the profile
                first_solves = agent.counts.solves
            next_obs, _, terminated, truncated, _ = env.step(action)
            agent.observe(obs, action, next_obs)
            obs = next_obs
            if terminated or truncated:
                break
    diag = {k: v[1:] for k, v in agent.diagnostics_arrays().items()}
    stats = [s for s in rec.records[first_solves:] if "iter_count" in s]
    if not stats:
        raise RuntimeError(f"{controller} on {env_name}: no solver statistics recorded")
    out: dict[str, float] = {
        "act_ms": 1e3 * float(np.median(diag["act_time"])),
        "iterations": float(np.median([s["iter_count"] for s in stats])),
        "solves": float(len(stats)),
    }
    per_solve = np.array([[s.get(f"t_wall_{f}", 0.0) for f in FUNCTIONS] for s in stats])
    for f, col in zip(FUNCTIONS, per_solve.T, strict=True):
        out[f"{f}_ms"] = 1e3 * float(np.median(col))
    out["functions_ms"] = 1e3 * float(np.median(per_solve.sum(axis=1)))
    solve = diag["solve_time"][diag["replanned"]]
    iters = diag["iterations"][diag["replanned"]]
    ok = iters > 0
    out["per_iteration_ms"] = 1e3 * float(np.median(solve[ok] / iters[ok]))
    out["solve_ms"] = 1e3 * float(np.median(solve))
    out["outside_ms"] = 1e3 * float(np.median(diag["act_time"][diag["replanned"]] - solve))
    return out


def render(rows: Sequence[tuple[str, str, dict[str, float]]], steps: int) -> str:
    """The Markdown report."""
    head = ("| env | controller | act median (ms) | solve median (ms) | outside solver (ms) | "
            "iterations | "
            "per iteration (ms) | NLP functions (ms) | of which Hessian | Jacobian | "
            "constraints |")
    lines = [
        "# Where an MPC step's time goes",
        "",
        f"Command: `OMP_NUM_THREADS=1 python -m benchmarks.studies.profile_mpc --steps {steps}`  ",
        f"Python {platform.python_version()}, {platform.machine()}, {os.cpu_count()} CPU(s), "
        "one thread; each env's default scenario, seed 0; medians over the solves of one "
        "closed-loop run (the first solve, which builds the NLP, excluded). *NLP functions*: "
        "CasADi's wall time evaluating the objective, constraints, constraint Jacobian and "
        "Lagrangian Hessian inside one IPOPT call; the rest of the solve is IPOPT's own work "
        "(KKT factorization, line search). *Outside solver*: the rest of the `act` call (the "
        "learner's update with the last transition, the linearized recipes' GP evaluations, "
        "the warm start).",
        "",
        head,
        "|" + "---|" * 2 + "---:|" * 9,
    ]
    for env_name, controller, r in rows:
        lines.append(
            f"| {env_name} | {controller} | {r['act_ms']:.1f} | {r['solve_ms']:.1f} | "
            f"{r['outside_ms']:.1f} | "
            f"{r['iterations']:.0f} | {r['per_iteration_ms']:.2f} | {r['functions_ms']:.2f} | "
            f"{r['nlp_hess_l_ms']:.2f} | {r['nlp_jac_g_ms']:.2f} | {r['nlp_g_ms']:.2f} |")
    lines += ["", "Ratios SSGP recipe / nominal MPC (median act time; median iterations; median "
              "NLP function time per solve):", ""]
    by = {(e, c): r for e, c, r in rows}
    for env_name in dict.fromkeys(e for e, _, _ in rows):
        n = by.get((env_name, "nominal-mpc"))
        for c in (c for c in CONTROLLERS if c.startswith("ssgp")):
            s = by.get((env_name, c))
            if s is None or n is None:
                continue
            lines.append(
                f"- {env_name}, {c}: act {s['act_ms'] / n['act_ms']:.1f}x, iterations "
                f"{s['iterations'] / max(n['iterations'], 1):.1f}x, NLP functions "
                f"{s['functions_ms'] / max(n['functions_ms'], 1e-9):.1f}x")
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100, help="closed-loop steps per run")
    parser.add_argument("--envs", nargs="+", default=list(ENVS), choices=list(ENVS))
    args = parser.parse_args(argv)
    rows = []
    jobs = [(e, c) for e in args.envs for c in CONTROLLERS]
    for env_name, controller in tqdm(jobs, desc="profile", unit="run"):
        rows.append((env_name, controller, profile(env_name, controller, args.steps)))
    text = render(rows, args.steps)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(text)
    print(text)
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
