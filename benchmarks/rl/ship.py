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
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path
from typing import Any

from benchmarks.rl.runs import PLANS, REPO, Plan
from benchmarks.rl.summary import load_runs

__all__ = ["RULE", "select_seed", "ship"]

MODELS = Path(__file__).resolve().parents[1] / "models"
FILES = ("model.zip", "vecnormalize.pkl", "metadata.json", "learning_curve.csv")
RULE = ("lowest mean cost at the seed's last training evaluation (reset seeds 1000..1019; "
        "the final-evaluation seeds 0..19 are not looked at)")


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


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--plan", required=True, choices=sorted(n for n in PLANS
                                                                  if not n.startswith("pilot")))
    args = parser.parse_args(argv)
    try:
        record = ship(args.plan, PLANS[args.plan])
    except ValueError as err:
        parser.error(str(err))
    print(json.dumps(record, indent=2))


if __name__ == "__main__":
    main()
