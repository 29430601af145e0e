"""Which learned term the SSGP real-time iteration should use, per system (the
``learned_term`` of each system's :class:`gp_agents.mpc.tuning.RTITuning`).

The split RTI (``scheme="rti-split"``) of a reference MPC (the nominal one; on the cart pole,
whose nominal RTI steps are all rejected because its model cannot swing the pole up, the oracle
MPC: the same OCP with the true model) and of the SSGP-MPC with the GP linearized per node
(``learned_dynamics="linearized"``: its full Jacobian in the QP) and with the GP linearized on
the nominal model's Jacobian pattern only (``"linearized-pattern"``: the nominal QP's sparsity,
the dropped derivatives adjoint-corrected), the three agents in lockstep
on envs reset with the same seed (so a change of the machine's load slows them alike), on
tuning seeds (default 100-109, the Dubins vehicle 100-115; disjoint from every preset's
evaluation seeds). Per system and scenario: episodes at the goal, the mean closed-loop cost,
and the latency (``act`` time minus the preparation done after the action, over the
replanning steps after the first) as its median per episode divided by the reference split
RTI's in the same episode: the median of these per-seed ratios and their range. Outcomes do
not depend on the machine's load; the ratios do, a little.

The rule that sets ``rti_learned_dynamics``: the full linearization (the exact Gauss-Newton
step) unless the pattern term, in every scenario of the system, reaches the goal on at least as
many tuning seeds and has the lower latency on at least 80% of the seeds, each paired with the
full linearization's episode run in lockstep with it (a paired count, which a change of the
machine's load does not tip the way it moves a ratio near a threshold); then the pattern term.
Run (one core)::

    OMP_NUM_THREADS=1 python -m benchmarks.studies.rti_learned_term [--systems quadrotor] \\
        [--seeds 100-109] [--dubins-seeds 100-115] [--compare RECIPE-split,...] [--out FILE.md]

``--compare`` runs further split-RTI recipes in the same lockstep (their rows take no part in
the rule).
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
from tqdm import tqdm

from benchmarks.cli import parse_seeds, print_report
from benchmarks.controllers import CONTROLLERS, build_controller, make_env
from gp_agents.agent import rollout_lockstep

__all__ = ["CASES", "RECIPES", "REFERENCES", "episode_latency", "recipes", "run", "table"]

RECIPES = ("nominal-mpc-rti-split", "ssgp-mpc-rti-linearized-split",
           "ssgp-mpc-rti-pattern-split")
"""The reference (first) and the two linearized learned terms, all split RTIs."""
REFERENCES = {"cartpole": "oracle-mpc-rti-split"}
"""The reference split RTI where it is not the nominal one (the cart pole's nominal RTI steps
are all rejected: its latency would be a converged solve's)."""


def recipes(system: str) -> tuple[str, ...]:
    """:data:`RECIPES` with ``system``'s reference (:data:`REFERENCES`) first."""
    return (REFERENCES.get(system, RECIPES[0]), *RECIPES[1:])
CASES = {"cartpole": ("online",), "quadrotor": ("gp", "online"), "dubins": ("paper",)}
"""Scenarios per system: those of the ``rti`` preset."""
TUNING_SEEDS = tuple(range(100, 110))
DUBINS_TUNING_SEEDS = tuple(range(100, 116))


def episode_latency(diagnostics: dict[str, np.ndarray]) -> float:
    """Median latency (s) of one split-RTI episode: ``act_time - preparation_time`` over the
    replanning steps after the first (which builds the NLP and solves to convergence).

    Raises:
        ValueError: the diagnostics have no preparation times (not a split RTI) or no
            replanning step after the first.
    """
    if "preparation_time" not in diagnostics:
        raise ValueError("the diagnostics have no preparation_time: not a split RTI")
    replanned = diagnostics["replanned"].astype(bool).copy()
    first = np.flatnonzero(replanned)
    if first.size < 2:
        raise ValueError("an episode with fewer than two replanning steps has no latency")
    replanned[first[0]] = False
    latency = (diagnostics["act_time"] - diagnostics["preparation_time"])[replanned]
    return float(np.median(latency))


def run(system: str, scenario: str, seeds: Iterable[int], recipes: Sequence[str] = RECIPES,
        progress: bool = True) -> list[dict[str, object]]:
    """One lockstep episode of every recipe per seed; one row per (recipe, seed) with
    ``success``, ``cost`` and ``latency`` (s; :func:`episode_latency`)."""
    rows: list[dict[str, object]] = []
    for seed in tqdm(list(seeds), disable=not progress, desc=f"{system} {scenario}"):
        pairs = []
        for recipe in recipes:
            env = make_env(system, scenario)
            pairs.append((env, build_controller(recipe, env, system, seed).agent))
        for recipe, (env, agent), ep in zip(recipes, pairs, rollout_lockstep(pairs, seed),
                                            strict=True):
            rows.append(dict(system=system, scenario=scenario, recipe=recipe, seed=seed,
                             success=bool(ep.infos[-1]["success"]), cost=float(ep.cost),
                             latency=episode_latency(agent.diagnostics_arrays())))
            env.close()
    return rows


def table(rows: list[dict[str, object]], reference: str | None = None) -> str:
    """Markdown: one row per (system, scenario, recipe); latency ratios against the
    reference's episode of the same seed (``reference``, default each system's first recipe
    of :func:`recipes`)."""
    lines = ["| system | scenario | recipe | at the goal | mean cost | median latency (ms) | "
             "latency / the reference split RTI's (-), median over seeds [min, max] | "
             f"seeds with a lower latency than {RECIPES[1]} |",
             "|---|---|---|---:|---:|---:|---|---:|"]

    def ref_of(system: object) -> str:
        return reference if reference is not None else recipes(str(system))[0]

    ref = {(r["system"], r["scenario"], r["seed"]): float(r["latency"])
           for r in rows if r["recipe"] == ref_of(r["system"])}
    full = {(r["system"], r["scenario"], r["seed"]): float(r["latency"])
            for r in rows if r["recipe"] == RECIPES[1]}
    for key in dict.fromkeys((r["system"], r["scenario"], r["recipe"]) for r in rows):
        group = [r for r in rows if (r["system"], r["scenario"], r["recipe"]) == key]
        latency = np.array([float(r["latency"]) for r in group])
        ratios = np.array([float(r["latency"]) / ref[(r["system"], r["scenario"], r["seed"])]
                           for r in group if (r["system"], r["scenario"], r["seed"]) in ref])
        ratio = ("-" if key[2] == ref_of(key[0]) or not ratios.size else
                 f"{np.median(ratios):.2f}x [{ratios.min():.2f}, {ratios.max():.2f}]")
        paired = [float(r["latency"]) < full[(r["system"], r["scenario"], r["seed"])]
                  for r in group if (r["system"], r["scenario"], r["seed"]) in full]
        wins = ("-" if key[2] == RECIPES[1] or not paired else
                f"{sum(paired)}/{len(paired)}")
        lines.append(f"| {key[0]} | `{key[1]}` | {key[2]} | "
                     f"{sum(bool(r['success']) for r in group)}/{len(group)} | "
                     f"{np.mean([float(r['cost']) for r in group]):.2f} | "
                     f"{1e3 * np.median(latency):.2f} | {ratio} | {wins} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Print (and with ``--out`` write) the Markdown table."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--systems", default=",".join(CASES),
                        help=f"comma-separated systems (default: {','.join(CASES)})")
    parser.add_argument("--seeds", type=parse_seeds,
                        default=f"{TUNING_SEEDS[0]}-{TUNING_SEEDS[-1]}",
                        help="env seeds of the cart pole and quadrotor, 'lo-hi' or "
                             "comma-separated (default: tuning seeds 100-109)")
    parser.add_argument("--dubins-seeds", type=parse_seeds,
                        default=f"{DUBINS_TUNING_SEEDS[0]}-{DUBINS_TUNING_SEEDS[-1]}",
                        help="env seeds of the Dubins vehicle (default: 100-115)")
    parser.add_argument("--compare", default="",
                        help="comma-separated further split-RTI recipes run in the same "
                             "lockstep (e.g. ssgp-mpc-rti-parametric-split)")
    parser.add_argument("--out", type=Path, help="also write the table (Markdown) here")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    systems = [s for s in args.systems.split(",") if s]
    compare = [c for c in args.compare.split(",") if c]
    for c in compare:
        if c not in CONTROLLERS or not c.endswith("-split"):
            parser.error(f"--compare takes split-RTI recipes (names ending in -split), got {c!r}")
    unknown = sorted(set(systems) - set(CASES))
    if unknown or not systems:
        parser.error(f"unknown or no system(s) {unknown}; choose from {list(CASES)}")
    rows: list[dict[str, object]] = []
    for system in systems:
        seeds = args.dubins_seeds if system == "dubins" else args.seeds
        for scenario in CASES[system]:
            rows += run(system, scenario, seeds, (*recipes(system), *compare),
                        progress=not args.no_progress)
    command = ("python -m benchmarks.studies.rti_learned_term "
               f"--systems {','.join(systems)} --seeds "
               f"{','.join(map(str, args.seeds))} --dubins-seeds "
               f"{','.join(map(str, args.dubins_seeds))}"
               + (f" --compare {','.join(compare)}" if compare else ""))
    text = (f"# The SSGP RTI's learned term: full linearization vs the nominal Jacobian "
            f"pattern\n\n`OMP_NUM_THREADS=1 {command}` (tuning seeds; one lockstep episode of "
            f"each recipe per seed, system defaults otherwise). Latency: `act` time minus the "
            f"preparation after the action, median over an episode's replanning steps after "
            f"the first; the ratio is per seed against the reference split RTI's episode (the "
            f"nominal's; the cart pole: the oracle's) run in "
            f"lockstep with it.\n\n{table(rows)}\n")
    print_report(text, args.out)


if __name__ == "__main__":
    main()
