"""Where the zero-order learned term fails: the Dubins vehicle's true-to-nominal control gain.

:class:`~gp_agents.mpc.gp_zero_order.ZeroOrderGP` freezes the learned residual's *value* at
every node, so the real-time iteration's QP carries the nominal model's constraint Jacobian,
not the learned model's. An SQP step with an inexact Jacobian is a fixed-point iteration; for
a control that acts through a gain (true ``g``, the QP's ``g_nom``), a defect ``e`` in the
dynamics becomes ``(1 - g / g_nom) e`` after the step, which shrinks only while
``0 < g / g_nom < 2``: a model that believes the actuator more than twice as weak as it is
overshoots by more than the defect it corrects, and the iteration alternates instead of
settling. The adjoint correction of the gradient fixes where the iteration would stop, not
whether it gets there.

On the Dubins vehicle the learned residual is exactly the actuator loss, ``-b u`` (it acts
only through the controls; :mod:`gp_envs.physics.dubins`): per control, ``g_i = 1 - b_i`` (the
truth) and ``g_nom_i = 1 - b_nom_i`` (the reset's nominal draw, ``N(0.3, 0.3)`` clipped at
0.9). Per seed this tool reports ``rho = max_i g_i / g_nom_i`` and what the one-call SSGP RTI
did with the zero-order and the linearized term (the linearized QP has the learned model's
Jacobian): run here on the given seeds (default: the RTI tuning seeds 100-115), and/or read
from a report's ``metrics.csv`` (``--metrics``, e.g. the ``rti`` preset's evaluation seeds).
Outcomes only: the machine's load changes no number here. Run (one core)::

    OMP_NUM_THREADS=1 python -m benchmarks.studies.rti_zero_order [--seeds 100-115] \\
        [--metrics rti-before-recovery.csv] [--out FILE.md]

The ``rti`` preset's run before the RTI recovery, which the decision record reads, is in the
git history: ``git show 7d41892:benchmarks/results/archive/rti-before-recovery/metrics.csv``.
"""

from __future__ import annotations

import argparse
import csv
import os
from collections.abc import Iterable
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

from tqdm import tqdm

import gp_envs
from benchmarks.cli import parse_seeds, print_report
from benchmarks.controllers import make_env
from benchmarks.studies.rti_levenberg_marquardt import TUNING_SEEDS, rti_episode

__all__ = ["RECIPES", "STABLE_RATIO", "gain_ratio", "metrics_rows", "run", "tables"]

RECIPES = ("ssgp-mpc-rti-zero-order", "ssgp-mpc-rti")
"""The one-call SSGP RTI with the zero-order and with the linearized learned term."""
STABLE_RATIO = 2.0
"""The iteration with the nominal Jacobian contracts for a gain ratio below this."""


def gain_ratio(seed: int) -> dict[str, float]:
    """The Dubins ``paper`` episode of env seed ``seed``: nominal and true loss factors and
    ``rho = max_i (1 - b_i) / (1 - b_nom_i)`` (dimensionless)."""
    env = make_env("dubins", "paper")
    env.reset(seed=seed)
    nominal = env.unwrapped.nominal_model.params
    truth = gp_envs.oracle_model(env).params
    rho = max((1.0 - truth[k]) / (1.0 - nominal[k]) for k in ("b1", "b2"))
    env.close()
    return dict(b1_nominal=float(nominal["b1"]), b2_nominal=float(nominal["b2"]),
                b1_true=float(truth["b1"]), b2_true=float(truth["b2"]), rho=float(rho))


def run(seeds: Iterable[int], recipes: Iterable[str] = RECIPES,
        progress: bool = True) -> list[dict[str, object]]:
    """One episode per (recipe, seed) on the Dubins vehicle (system defaults); one row each
    (:func:`benchmarks.studies.rti_levenberg_marquardt.rti_episode`) with ``source="run"``."""
    jobs = [(r, s) for r in recipes for s in seeds]
    return [dict(source="run", **rti_episode("dubins", recipe, seed))
            for recipe, seed in tqdm(jobs, disable=not progress, desc="dubins zero-order")]


def metrics_rows(path: Path, recipes: Iterable[str] = RECIPES) -> list[dict[str, object]]:
    """The Dubins episodes of ``recipes`` in a report's ``metrics.csv``, as :func:`run`'s rows
    (``contacts``: the episode's violation steps) with ``source`` the file.

    Raises:
        FileNotFoundError: no such file.
        ValueError: it has none of these episodes.
    """
    recipes = set(recipes)
    with open(path, newline="") as fh:
        rows = [dict(source=str(path), recipe=r["controller"], seed=int(r["seed"]),
                     success=r["success"] == "True", cost=float(r["cost"]),
                     contacts=int(float(r["violations"])))
                for r in csv.DictReader(fh)
                if r["env"] == "dubins" and r["controller"] in recipes and r["status"] == "ok"]
    if not rows:
        raise ValueError(f"{path} has no Dubins episodes of {sorted(recipes)}")
    return rows


