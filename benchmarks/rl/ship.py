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

``--best`` ships a best learning-curve policy instead, for a plan whose policies reach the goal
during training and lose it by the end: the seed whose training evaluations include the plan's
best one (:data:`BEST_RULE`, on the same training-evaluation seeds) is trained again with the
same configuration, the run keeping its best learning-curve policy in ``best/`` (SB3's
``EvalCallback`` best model; :mod:`benchmarks.rl.train`), and that policy is shipped. A re-run
rather than the original policy, because the plans' runs kept their final policies only and
training does not reproduce bit for bit across library versions (a difference in a float's last
digits grows into another run). ``--from DIR`` names the re-run; its
configuration must be the plan seed's; without ``--from`` the command prints the training
command to run first::

    python -m benchmarks.rl.ship --plan cartpole_online_tqc --best
    python -m benchmarks.rl.ship --plan cartpole_online_tqc --best --from DIR

``--run DIR --why TEXT`` ships one saved policy that no plan made (a study's run, its
``best/`` policy), with the study's reason as the rule::

    python -m benchmarks.rl.ship --run benchmarks/results/rl/goal_bonus/b100_seed300/best \
        --why "docs/studies/rl_goal_bonus.md: ..."
"""

from __future__ import annotations

import argparse
import json
import shlex
import shutil
from pathlib import Path
from typing import Any

from benchmarks.rl.runs import PLANS, REPO, Plan
from benchmarks.rl.summary import load_runs

__all__ = ["BEST_RULE", "RULE", "best_policy", "select_seed", "ship", "ship_best", "ship_run"]

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


def _copy_curve(curve: Path, dest: Path, steps: int) -> None:
    """Copy the learning curve ``curve`` to ``dest`` up to ``steps`` (the evaluations that led
    to the policy shipped; none past it), or remove ``dest``'s when there is none."""
    if not curve.is_file():
        (dest / "learning_curve.csv").unlink(missing_ok=True)
        return
    lines = curve.read_text().splitlines()
    col = lines[0].split(",").index("timesteps")
    keep = [ln for ln in lines[1:] if float(ln.split(",")[col]) <= steps]
    (dest / "learning_curve.csv").write_text("\n".join([lines[0], *keep]) + "\n")


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
    """Copy the best learning-curve policy of ``source`` (``source/best``), a run of the seed
    :func:`best_policy` picks with the plan's configuration, to ``models/<env>/<algo>/``;
    returns its ``shipped_from`` record.

    Raises:
        ValueError: ``source`` has no finished run or no ``best/`` policy, or was trained with
            another configuration than the plan's seed.
    """
    seed, row = best_policy(name, plan)
    plan_meta = json.loads((plan.run_dir(name, seed) / "metadata.json").read_text())
    meta_file = source / "metadata.json"
    best_dir = source / "best"
    if not meta_file.is_file() or not (best_dir / "metadata.json").is_file():
        raise ValueError(f"{source} is not a finished run with a best/ policy (train it with "
                         f"the command `ship --best` prints)")
    meta = json.loads((best_dir / "metadata.json").read_text())
    if meta.get("run_config") != plan_meta.get("run_config"):
        raise ValueError(f"{source} was trained with another configuration than plan {name!r} "
                         f"seed {seed}: not its re-run")
    dest = models / plan.env / plan.algo
    dest.mkdir(parents=True, exist_ok=True)
    for f in FILES[:3]:
        shutil.copyfile(best_dir / f, dest / f)
    _copy_curve(source / "learning_curve.csv", dest, int(meta["training_steps"]))
    best = meta["best_of_learning_curve"]
    meta.setdefault("train_time_s", best["wall_time_s"])  # a best policy's: at its evaluation
    record = {"plan": name, "seed": seed, "rule": BEST_RULE,
              "plan_best_training_eval": {k: row[k] for k in _CURVE_KEYS},
              "training_eval": {k: best[k] for k in _CURVE_KEYS},
              "run_dir": str(source.relative_to(REPO) if source.is_relative_to(REPO)
                             else source)}
    meta["shipped_from"] = record
    (dest / "metadata.json").write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
    return record


