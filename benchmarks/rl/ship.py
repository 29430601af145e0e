"""Ship one seed of a finished multi-seed RL plan as the package's baseline policy.

The RL rows of every benchmark load ``benchmarks/models/<env>/<algo>/``. This copies one seed's
final model of a plan (:data:`benchmarks.rl.runs.PLANS`) there, chosen on the
*training-evaluation* reset seeds only (1000..1019 of each seed's ``learning_curve.csv``,
disjoint from the final evaluation's 0..19 and from every benchmark's episode seeds): the seed
whose last training evaluation has the lowest mean cost, which gives RL its strongest final
policy without looking at the seeds it is judged on. No checkpoint is picked: it is the
plan's final policy of that seed. Its ``metadata.json`` gains ``shipped_from`` (plan, seed,
rule, every candidate's last training-evaluation cost)::

    python -m benchmarks.rl.ship --plan cartpole_online_sac

``--best`` ships the plan's best learning-curve policy instead (:data:`BEST_RULE`, on the same
training-evaluation seeds: SB3's ``EvalCallback`` best model across the seeds), for a plan whose
policies reach the goal during training and lose it by the end. The policy is the seed's run
trained to that evaluation's step, which a run of the same command with that ``--steps``
reproduces (training is deterministic per seed and command): ``--from DIR`` names that run,
whose learning curve must equal the plan seed's up to the step; without ``--from`` the command
prints the training command to run first::

    python -m benchmarks.rl.ship --plan cartpole_online_tqc --best
    python -m benchmarks.rl.ship --plan cartpole_online_tqc --best --from DIR
"""

from __future__ import annotations

import argparse
import json
import shlex
import shutil
from pathlib import Path
from typing import Any

from benchmarks.rl.runs import PLANS, REPO, Plan
from benchmarks.rl.seeds import read_curve
from benchmarks.rl.summary import load_runs

__all__ = ["BEST_RULE", "RULE", "best_policy", "select_seed", "ship", "ship_best"]

MODELS = Path(__file__).resolve().parents[1] / "models"
FILES = ("model.zip", "vecnormalize.pkl", "metadata.json", "learning_curve.csv")
RULE = ("lowest mean cost at the seed's last training evaluation (reset seeds 1000..1019; "
        "the final-evaluation seeds 0..19 are not looked at)")
BEST_RULE = ("the best training evaluation over every seed and step: highest success rate, then "
             "lowest mean cost, then the smaller seed and step (reset seeds 1000..1019; the "
             "final-evaluation seeds are not looked at)")
_CURVE_KEYS = ("timesteps", "success_rate", "mean_cost", "mean_final_distance")


def select_seed(last_costs: dict[int, float]) -> int:
    """The seed of the lowest cost (ties: the smaller seed).

    Raises:
        ValueError: no candidates.
    """
    if not last_costs:
        raise ValueError("no finished seed to choose from")
    return min(last_costs, key=lambda s: (last_costs[s], s))


def ship(name: str, plan: Plan, models: Path = MODELS) -> dict[str, Any]:
    """Copy the selected seed of finished plan ``name`` to ``models/<env>/<algo>/``; returns
    its ``shipped_from`` record.

    Raises:
        ValueError: a seed of the plan has not finished, or has no training evaluation.
    """
    runs = load_runs(name, plan)
    done = {r.seed: r for r in runs if r.finished}
    missing = sorted(set(plan.seeds) - set(done))
    if missing:
        raise ValueError(f"plan {name!r} has unfinished seeds {missing}: ship a finished plan")
    if any(not r.curve for r in done.values()):
        raise ValueError(f"plan {name!r}: a seed has no training evaluation to select on")
    last = {s: float(r.curve[-1]["mean_cost"]) for s, r in done.items()}
    seed = select_seed(last)
    run = done[seed]
    dest = models / plan.env / plan.algo
    dest.mkdir(parents=True, exist_ok=True)
    for f in FILES:
        shutil.copyfile(run.path / f, dest / f)
    record = {"plan": name, "seed": seed, "rule": RULE,
              "run_dir": str(run.path.relative_to(REPO) if run.path.is_relative_to(REPO)
                             else run.path),
              "last_training_eval_cost": {str(s): c for s, c in sorted(last.items())}}
    meta = json.loads((dest / "metadata.json").read_text())
    meta["shipped_from"] = record
    (dest / "metadata.json").write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
    return record