def tables(rows: list[dict[str, object]], recipes: Iterable[str] = RECIPES) -> str:
    """Markdown: episodes at the goal / with an obstacle contact per recipe and ratio band,
    then one row per (source, seed) sorted by ``rho``."""
    recipes = list(recipes)
    ratios = {s: gain_ratio(s) for s in sorted({int(r["seed"]) for r in rows})}
    sources = list(dict.fromkeys(str(r["source"]) for r in rows))
    by_key = {(str(r["source"]), int(r["seed"]), str(r["recipe"])): r for r in rows}
    lines = ["| seeds from | rho band | seeds | "
             + " | ".join(f"{c}: at the goal / contact" for c in recipes) + " |",
             "|---|---|---:|" + "---:|" * len(recipes)]
    for source in sources:
        for band, test in ((f"< {STABLE_RATIO:g}", lambda x: x < STABLE_RATIO),
                           (f">= {STABLE_RATIO:g}", lambda x: x >= STABLE_RATIO)):
            seeds = [s for s in ratios if test(ratios[s]["rho"])
                     and any((source, s, c) in by_key for c in recipes)]
            cells = []
            for c in recipes:
                group = [by_key[(source, s, c)] for s in seeds if (source, s, c) in by_key]
                cells.append(f"{sum(bool(r['success']) for r in group)}/{len(group)} / "
                             f"{sum(int(r['contacts']) > 0 for r in group)}")
            lines.append(f"| {source} | {band} | {len(seeds)} | " + " | ".join(cells) + " |")
    lines += ["", "| seeds from | seed | b1 nominal | b2 nominal | rho | "
              + " | ".join(f"{c}: goal, cost" for c in recipes) + " |",
              "|---|---:|---:|---:|---:|" + "---|" * len(recipes)]
    keys = sorted({(str(r["source"]), int(r["seed"])) for r in rows},
                  key=lambda k: (sources.index(k[0]), ratios[k[1]]["rho"], k[1]))
    for source, seed in keys:
        q = ratios[seed]
        cells = []
        for c in recipes:
            r = by_key.get((source, seed, c))
            cells.append("-" if r is None else
                         f"{'yes' if r['success'] else 'NO'}{' (contact)' if r['contacts'] else ''}"
                         f", {float(r['cost']):.1f}")
        lines.append(f"| {source} | {seed} | {q['b1_nominal']:.3f} | {q['b2_nominal']:.3f} | "
                     f"{q['rho']:.2f} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Print (and with ``--out`` write) the Markdown tables."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=lambda t: [] if t == "none" else parse_seeds(t),
                        default=f"{TUNING_SEEDS[0]}-{TUNING_SEEDS[-1]}",
                        help="env seeds to run, 'lo-hi' or comma-separated (default: the RTI "
                             "tuning seeds); 'none' runs nothing")
    parser.add_argument("--metrics", type=Path, action="append", default=[],
                        help="also read the recipes' Dubins episodes from this metrics.csv "
                             "(repeatable)")
    parser.add_argument("--out", type=Path, help="also write the tables (Markdown) here")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    rows: list[dict[str, object]] = []
    try:
        for path in args.metrics:
            rows += metrics_rows(path)
    except (OSError, ValueError, KeyError) as err:
        parser.error(f"--metrics: {err}")
    if args.seeds:
        rows += run(args.seeds, progress=not args.no_progress)
    if not rows:
        parser.error("nothing to report: give --seeds or --metrics")
    command = "python -m benchmarks.studies.rti_zero_order --seeds " + (
        ",".join(map(str, args.seeds)) or "none") + "".join(f" --metrics {p}" for p in args.metrics)
    text = (f"# The zero-order learned term's RTI against the true-to-nominal control gain, "
            f"Dubins\n\n`{command}` (run: one episode per recipe and seed, system defaults; "
            f"metrics: episodes of that report, not re-run). rho = max over the two controls "
            f"of (1 - b_true) / (1 - b_nominal): the true control gain over the one in the "
            f"zero-order QP (see the module docstring for why {STABLE_RATIO:g} is the "
            f"threshold).\n\n{tables(rows)}\n")
    print_report(text, args.out)


if __name__ == "__main__":
    main()
