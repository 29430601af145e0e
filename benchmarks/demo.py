"""Demo: one seeded rollout of each registered env, a table and a picture of the last frames.

Run: ``make bench`` (or ``python -m benchmarks.demo``). The policy is uniform random actions
(seeded): this shows the envs, their rewards and terminations, not a controller.
Writes ``benchmarks/results/demo/demo.png``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import gymnasium as gym
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from tqdm import tqdm

import gp_envs

OUT = Path(__file__).resolve().parent / "results" / "demo"


def rollout(env_id: str, seed: int) -> dict:
    """Run one episode of ``env_id`` with seeded random actions; return a summary and a frame."""
    env = gym.make(env_id, render_mode="rgb_array")
    env.action_space.seed(seed)
    _, info = env.reset(seed=seed)
    ret, steps, done = 0.0, 0, False
    while not done:
        _obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        ret += reward
        steps += 1
        done = terminated or truncated
    frame = env.render()
    env.close()
    return {"env": env_id, "return": ret, "steps": steps, "success": info["success"],
            "end": info["termination_reason"] or "time limit", "frame": frame}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    results = [rollout(env_id, args.seed) for env_id in tqdm(gp_envs.ENV_IDS, desc="rollouts")]
    print(f"\n{'env':32s} {'steps':>5s} {'return':>12s} {'success':>8s}  end")
    for r in results:
        print(f"{r['env']:32s} {r['steps']:5d} {r['return']:12.2f} "
              f"{r['success']!s:>8s}  {r['end']}")
    fig, axes = plt.subplots(1, len(results), figsize=(5 * len(results), 4))
    for ax, r in zip(axes, results, strict=True):
        ax.imshow(r["frame"])
        ax.set_title(f"{r['env']}\nlast frame, random actions", fontsize=9)
        ax.axis("off")
    OUT.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT / "demo.png", dpi=80, bbox_inches="tight")
    print(f"wrote {OUT / 'demo.png'}")


if __name__ == "__main__":
    main()
