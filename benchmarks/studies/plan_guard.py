"""Does a plan-level nominal fallback, or the learner itself in the NLP instead of its
expansion, keep the robust recipe from ending below the nominal MPC on a truth outside its model
family, and what does each cost inside it? (issue: your env, your simulator; decision record
``docs/studies/plan_guard.md``).

``robust-mpc-guarded`` is the robust recipe with ``Converged(nominal_above=1)``
(:class:`gp_agents.mpc.guard.NominalGuardPlanner`): it plans with the nominal model beside the
learned one and acts on the nominal plan where the learned plan's linearization error exceeds
its tolerance. The threshold is the term's own tolerance (1), fixed before the evaluation
seeds were run; the tuning seeds 0-9 on the friction truth are where the mechanism was found.
``robust-mpc-exact`` is the robust recipe with ``term="exact"``: the learner itself in the NLP.
``robust-mpc-linearized`` is the robust recipe with ``term="linearized"`` on every env: as it
plans on the package's systems (the ``robust-mpc@converged`` rows there: its converged IPOPT
solve, the recipe's scheme on every system when this study ran), and as it planned on the
outside truths before this study (``make_mpc`` now plans there with the exact term).

Groups (each its own folder under ``benchmarks/results/plan-guard``, the CLI's trials):

- ``tuning``: DMC cart-pole with Coulomb friction, seeds 0-9 (the own-env tuning seeds);
- ``outside``: the same and DMC's plain swing-up, evaluation seeds 2000-2009 (the own-env
  preset's), 200 initial samples collected as a user does;
- ``outside-pendulum``: Gymnasium's Pendulum-v1 with the 60%-light nominal, seeds 2000-2009;
- ``cartpole``, ``quadrotor``, ``dubins``: the package's own systems, fixed and time-varying
  truth, the robustness preset's evaluation seeds 200-209.

Run: ``OMP_NUM_THREADS=1 python -m benchmarks.studies.plan_guard [--workers 2]`` (resumable:
finished trials are kept); writes ``benchmarks/results/plan-guard/tables.md``.
"""

from __future__ import annotations

import argparse
import math
from collections import defaultdict
from pathlib import Path

import numpy as np

from benchmarks.presets import custom_experiment
from benchmarks.report.stats import mean_ci
from benchmarks.studies.study_runs import read_metrics, run_and_record, success_text, write_tables
from benchmarks.trial import Cell, TrialSpec

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "benchmarks" / "results" / "plan-guard"
GUARDED = "robust-mpc-guarded"
EXACT = "robust-mpc-exact"
OUTSIDE_ENVS = ("dmc-cartpole", "pendulum-v1")
"""Envs whose reward is their own (the table shows the return; elsewhere the task's cost)."""

LINEARIZED = "robust-mpc-linearized"
_ALL = ("nominal-mpc", LINEARIZED, GUARDED, EXACT)
_PAIR = ("robust-mpc@converged", GUARDED, EXACT)
_OUTSIDE_PAIR = (LINEARIZED, GUARDED, EXACT)
GROUPS: dict[str, tuple[tuple[str, ...], str, tuple[str, ...] | None, range, Cell]] = {
    "tuning": (_ALL, "dmc-cartpole", ("swingup-friction",), range(0, 10), Cell(data="own")),
    "outside": (_ALL, "dmc-cartpole", ("swingup-friction", "swingup"), range(2000, 2010),
                Cell(data="own")),
    "outside-pendulum": (_OUTSIDE_PAIR, "pendulum-v1", None, range(2000, 2010), Cell(data="own")),
    "cartpole": (_PAIR, "cartpole", ("online", "online-wear"), range(200, 210), Cell()),
    "quadrotor": (_PAIR, "quadrotor", ("online", "online-payload"), range(200, 210), Cell()),
    "dubins": (_PAIR, "dubins", ("paper", "paper-wear"), range(200, 210), Cell()),
}
"""folder -> (controllers, env, scenarios (None: the default), seeds, cell)."""


def specs(group: str) -> list[TrialSpec]:
    """The trials of ``group`` exactly as the CLI's custom grid makes them."""
    controllers, env, scenarios, seeds, cell = GROUPS[group]
    exp = custom_experiment(list(controllers), [env], list(scenarios) if scenarios else None,
                            list(seeds), None, cell)
    return list(exp.specs)


def table(rows: dict[str, dict[str, dict[str, str]]]) -> str:
    """One row per (group, env, scenario, controller): success, the return (outside envs) or
    cost with its 95% interval and its worst seed, the steps without the learned residual, and
    the act median; ``rows``: each group's metrics by trial key (:func:`run_and_record`)."""
    lines = ["| group | env | scenario | controller | n | success | mean return or cost "
             "[95%] | worst seed | steps without the learned residual (mean) | act median "
             "(ms) |", "|---|---|---|---|---:|---|---:|---:|---:|---:|"]
    for group, metrics in rows.items():
        by: dict[tuple[str, str, str], list[dict[str, str]]] = defaultdict(list)
        for r in metrics.values():
            if r["status"] != "ok":
                continue
            by[(r["env"], r["scenario"], r["controller"])].append(r)
        for (env, scenario, controller), rows in sorted(by.items()):
            outside = env in OUTSIDE_ENVS
            values = np.array([float(r["return"] if outside else r["cost"]) for r in rows])
            k, n = sum(r["success"] == "True" for r in rows), len(rows)
            m_lo, m_hi = mean_ci(values)
            worst = values.min() if outside else values.max()
            off = [float(r["residual_off_steps"]) for r in rows]
            off_text = "-" if all(math.isnan(v) for v in off) else f"{np.nanmean(off):.1f}"
            act = float(np.median([float(r["act_median_ms"]) for r in rows]))
            kind = "return" if outside else "cost"
            lines.append(
                f"| {group} | {env} | `{scenario}` | `{controller}` | {n} | {success_text(k, n)} "
                f"| {kind} {values.mean():.2f} [{m_lo:.2f}, {m_hi:.2f}] | "
                f"{worst:.2f} | {off_text} | {act:.1f} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--groups", default=",".join(GROUPS),
                        help=f"comma-separated groups to run (default all: {', '.join(GROUPS)}); "
                             f"the table keeps the others' committed metrics")
    args = parser.parse_args(argv)
    groups = [g for g in args.groups.split(",") if g]
    for g in groups:
        if g not in GROUPS:
            parser.error(f"unknown group {g!r}; groups: {', '.join(GROUPS)}")
    rows = {g: run_and_record(specs(g), OUT / g, args.workers) if g in groups
            else read_metrics(OUT / g / "metrics.csv") for g in GROUPS
            if g in groups or (OUT / g / "metrics.csv").is_file()}  # the others as committed
    text = write_tables(OUT, "The plan-level nominal fallback and the exact term against the "
                        "robust recipe's linearized term",
                        "OMP_NUM_THREADS=1 python -m benchmarks.studies.plan_guard --workers 2",
                        table(rows))
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
