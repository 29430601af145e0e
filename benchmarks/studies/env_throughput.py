"""Env step throughput (steps per second) of every registered env, on one core.

Run: ``make throughput`` or ``OMP_NUM_THREADS=1 python benchmarks/studies/env_throughput.py``.
Steps go through ``gym.make`` (with Gymnasium's default wrappers) under a fixed random action
sequence; the figure is the median over repeats. Writes ``benchmarks/results/env_throughput.md``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import platform
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import gp_envs

RESULTS = Path(__file__).resolve().parents[1] / "results" / "env_throughput.md"


def measure(env_id: str, steps: int, repeats: int) -> list[float]:
    """Steps per second of ``env_id`` over ``repeats`` runs of ``steps`` steps each."""
    env = gym.make(env_id)
    env.action_space.seed(0)
    actions = [env.action_space.sample() for _ in range(steps)]
    rates = []
    for r in range(repeats):
        env.reset(seed=r)
        start = time.perf_counter()
        for a in actions:
            _, _, terminated, truncated, _ = env.step(a)
            if terminated or truncated:
                env.reset()
        rates.append(steps / (time.perf_counter() - start))
    return rates


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    rows = []
    for env_id in gp_envs.ENV_IDS:
        rates = measure(env_id, args.steps, args.repeats)
        rows.append((env_id, float(np.median(rates)), float(np.min(rates)), float(np.max(rates))))
        print(f"{env_id:32s} median {rows[-1][1]:8.0f} steps/s "
              f"(min {rows[-1][2]:.0f}, max {rows[-1][3]:.0f})")
    target = 10_000
    cart = rows[0][1]
    verdict = "met" if cart >= target else "NOT met"
    lines = [
        "# Env step throughput",
        "",
        "Command: `OMP_NUM_THREADS=1 python benchmarks/studies/env_throughput.py "
        f"--steps {args.steps} "
        f"--repeats {args.repeats}`  ",
        f"Python {platform.python_version()}, {platform.machine()}, one core; steps through "
        "`gym.make` with random actions, median over repeats.",
        "",
        "| env | median steps/s | min | max |",
        "|---|---:|---:|---:|",
        *[f"| {r[0]} | {r[1]:.0f} | {r[2]:.0f} | {r[3]:.0f} |" for r in rows],
        "",
        f"Target: at least {target:,} cart-pole steps/s on one core: {verdict} ({cart:.0f}).",
        "",
    ]
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text("\n".join(lines))
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
