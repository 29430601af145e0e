"""Recovering rejected real-time-iteration steps inside the real-time scheme (issue 43, item 1).

Run (one core; resumable: finished episodes in ``results.jsonl`` are skipped)::

    OMP_NUM_THREADS=1 python -m benchmarks.studies.rti_recovery [--budgets 0,3]
        [--seeds 0-19] [--cells cartpole,cartpole-r0.1,...] [--controllers robust-mpc@rti-split]
        [--out benchmarks/results/rti_recovery]

Question: how many of the robust recipe's split-RTI steps (``make_mpc(env, "robust",
scheme="rti-split")``) does the safety net reject, and how many of those can further
iterations recover inside the real-time scheme (``RTI.recovery_iterations``: feasibility
projections while the point violates, SQP iterations from feasible points, the step recovered
by an SQP iteration within tolerance or the feasible projection of one; an iteration budget, no
wall-clock limit) before the converged fallback?

Each budget is set through the public per-system tuning (:func:`gp_agents.mpc.
register_rti_tuning`, the field ``recovery_iterations``, every recipe's entry of
``recipe_recovery_iterations`` cleared) in this process, and every episode is the benchmark
engine's own (:func:`benchmarks.trial.run_episode`, the controller ``robust-mpc@rti-split`` or
the RTI controllers given, and ``robust-mpc`` converged as each cell's reference). Tuning seeds
only (default 0-19); the robustness preset's evaluation seeds are 200-249.

The report (``report.md``) is generated from ``results.jsonl``: per cell and controller the
successes, the RTI steps taken, recovered and rejected, the rejected fraction, the largest
final position error and the median act time.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import sys
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_OUT = ROOT / "benchmarks" / "results" / "rti_recovery"
CELLS: dict[str, tuple[str, str, dict[str, Any]]] = {
    "cartpole": ("cartpole", "online", {}),
    "cartpole-r0.1": ("cartpole", "online", {"randomize": 0.1}),
    "cartpole-r0.1-ddiff": ("cartpole", "online", {"randomize": 0.1, "data": "diff"}),
    "cartpole-r0.1-down": ("cartpole", "online", {"randomize": 0.1, "data": "own"}),
    "cartpole-r0.2-ddiff": ("cartpole", "online", {"randomize": 0.2, "data": "diff"}),
    "quadrotor": ("quadrotor", "online", {}),
    "quadrotor-r0.1-ddiff": ("quadrotor", "online", {"randomize": 0.1, "data": "diff"}),
    "quadrotor-perturbed": ("quadrotor", "online", {"start": "perturbed"}),
    "dubins": ("dubins", "paper", {}),
    "dubins-wear": ("dubins", "paper-wear", {}),
}
"""Study cells: (env, scenario, :class:`benchmarks.trial.Cell` fields)."""
RTI_CONTROLLER, REFERENCE = "robust-mpc@rti-split", "robust-mpc"


def _seeds(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


def _key(cell: str, controller: str, budget: int | None, seed: int) -> str:
    return f"{cell}|{controller}|{'-' if budget is None else budget}|{seed}"


def run_one(cell: str, controller: str, budget: int | None, seed: int) -> dict[str, Any]:
    """One episode of the engine with the RTI's recovery budget ``budget`` on the cell's
    system (None: the converged reference)."""
    from benchmarks.trial import Cell, TrialSpec, run_episode
    from gp_agents.mpc.tuning import RTI_TUNING, register_rti_tuning, rti_tuning

    env, scenario, fields = CELLS[cell]
    if budget is not None:
        base = RTI_TUNING.get(env, rti_tuning(env))
        register_rti_tuning(env, dataclasses.replace(base, recovery_iterations=int(budget),
                                                     recipe_recovery_iterations={}))
    spec = TrialSpec("episode", env, scenario, controller, seed, cell=Cell(**fields))
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = run_episode(spec)["metrics"]
    keep = ("success", "cost", "final_position_error", "final_distance", "steps",
            "rti_steps", "rti_recovered", "rti_recovery_iterations", "rti_rejected",
            "solver_failures", "fallbacks", "act_median_ms", "act_p95_ms", "violations")
    return {"key": _key(cell, controller, budget, seed), "cell": cell, "env": env,
            "scenario": scenario, "controller": controller, "budget": budget, "seed": seed,
            **{k: _plain(m.get(k)) for k in keep}, "wall_s": time.perf_counter() - start}


def _plain(v: Any) -> Any:
    if isinstance(v, np.generic):
        return v.item()
    return v


def load(path: Path) -> list[dict[str, Any]]:
    if not path.exists():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def _fmt(v: Any, digits: int = 3) -> str:
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def summarize(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per (cell, controller, budget): counts summed over seeds."""
    groups: dict[tuple[str, str, Any], list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault((r["cell"], r["controller"], r["budget"]), []).append(r)
    out = []
    order = list(CELLS)
    for (cell, controller, budget), g in sorted(
            groups.items(), key=lambda kv: (order.index(kv[0][0]) if kv[0][0] in order else 99,
                                            kv[0][1] != REFERENCE, kv[0][2] or 0)):
        steps = sum(int(r["rti_steps"]) for r in g)
        rejected = sum(int(r["rti_rejected"]) for r in g)
        pos = [r["final_position_error"] for r in g
               if r["final_position_error"] is not None and np.isfinite(r["final_position_error"])]
        out.append({
            "cell": cell, "controller": controller, "budget": budget, "episodes": len(g),
            "success": sum(bool(r["success"]) for r in g),
            "seeds": f"{min(r['seed'] for r in g)}-{max(r['seed'] for r in g)}",
            "rti_steps": steps, "recovered": sum(int(r["rti_recovered"]) for r in g),
            "recovery_iterations": sum(int(r["rti_recovery_iterations"]) for r in g),
            "rejected": rejected,
            "rejected_pct": 100.0 * rejected / steps if steps else float("nan"),
            "worst_rejected_pct": max((100.0 * int(r["rti_rejected"]) / int(r["rti_steps"])
                                       for r in g if int(r["rti_steps"])), default=float("nan")),
            "final_pos_err_max": max(pos) if pos else float("nan"),
            "cost_mean": float(np.mean([r["cost"] for r in g])),
            "act_median_ms": float(np.median([r["act_median_ms"] for r in g])),
            "failed_seeds": ",".join(str(r["seed"]) for r in g if not r["success"]),
        })
    return out


def write_report(out: Path, rows: Sequence[dict[str, Any]], command: str) -> Path:
    table = summarize(rows)
    lines = ["# RTI recovery (issue 43, item 1)", "",
             "Generated by `benchmarks/studies/rti_recovery.py` from `results.jsonl`; every "
             "episode is the benchmark engine's (`benchmarks.trial.run_episode`). The RTI "
             "controllers (default "
             f"`{RTI_CONTROLLER}`) take `RTI.recovery_iterations` = *budget* (set "
             "through `register_rti_tuning`); the reference is the converged "
             f"`{REFERENCE}`. *recovered*: steps whose violation exceeded the tolerance and "
             "that the recovery made acceptable; *rejected*: steps replaced by a converged "
             "solve; *worst %*: the largest rejected fraction of one episode.", "",
             f"Command: `{command}`", "",
             f"Machine: {platform.machine()}, {os.cpu_count()} cores, Python "
             f"{platform.python_version()}, OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}",
             "",
             "| cell | controller | budget | seeds | success | RTI steps | recovered | "
             "recovery iters | rejected | rejected % | worst % | max final pos. err. | "
             "cost mean | act median (ms) | failed seeds |",
             "|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for r in table:
        rti = r["controller"] != REFERENCE
        lines.append(
            f"| {r['cell']} | {r['controller']} | {'-' if r['budget'] is None else r['budget']} "
            f"| {r['seeds']} | {r['success']}/{r['episodes']} "
            f"| {r['rti_steps'] if rti else '-'} | {r['recovered'] if rti else '-'} "
            f"| {r['recovery_iterations'] if rti else '-'} | {r['rejected'] if rti else '-'} "
            f"| {_fmt(r['rejected_pct'], 2) if rti else '-'} "
            f"| {_fmt(r['worst_rejected_pct'], 2) if rti else '-'} "
            f"| {_fmt(r['final_pos_err_max'])} | {_fmt(r['cost_mean'], 4)} "
            f"| {_fmt(r['act_median_ms'])} | {r['failed_seeds'] or '-'} |")
    path = out / "report.md"
    path.write_text("\n".join(lines) + "\n")
    (out / "summary.json").write_text(json.dumps(table, indent=1))
    return path


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--budgets", default="0,3", help="recovery budgets, comma-separated")
    parser.add_argument("--seeds", default="0-19", help="tuning seeds, e.g. 0-19 or 0,3,5")
    parser.add_argument("--cells", default=",".join(CELLS), help=f"of {list(CELLS)}")
    parser.add_argument("--controllers", default=RTI_CONTROLLER,
                        help="RTI controllers (benchmark names), comma-separated")
    parser.add_argument("--no-reference", action="store_true",
                        help="skip the converged reference episodes")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = parser.parse_args(argv)
    seeds = _seeds(args.seeds)
    if any(s >= 200 for s in seeds):
        parser.error("seeds >= 200 are the robustness preset's evaluation seeds: tune on others")
    budgets = [int(b) for b in args.budgets.split(",") if b != ""]
    cells = [c for c in args.cells.split(",") if c]
    unknown = sorted(set(cells) - set(CELLS))
    if unknown:
        parser.error(f"unknown cells {unknown}; known: {list(CELLS)}")
    from benchmarks.studies.variants import RTI_VARIANTS

    controllers = [c for c in args.controllers.split(",") if c]
    if not controllers or set(controllers) - set(RTI_VARIANTS):
        parser.error(f"--controllers takes RTI controllers, got {args.controllers!r}")
    args.out.mkdir(parents=True, exist_ok=True)
    results = args.out / "results.jsonl"
    done = {r["key"] for r in load(results)}
    jobs = [(c, r, b, s) for c in cells for r in controllers for b in budgets for s in seeds]
    if not args.no_reference:
        jobs += [(c, REFERENCE, None, s) for c in cells for s in seeds]
    todo = [j for j in jobs if _key(*j) not in done]
    print(f"{len(jobs)} episodes, {len(jobs) - len(todo)} done, {len(todo)} to run",
          flush=True)
    for i, job in enumerate(todo, 1):
        row = run_one(*job)
        with results.open("a") as fh:
            fh.write(json.dumps(row) + "\n")
        print(f"[{i}/{len(todo)}] {row['key']}: success={row['success']} "
              f"rti {row['rti_steps']}/{row['rti_recovered']}/{row['rti_rejected']} "
              f"({row['wall_s']:.1f} s)", flush=True)
    command = "OMP_NUM_THREADS=1 python -m benchmarks.studies.rti_recovery " + " ".join(
        sys.argv[1:] if argv is None else argv)
    print(f"report: {write_report(args.out, load(results), command.strip())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
