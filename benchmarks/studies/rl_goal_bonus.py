"""The cart-pole SAC with a goal bonus: does a training-only reward for being inside the goal
tolerance make the baseline hold the swing-up (decision record ``docs/studies/rl_goal_bonus.md``)?

Evaluates saved SAC runs deterministically with :func:`benchmarks.rl.evaluate.evaluate` (the
plain ``gym.make`` loop, one episode per reset seed; success: ``info["is_success"]`` at the last
step, Wilson 95% interval; cost ``-return``, bootstrap 95% interval of the mean) on one of two
seed sets, disjoint from each other and from every committed evaluation (the RL evaluation's
0..19, the learning curves' 1000..1019, the presets' 0..49, 200..249, 400..449, 500..509,
2000..2009):

* ``tuning``: reset seeds 3000..3019, which chose the bonus among the tuning runs;
* ``final``: reset seeds 5000..5039, the comparison with the previously shipped model, run
  once after the choice.

The runs (training seed 300, disjoint from the plans' 0..4 and the sweeps' 100..102)::

    python -m benchmarks.rl.train --env cartpole --scenario online --algo sac \\
        --hyperparams sac-swingup --reward bounded-shift --time-feature --goal-bonus B \\
        --steps 150000 --seed 300 --eval-freq 5000 --eval-episodes 20 \\
        --checkpoint-freq 10000 --out benchmarks/results/rl/goal_bonus/bB_seed300

Run: ``python -m benchmarks.studies.rl_goal_bonus --seeds tuning --models DIR [DIR ...]``
(directories relative to the repository). Writes
``benchmarks/results/rl/goal_bonus/<seeds>_eval.md`` and ``<seeds>_eval.csv`` (one row per
model) and ``<seeds>_episodes.csv``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import csv
from pathlib import Path

from benchmarks.rl.evaluate import evaluate

REPO = Path(__file__).resolve().parents[2]
OUT = REPO / "benchmarks" / "results" / "rl" / "goal_bonus"
SEED_SETS = {"tuning": range(3000, 3020), "final": range(5000, 5040)}
"""Reset seeds of the two evaluations (see the module docstring)."""


def _bonus(row_model: Path) -> str:
    import json

    meta = json.loads((row_model / "metadata.json").read_text())
    for w in meta.get("training_wrappers", []):
        if w["name"] == "GoalBonusReward":
            return f"{w['bonus_per_s']:g}"
    return "0"


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", choices=sorted(SEED_SETS), required=True)
    parser.add_argument("--models", type=Path, nargs="+", required=True,
                        help="saved run directories (model.zip, metadata.json, ...)")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    seeds = SEED_SETS[args.seeds]
    args.out.mkdir(parents=True, exist_ok=True)
    rows, episodes = [], []
    for d in args.models:
        d = (REPO / d).resolve() if not d.is_absolute() else d
        row, eps = evaluate(d, seeds)
        row["goal_bonus_per_s"] = _bonus(d)
        row["model"] = str(d.relative_to(REPO))
        for e in eps:
            e["model"] = row["model"]
        rows.append(row)
        episodes.extend(eps)
        print(f"{row['model']}: success {row['success_rate']:.2f} "
              f"[{row['success_ci_low']:.2f}, {row['success_ci_high']:.2f}]  cost "
              f"{-row['mean_return']:.2f} [{-row['return_ci_high']:.2f}, "
              f"{-row['return_ci_low']:.2f}]", flush=True)
    stem = f"{args.seeds}_eval"
    for path, data in ((args.out / f"{stem}.csv", rows),
                       (args.out / f"{args.seeds}_episodes.csv", episodes)):
        with open(path, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=list(data[0]))
            writer.writeheader()
            writer.writerows(data)
    lines = [f"# Cart-pole RL policies (goal bonus, best learning-curve policies): "
             f"{args.seeds} evaluation",
             "",
             f"Deterministic episodes, reset seeds {seeds.start}..{seeds.stop - 1} "
             f"({len(seeds)} per model); success with its Wilson 95% interval, mean cost "
             "(-return) with its bootstrap 95% interval. "
             "`python -m benchmarks.studies.rl_goal_bonus --seeds "
             f"{args.seeds} --models {' '.join(r['model'] for r in rows)}`",
             "",
             "| model | goal bonus (1/s) | train seed | steps | success | 95% CI | mean cost | "
             "95% CI | success at some step | final distance | ends |",
             "|---|---:|---:|---:|---:|---|---:|---|---:|---:|---|"]
    for r in rows:
        lines.append(
            f"| `{r['model']}` | {r['goal_bonus_per_s']} | {r['seed']} | "
            f"{r['training_steps']} | {r['success_rate']:.2f} | "
            f"[{r['success_ci_low']:.2f}, {r['success_ci_high']:.2f}] | "
            f"{-r['mean_return']:.2f} | [{-r['return_ci_high']:.2f}, {-r['return_ci_low']:.2f}] "
            f"| {r['success_any_rate']:.2f} | {r['mean_final_distance']:.3f} | {r['ends']} |")
    (args.out / f"{stem}.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out / (stem + '.md')}")


if __name__ == "__main__":
    main()
