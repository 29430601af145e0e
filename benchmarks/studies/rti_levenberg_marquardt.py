"""Which Levenberg-Marquardt term the real-time iteration should use, per system (the
``levenberg_marquardt`` of each system's :class:`gp_agents.mpc.tuning.RTITuning`).

The RTI recipes (nominal and SSGP, one call and split into preparation and feedback) with
``levenberg_marquardt=mu`` for each ``mu`` given, on tuning seeds (default 100-115, disjoint
from every preset's evaluation seeds): episodes at the goal, the RTI steps the safety net
rejected (each costs a converged solve, and they dominate the median step where they are
frequent) and the closed-loop cost. Outcomes only: the machine's load changes no number here.

The rule that sets a system's ``levenberg_marquardt``: of the ``mu`` whose SSGP RTIs (one call
and split) each reach the goal on at least as many tuning seeds as at ``mu = 0`` with a mean
cost within 2% of theirs at ``mu = 0``, and whose reference RTI (nominal; the cart pole's
oracle) loses no seed either, the one with the fewest rejected SSGP RTI steps; ties: the
smaller ``mu``. ``--reference`` adds converged recipes (one episode per seed, no ``mu``) as
the outcome each RTI is measured against on the same seeds. Run (one core)::

    OMP_NUM_THREADS=1 python -m benchmarks.studies.rti_levenberg_marquardt [--system dubins] \\
        [--mu 0,0.003,0.01,0.03] [--seeds 100-115] [--reference robust-mpc] [--out FILE.md]
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Sequence
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
from tqdm import tqdm

import gp_envs
from benchmarks.cli import parse_seeds, print_report
from benchmarks.controllers import (
    CONTROLLERS,
    build_controller,
    check_env_scenario,
    make_env,
)
from benchmarks.studies.rti_qp_solvers import SCENARIOS
from benchmarks.studies.variants import RTI_VARIANTS
from gp_agents.agent import rollout

RECIPES = ("nominal-mpc-rti", "nominal-mpc-rti-split", "ssgp-mpc-rti", "ssgp-mpc-rti-split")
"""The RTI recipes compared (:data:`benchmarks.studies.variants.RTI_VARIANTS`)."""
MUS = (0.0, 0.003, 0.01, 0.03)
TUNING_SEEDS = tuple(range(100, 116))


def run(system: str, mus: list[float], seeds: list[int], recipes: list[str],
        progress: bool = True, scenario: str | None = None,
        references: Sequence[str] = ()) -> list[dict[str, object]]:
    """One episode per (recipe, mu, seed) on ``scenario`` (default: the system's
    :data:`~benchmarks.studies.rti_qp_solvers.SCENARIOS` entry), and one per (reference,
    seed) for the converged ``references`` (``mu`` None); returns one row per episode."""
    jobs = [(r, None, s) for r in references for s in seeds]
    jobs += [(r, mu, s) for r in recipes for mu in mus for s in seeds]
    return [dict(mu=mu, **rti_episode(
        system, recipe, seed, None if mu is None else {"levenberg_marquardt": mu}, scenario))
            for recipe, mu, seed in tqdm(jobs, disable=not progress, desc=f"{system} RTI mu")]


def rti_episode(system: str, recipe: str, seed: int,
                settings: dict[str, object] | None = None,
                scenario: str | None = None) -> dict[str, object]:
    """One episode of RTI recipe ``recipe`` on ``system``'s ``scenario`` (default its RTI
    scenario, :data:`~benchmarks.studies.rti_qp_solvers.SCENARIOS`) with env seed ``seed``
    (``settings``: extra :class:`gp_agents.PseudospectralMPC` settings): ``recipe``, ``seed``,
    ``success``, ``cost``, the RTI steps the safety net ``rejected`` of ``rti_steps`` (both 0
    for a converged recipe), and the steps with a constraint violation (``contacts``)."""
    env = make_env(system, scenario or SCENARIOS[system])
    built = build_controller(recipe, env, system, seed, settings=settings)
    episode = rollout(env, built.agent, seed)
    planner = built.agent.planner
    return dict(recipe=recipe, seed=seed, success=bool(episode.infos[-1]["success"]),
                cost=float(episode.cost), rejected=int(getattr(planner, "n_rti_rejected", 0)),
                rti_steps=int(getattr(planner, "n_rti_steps", 0)),
                contacts=int(sum(bool(i["constraint_violation"]) for i in episode.infos)))


def table(rows: list[dict[str, object]]) -> str:
    """The Markdown table: one row per (recipe, mu)."""
    lines = ["| recipe | mu | at the goal | rejected / RTI steps | episodes with a violation | "
             "mean cost | max cost | missed seeds |",
             "|---|---:|---:|---:|---:|---:|---:|---|"]
    keys = list(dict.fromkeys((r["recipe"], r["mu"]) for r in rows))
    for recipe, mu in keys:
        group = [r for r in rows if r["recipe"] == recipe and r["mu"] == mu]
        costs = np.array([r["cost"] for r in group], float)
        missed = [str(r["seed"]) for r in group if not r["success"]]
        mu_text = "-" if mu is None else format(mu, "g")
        lines.append(
            f"| {recipe} | {mu_text} | {sum(bool(r['success']) for r in group)}/{len(group)} | "
            f"{sum(int(r['rejected']) for r in group)} / "
            f"{sum(int(r['rti_steps']) for r in group)} | "
            f"{sum(int(r['contacts']) > 0 for r in group)} | {costs.mean():.2f} | "
            f"{costs.max():.2f} | {', '.join(missed) or '-'} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Print (and with ``--out`` write) the Markdown table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--system", default="dubins", help="a registered system name")
    parser.add_argument("--scenario", help="the env scenario (default: the system's RTI "
                        "scenario, benchmarks.studies.rti_qp_solvers.SCENARIOS)")
    parser.add_argument("--mu", default=",".join(f"{m:g}" for m in MUS),
                        help="comma-separated Levenberg-Marquardt terms, each >= 0")
    parser.add_argument("--seeds", type=parse_seeds,
                        default=f"{TUNING_SEEDS[0]}-{TUNING_SEEDS[-1]}",
                        help="env seeds, 'lo-hi' or comma-separated (default: tuning seeds)")
    parser.add_argument("--recipes", default=",".join(RECIPES),
                        help="comma-separated RTI recipes")
    parser.add_argument("--reference", default="",
                        help="comma-separated converged recipes run on the same seeds")
    parser.add_argument("--out", type=Path, help="also write the table (Markdown) here")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    if args.system not in gp_envs.SYSTEMS or args.system not in SCENARIOS:
        parser.error(f"unknown system {args.system!r}; choose from {sorted(SCENARIOS)}")
    try:
        mus = [float(m) for m in args.mu.split(",") if m]
    except ValueError as err:
        parser.error(f"--mu must be comma-separated numbers ({err})")
    seeds = args.seeds
    if not mus or not all(np.isfinite(m) and m >= 0 for m in mus):
        parser.error(f"--mu must be finite numbers >= 0, got {args.mu!r}")
    recipes = [r for r in args.recipes.split(",") if r]
    unknown = sorted(set(recipes) - set(RTI_VARIANTS))
    if unknown or not recipes or not seeds:
        parser.error(f"unknown or no recipe(s) {unknown} or no seeds; RTI recipes: "
                     f"{sorted(RTI_VARIANTS)}")
    references = [r for r in args.reference.split(",") if r]
    bad = sorted(r for r in references if r in RTI_VARIANTS or r not in CONTROLLERS
                 or CONTROLLERS[r].family != "mpc")
    if bad:
        parser.error(f"--reference takes converged MPC recipes, not {bad}")
    scenario = args.scenario or SCENARIOS[args.system]
    try:
        check_env_scenario(args.system, scenario)
    except ValueError as err:
        parser.error(str(err))
    rows = run(args.system, mus, seeds, recipes, progress=not args.no_progress,
               scenario=scenario, references=references)
    text = (f"# RTI Levenberg-Marquardt term, {args.system} `{scenario}`\n\n"
            f"`python -m benchmarks.studies.rti_levenberg_marquardt --system {args.system} "
            f"--scenario {scenario} --mu {args.mu} --seeds {','.join(map(str, seeds))} "
            f"--recipes {','.join(recipes)}"
            + (f" --reference {','.join(references)}" if references else "")
            + "` (tuning seeds; one episode per recipe, mu and "
            f"seed)\n\n{table(rows)}\n")
    print_report(text, args.out)


if __name__ == "__main__":
    main()