def ship_run(source: Path, why: str, models: Path = MODELS) -> dict[str, Any]:
    """Copy the saved policy in ``source`` (an agent directory: ``model.zip``,
    ``metadata.json``, ``vecnormalize.pkl`` if it has one; its learning curve, or its run's for
    a ``best/`` policy, up to its steps) to ``models/<env>/<algo>/`` (the env's short name and
    the algorithm from its metadata), with ``why`` as its rule; returns its ``shipped_from``
    record.

    Raises:
        ValueError: ``source`` is not a saved agent, its env is not a registered system, or
            ``why`` is empty.
    """
    from benchmarks.rl.train import ENV_SHORT_NAMES

    if not why.strip():
        raise ValueError("say why this policy ships (--why): the study and its rule")
    meta_file = source / "metadata.json"
    if not (meta_file.is_file() and (source / "model.zip").is_file()):
        raise ValueError(f"{source} is not a saved agent (model.zip and metadata.json)")
    meta = json.loads(meta_file.read_text())
    if "best_of_learning_curve" in meta:  # a best policy's training time: at its evaluation
        meta.setdefault("train_time_s", meta["best_of_learning_curve"]["wall_time_s"])
    short = {v: k for k, v in ENV_SHORT_NAMES.items()}.get(meta["env_id"])
    if short is None:
        raise ValueError(f"{source}: env {meta['env_id']!r} is not a registered system")
    dest = models / short / meta["algo"]
    dest.mkdir(parents=True, exist_ok=True)
    files = [f for f in FILES[:2] if (source / f).is_file()]
    for f in files:
        shutil.copyfile(source / f, dest / f)
    curve = source / "learning_curve.csv"  # a best/ policy's curve is its run's
    _copy_curve(curve if curve.is_file() else source.parent / "learning_curve.csv", dest,
                int(meta["training_steps"]))
    record = {"rule": why, "seed": meta.get("seed"),
              "run_dir": str(source.relative_to(REPO) if source.is_relative_to(REPO)
                             else source)}
    meta["shipped_from"] = record
    (dest / "metadata.json").write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
    return record


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--plan", choices=sorted(n for n in PLANS if not n.startswith("pilot")))
    parser.add_argument("--run", type=Path, default=None,
                        help="ship this saved policy instead of a plan's (with --why)")
    parser.add_argument("--why", default="", help="with --run: the study and its rule")
    parser.add_argument("--best", action="store_true",
                        help="ship the best learning-curve policy of a re-run of the plan's "
                             "best seed (BEST_RULE)")
    parser.add_argument("--from", dest="source", type=Path, default=None,
                        help="with --best: that re-run (without: print the training command "
                             "that makes it)")
    args = parser.parse_args(argv)
    if (args.plan is None) == (args.run is None):
        parser.error("give --plan or --run")
    if args.run is not None:
        if args.best or args.source is not None:
            parser.error("--best and --from go with --plan")
        try:
            print(json.dumps(ship_run(args.run, args.why), indent=2))
        except ValueError as err:
            parser.error(str(err))
        return
    plan = PLANS[args.plan]
    if args.source is not None and not args.best:
        parser.error("--from goes with --best")
    try:
        if not args.best:
            record = ship(args.plan, plan)
        elif args.source is None:
            seed, row = best_policy(args.plan, plan)
            cmd = plan.command(args.plan, seed)
            out = cmd.index("--out") + 1
            cmd[out] = f"{cmd[out]}-rerun"
            print(f"best: seed {seed} at {int(row['timesteps'])} steps (success "
                  f"{row['success_rate']:.2f}, cost {row['mean_cost']:.2f}); train the seed "
                  f"again, then ship its best policy with --from {cmd[out]}:\n"
                  f"python {shlex.join(cmd)}")
            return
        else:
            record = ship_best(args.plan, plan, args.source)
    except ValueError as err:
        parser.error(str(err))
    print(json.dumps(record, indent=2))


if __name__ == "__main__":
    main()
