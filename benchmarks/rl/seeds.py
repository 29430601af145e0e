"""One RL plan's seeds: their learning curves, final policies' episodes and the statistics
over seeds (median, quartiles, bootstrap interval of the median)."""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import csv
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import gp_envs  # noqa: F401  (registers the envs)
from benchmarks.rl.runs import REPO, Plan
from gp_agents.agent import rollout
from gp_agents.rl import METADATA_FILE, RLAgent

OUT = Path(__file__).resolve().parents[1] / "results" / "rl"
FINAL_SEEDS = range(20)
N_BOOT = 10_000
METRICS = (("success_rate", "success rate", "{:.2f}"), ("mean_cost", "mean cost", "{:.2f}"),
           ("mean_final_distance", "final distance", "{:.3f}"))
"""(key, label, format) of the per-policy metrics reported."""


@dataclass
class SeedRun:
    """One seed of a plan: its learning curve so far and, if finished, metadata and episodes."""

    seed: int
    path: Path
    curve: list[dict[str, float]]
    metadata: dict[str, Any] | None
    episodes: list[dict[str, Any]] | None = None

    @property
    def finished(self) -> bool:
        """Whether a final model was saved."""
        return self.metadata is not None


def read_curve(path: Path) -> list[dict[str, float]]:
    """Rows of a ``learning_curve.csv`` (empty if missing)."""
    if not path.is_file():
        return []
    with open(path, newline="") as fh:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(fh)]


def load_runs(name: str, plan: Plan) -> list[SeedRun]:
    """The plan's seeds that have at least a learning curve."""
    runs = []
    for seed in plan.seeds:
        d = plan.run_dir(name, seed)
        curve = read_curve(d / "learning_curve.csv")
        meta_file = d / METADATA_FILE
        meta = json.loads(meta_file.read_text()) if meta_file.is_file() else None
        if meta is not None and meta.get("training_steps", 0) < plan.steps:
            meta = None  # an older, shorter final model: being extended
        if curve or meta:
            runs.append(SeedRun(seed, d, curve, meta))
    return runs


def final_episodes(run: SeedRun, seeds: range = FINAL_SEEDS) -> list[dict[str, Any]]:
    """Deterministic episodes of the run's final policy on the plain env, one per reset seed."""
    assert run.metadata is not None
    env = gym.make(run.metadata["env_id"], scenario=run.metadata["scenario"])
    agent = RLAgent.load(run.path, env)
    eps = [{"seed": run.seed, "episode_seed": s, **rollout(env, agent, s).summary()} for s in seeds]
    env.close()
    for e in eps:
        e["cost"] = -e["return"]
    return eps


def policy_metrics(episodes: list[dict[str, Any]]) -> dict[str, float]:
    """Success rate, mean cost, mean final distance (and extras) over one policy's episodes."""
    return {"success_rate": float(np.mean([e["success"] for e in episodes])),
            "mean_cost": float(np.mean([e["cost"] for e in episodes])),
            "mean_final_distance": float(np.mean([e["final_distance"] for e in episodes])),
            "success_any_rate": float(np.mean([e["success_any"] for e in episodes])),
            "terminated": int(sum(e["end"] != "time limit" for e in episodes))}


def median_iqr_ci(values: list[float], n_boot: int = N_BOOT) -> dict[str, float]:
    """Median, quartiles and percentile-bootstrap 95% CI of the median over ``values``.

    The CI resamples the values (seeds) with replacement ``n_boot`` times (NumPy generator,
    seed 0); NaN for fewer than 2 values.
    """
    x = np.asarray(values, dtype=float)
    q25, med, q75 = np.percentile(x, [25, 50, 75])
    lo = hi = float("nan")
    if x.size >= 2:
        rng = np.random.default_rng(0)
        meds = np.median(x[rng.integers(0, x.size, size=(n_boot, x.size))], axis=1)
        lo, hi = np.percentile(meds, [2.5, 97.5])
    return {"median": float(med), "q25": float(q25), "q75": float(q75), "ci_lo": float(lo),
            "ci_hi": float(hi), "n": int(x.size)}


def _rel(path: Path) -> Path:
    """``path`` relative to the repository if it is inside it."""
    return path.relative_to(REPO) if path.is_relative_to(REPO) else path


def curve_percentiles(runs: list[SeedRun], key: str, q: tuple[float, ...] = (25, 50, 75),
                      min_seeds: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Percentiles ``q`` over seeds of ``key`` at each evaluation step reached by at least
    ``min_seeds`` seeds: the steps (S,) and the percentiles (len(q), S)."""
    by_step: dict[int, list[float]] = {}
    for r in runs:
        for row in r.curve:
            by_step.setdefault(int(row["timesteps"]), []).append(row[key])
    steps = sorted(s for s, v in by_step.items() if len(v) >= min_seeds)
    values = np.array([np.percentile(by_step[s], q) for s in steps]).reshape(len(steps), len(q))
    return np.array(steps), values.T


def median_curve(runs: list[SeedRun], key: str, min_seeds: int = 2
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Median over seeds of ``key`` at each evaluation step reached by >= ``min_seeds`` seeds."""
    steps, values = curve_percentiles(runs, key, (50,), min_seeds)
    return steps, values[0]