def best_policy(name: str, plan: Plan) -> tuple[int, dict[str, float]]:
    """The seed and learning-curve row of the plan's best training evaluation
    (:data:`BEST_RULE`), over its finished seeds.

    Raises:
        ValueError: a seed of the plan has not finished, or none has a training evaluation.
    """
    done = {r.seed: r for r in load_runs(name, plan) if r.finished}
    missing = sorted(set(plan.seeds) - set(done))
    if missing:
        raise ValueError(f"plan {name!r} has unfinished seeds {missing}: ship a finished plan")
    rows = [(s, row) for s, r in done.items() for row in r.curve]
    if not rows:
        raise ValueError(f"plan {name!r} has no training evaluation to select on")
    return min(rows, key=lambda sr: (-sr[1]["success_rate"], sr[1]["mean_cost"], sr[0],
                                     sr[1]["timesteps"]))


def ship_best(name: str, plan: Plan, source: Path, models: Path = MODELS) -> dict[str, Any]:
    """Copy the plan's best learning-curve policy (:func:`best_policy`), trained again into
    run directory ``source``, to ``models/<env>/<algo>/``; returns its ``shipped_from`` record.

    Raises:
        ValueError: ``source`` is not that seed's run finished at that step: another length,
            or a learning curve that differs from the plan seed's (values to 1e-9 relative,
            wall times aside) up to it.
    """
    seed, row = best_policy(name, plan)
    step = int(row["timesteps"])
    meta = json.loads((source / "metadata.json").read_text())
    if int(meta["training_steps"]) != step or int(meta.get("seed", -1)) != seed:
        raise ValueError(f"{source} holds seed {meta.get('seed')} at {meta['training_steps']} "
                         f"steps; the best policy is seed {seed} at {step}")
    plan_curve = next(r for r in load_runs(name, plan) if r.seed == seed).curve
    want = [r for r in plan_curve if r["timesteps"] <= step]
    got = read_curve(source / "learning_curve.csv")
    same = len(got) == len(want) and all(
        abs(a[k] - b[k]) <= 1e-9 * max(1.0, abs(b[k])) for a, b in zip(got, want, strict=True)
        for k in _CURVE_KEYS)
    if not same:
        raise ValueError(f"{source}'s learning curve differs from plan {name!r} seed {seed}'s up "
                         f"to step {step}: it is not the plan's policy")
    dest = models / plan.env / plan.algo
    dest.mkdir(parents=True, exist_ok=True)
    for f in FILES:
        shutil.copyfile(source / f, dest / f)
    record = {"plan": name, "seed": seed, "rule": BEST_RULE, "step": step,
              "training_eval": {k: row[k] for k in _CURVE_KEYS},
              "run_dir": str(source.relative_to(REPO) if source.is_relative_to(REPO)
                             else source)}
    meta["shipped_from"] = record
    (dest / "metadata.json").write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
    return record


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--plan", required=True, choices=sorted(n for n in PLANS
                                                                  if not n.startswith("pilot")))
    parser.add_argument("--best", action="store_true",
                        help="ship the best learning-curve policy over the seeds (BEST_RULE)")
    parser.add_argument("--from", dest="source", type=Path, default=None,
                        help="with --best: the run that reproduces it (without: print the "
                             "training command that makes it)")
    args = parser.parse_args(argv)
    plan = PLANS[args.plan]
    if args.source is not None and not args.best:
        parser.error("--from goes with --best")
    try:
        if not args.best:
            record = ship(args.plan, plan)
        elif args.source is None:
            seed, row = best_policy(args.plan, plan)
            cmd = plan.command(args.plan, seed)
            cmd[cmd.index("--steps") + 1] = str(int(row["timesteps"]))
            out = cmd.index("--out") + 1
            cmd[out] = f"{cmd[out]}-best"
            print(f"best: seed {seed} at {int(row['timesteps'])} steps (success "
                  f"{row['success_rate']:.2f}, cost {row['mean_cost']:.2f}); train it, then "
                  f"ship it with --from {cmd[out]}:\npython {shlex.join(cmd)}")
            return
        else:
            record = ship_best(args.plan, plan, args.source)
    except ValueError as err:
        parser.error(str(err))
    print(json.dumps(record, indent=2))


if __name__ == "__main__":
    main()
