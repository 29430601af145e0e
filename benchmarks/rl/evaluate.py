"""Evaluate every shipped RL baseline in the plain ``gym.make`` loop; tables and learning curves.

For each ``benchmarks/models/<env>/<algo>/`` (written by :mod:`benchmarks.rl.train`) this loads
the agent with :meth:`gp_agents.rl.RLAgent.load` into ``gym.make(env_id, scenario=...)`` and runs
20 episodes with reset seeds 0..19 (reset, ``agent.act``, ``env.step``, ``agent.observe``).
Success is ``info["is_success"]`` at the episode's last step. A policy that fails is reported as
failing.

Run: ``python -m benchmarks.rl.evaluate``. Writes ``benchmarks/results/rl/rl_eval.md``,
``rl_eval.csv`` (one row per model), ``rl_episodes.csv`` (one row per episode) and
``<env>_learning_curve.png`` (training-time evaluation success rate and mean return against env
steps, with the final 20-episode evaluation marked).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import csv
import json
from collections import Counter
from pathlib import Path
from typing import Any

import gymnasium as gym
import matplotlib
import numpy as np
import torch

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.ticker import FormatStrFormatter, FuncFormatter, SymmetricalLogLocator

import gp_envs  # noqa: F401  (registers the envs)
from benchmarks.report import mean_ci, wilson_ci
from gp_agents.agent import rollout
from gp_agents.rl import METADATA_FILE, RLAgent

HERE = Path(__file__).resolve().parents[1]
MODELS = HERE / "models"
OUT = HERE / "results" / "rl"
SEEDS = range(20)


def model_dirs(root: Path = MODELS) -> list[Path]:
    """Directories under ``root`` holding a saved agent (``<env>/<algo>/metadata.json``) of a
    registered ``gp_envs`` system; an outside env's (:mod:`benchmarks.outside_envs`: made
    through :func:`gp_envs.wrap`, not ``gym.make``) are the own-env preset's to evaluate."""
    out = []
    for p in sorted(root.glob(f"*/*/{METADATA_FILE}")):
        if json.loads(p.read_text())["env_id"] in gym.registry:
            out.append(p.parent)
    return out


def read_curve(path: Path) -> list[dict[str, float]]:
    """Rows of a ``learning_curve.csv`` (empty if missing)."""
    if not path.is_file():
        return []
    with open(path, newline="") as fh:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(fh)]


def evaluate(model_dir: Path, seeds: range = SEEDS) -> tuple[dict[str, Any], list[dict]]:
    """Run ``len(seeds)`` episodes of the agent in ``model_dir``; summary row and episodes."""
    meta = json.loads((model_dir / METADATA_FILE).read_text())
    env = gym.make(meta["env_id"], scenario=meta["scenario"])
    agent = RLAgent.load(model_dir, env)
    episodes = []
    for seed in seeds:
        ep = rollout(env, agent, seed).summary()
        episodes.append({"model": str(model_dir.relative_to(HERE)), "seed": seed, **ep})
    env.close()
    rets = np.array([e["return"] for e in episodes])
    ends = Counter(e["end"] for e in episodes)
    row = {
        "env": model_dir.parent.name,
        "env_id": agent.env_id,
        "scenario": agent.scenario,
        "algo": agent.algo,
        "seed": agent.seed,
        "training_steps": agent.training_steps,
        "train_time_s": agent.train_time_s,
        "episodes": len(episodes),
        "success_rate": float(np.mean([e["success"] for e in episodes])),
        **dict(zip(("success_ci_low", "success_ci_high"),
                   wilson_ci(int(sum(bool(e["success"]) for e in episodes)), len(episodes)),
                   strict=True)),
        "mean_return": float(rets.mean()),
        **dict(zip(("return_ci_low", "return_ci_high"), mean_ci(rets.tolist()), strict=True)),
        "std_return": float(rets.std()),
        "mean_length": float(np.mean([e["length"] for e in episodes])),
        "success_any_rate": float(np.mean([e["success_any"] for e in episodes])),
        "mean_final_distance": float(np.mean([e["final_distance"] for e in episodes])),
        "ends": "; ".join(f"{k}: {v}" for k, v in ends.most_common()),
        "model": str(model_dir.relative_to(HERE)),
    }
    return row, episodes


def plot_env(env: str, rows: list[dict[str, Any]], out: Path) -> None:
    """Learning curves (success rate, mean return vs env steps) of every algo trained on env."""
    fig, (ax_s, ax_r) = plt.subplots(1, 2, figsize=(10, 3.8))
    for i, row in enumerate(rows):
        color = f"C{i}"
        curve = read_curve(HERE / row["model"] / "learning_curve.csv")
        label = f"{row['algo'].upper()} (seed {row['seed']})"
        if curve:
            steps = [c["timesteps"] for c in curve]
            ax_s.plot(steps, [c["success_rate"] for c in curve], "-o", ms=3, color=color,
                      label=f"{label}: training evals")
            ax_r.plot(steps, [c["mean_return"] for c in curve], "-o", ms=3, color=color,
                      label=f"{label}: training evals")
        ax_s.plot(row["training_steps"], row["success_rate"], "*", ms=14, color=color,
                  markeredgecolor="k", label=f"{label}: final, seeds 0..19")
        ax_r.plot(row["training_steps"], row["mean_return"], "*", ms=14, color=color,
                  markeredgecolor="k", label=f"{label}: final, seeds 0..19")
    ax_s.set_ylim(-0.05, 1.05)
    ax_s.set_ylabel("success rate")
    ax_r.set_yscale("symlog", linthresh=10.0)
    ax_r.yaxis.set_major_locator(SymmetricalLogLocator(base=10, linthresh=10.0, subs=(1, 2, 5)))
    ax_r.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax_r.set_ylabel("mean return (symlog)")
    for ax in (ax_s, ax_r):
        ax.set_xlabel("env steps")
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v / 1000:g}k"))
        ax.grid(alpha=0.3)
    ax_s.legend(fontsize=7, loc="best")
    fig.suptitle(f"{rows[0]['env_id']} ({rows[0]['scenario']}): RL baseline learning curve",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def write_markdown(rows: list[dict[str, Any]], path: Path) -> None:
    """The summary table plus each model's learning curve as a compact table."""
    lines = [
        "# RL baselines (stable-baselines3): evaluation",
        "",
        "Written by `python -m benchmarks.rl.evaluate`. Each shipped model is loaded with "
        "`RLAgent.load` into `gym.make(env_id, scenario=...)` and run for 20 episodes "
        "(reset seeds 0..19) with its deterministic policy in the plain loop; success is "
        "`info[\"is_success\"]` at the last step (goal tolerance held for the task's hold time). "
        "Training time is wall clock on a shared 2-core machine, learning-curve evaluations "
        "included. Intervals (95%) are over the 20 episodes of the one shipped policy (Wilson "
        "for the success rate, bootstrap BCa of the mean return): they say how well 20 "
        "episodes pin down that policy, not how much another training seed would differ (the "
        "spread over training seeds is in `summary.md`).",
        "",
        "| env | scenario | algo | seed | env steps trained | training time (s) | success rate "
        "[95% CI] | mean return [95% CI] | std return | mean length | success at some step | "
        "final distance to goal | episode ends |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['env_id']} | {r['scenario']} | {r['algo'].upper()} | {r['seed']} | "
            f"{r['training_steps']} | {r['train_time_s']:.0f} | {r['success_rate']:.2f} "
            f"[{r['success_ci_low']:.2f}, {r['success_ci_high']:.2f}] | {r['mean_return']:.1f} "
            f"[{r['return_ci_low']:.1f}, {r['return_ci_high']:.1f}] | {r['std_return']:.1f} | "
            f"{r['mean_length']:.1f} | "
            f"{r['success_any_rate']:.2f} | {r['mean_final_distance']:.3f} | {r['ends']} |")
    lines += ["", "*success at some step*: fraction of episodes in which the goal tolerance was "
              "held for the hold time at some point (the success rate counts the last step). "
              "*final distance to goal*: mean `info[\"distance_to_goal\"]` at the last step "
              "(norm over the checked components: m, and rad for the cart-pole angle).",
              "", "Failing policies (success rate 0) are kept in the table: they are the result."]
    for r in rows:
        curve = read_curve(HERE / r["model"] / "learning_curve.csv")
        lines += ["", f"## {r['env_id']} ({r['scenario']}), {r['algo'].upper()}", "",
                  f"![learning curve]({r['env']}_learning_curve.png)", ""]
        if not curve:
            lines.append("No learning curve recorded.")
            continue
        lines += ["Training-time evaluations (deterministic, reset seeds 1000.., disjoint from "
                  "the final evaluation's):", "",
                  "| env steps | success rate | mean return |", "|---:|---:|---:|"]
        stride = max(1, len(curve) // 12)
        picked = curve[::stride] + ([curve[-1]] if (len(curve) - 1) % stride else [])
        for c in picked:
            lines.append(f"| {int(c['timesteps'])} | {c['success_rate']:.2f} | "
                         f"{c['mean_return']:.1f} |")
    path.write_text("\n".join(lines) + "\n")


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--models", type=Path, default=MODELS, help="models root")
    parser.add_argument("--out", type=Path, default=OUT, help="results directory")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    args.out.mkdir(parents=True, exist_ok=True)

    rows, episodes = [], []
    for d in model_dirs(args.models):
        row, eps = evaluate(d)
        rows.append(row)
        episodes += eps
        print(f"{row['env_id']:28s} {row['scenario']:7s} {row['algo']:4s} steps "
              f"{row['training_steps']:7d}  success {row['success_rate']:.2f}  "
              f"return {row['mean_return']:9.1f}  ({row['ends']})")
    if not rows:
        raise SystemExit(f"no models under {args.models}; run benchmarks.rl.train first")
    with open(args.out / "rl_eval.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    with open(args.out / "rl_episodes.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(episodes[0]))
        writer.writeheader()
        writer.writerows(episodes)
    for env in sorted({r["env"] for r in rows}):
        plot_env(env, [r for r in rows if r["env"] == env],
                 args.out / f"{env}_learning_curve.png")
    write_markdown(rows, args.out / "rl_eval.md")
    print(f"wrote {args.out / 'rl_eval.md'}")


if __name__ == "__main__":
    main()
