"""Train an SB3 baseline (SAC or PPO) on a registered ``gp_envs`` env and save it as an RLAgent.

The env is made with ``gym.make`` (same reward, same time limit as every other controller); the
agent's preprocessing (:mod:`gp_agents.rl`: angle -> cos/sin, VecNormalize, action rescaling to
``[-1, 1]``) is applied by wrappers around it and saved with the model. While training, every
``--eval-freq`` env steps a callback runs ``--eval-episodes`` deterministic episodes of the current
policy on a separate, plain ``gym.make`` env (reset seeds 1000, 1001, ...: disjoint from the
final evaluation's 0..19) and appends success rate and mean return to ``learning_curve.csv`` next
to the model, so sample efficiency can be compared at equal numbers of env steps.

Hyperparameters start from rl-baselines3-zoo's tuned settings (``hyperparams/sac.yml`` and
``hyperparams/ppo.yml``, Pendulum-v1 entries, the closest task: a dense quadratic cost on a
low-dimensional continuous-control system); deviations are listed in ``HYPERPARAMETERS`` and
recorded with the model.

Run (one core)::

    python -m benchmarks.train_rl --env cartpole --scenario online --algo sac --steps 100000

Writes ``benchmarks/models/<env-short-name>/<algo>/``: ``model.zip``, ``vecnormalize.pkl``,
``metadata.json`` (hyperparameters, seed, steps, wall-clock time) and ``learning_curve.csv``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse
import copy
import csv
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.callbacks import BaseCallback, CallbackList
from tqdm import tqdm

import gp_envs
from gp_agents.rl import ALGORITHMS, RLAgent, make_training_vec_env, rollout

MODELS = Path(__file__).resolve().parent / "models"

ENV_SHORT_NAMES = {
    "cartpole": "gp_envs/CartPoleSwingUp-v0",
    "quadrotor": "gp_envs/Quadrotor-v0",
    "dubins": "gp_envs/DubinsObstacle-v0",
}
"""``--env`` short names (also the model directory names) -> registered env ids."""

EVAL_SEED0 = 1000
"""First reset seed of the learning-curve evaluation episodes."""

HYPERPARAMETERS: dict[str, dict[str, Any]] = {
    # rl-baselines3-zoo sac.yml, Pendulum-v1: learning_rate 1e-3, everything else SB3 defaults
    # (written out here so the record is complete), except the network: [64, 64] as in zoo's
    # MountainCarContinuous-v0 entry instead of [256, 256], ~2x more steps per CPU second.
    "sac": {
        "source": "rl-baselines3-zoo hyperparams/sac.yml Pendulum-v1 (learning_rate 1e-3, "
                  "other values SB3 defaults) with net_arch [64, 64] from its "
                  "MountainCarContinuous-v0 entry; additions: obs normalization (VecNormalize), "
                  "angle cos/sin features",
        "n_envs": 1,
        "norm_obs": True,
        "norm_reward": False,
        "learning_rate": 1e-3,
        "buffer_size": 1_000_000,
        "learning_starts": 100,
        "batch_size": 256,
        "tau": 0.005,
        "gamma": 0.99,
        "train_freq": 1,
        "gradient_steps": 1,
        "ent_coef": "auto",
        "policy_kwargs": {"net_arch": [64, 64]},
    },
    # rl-baselines3-zoo ppo.yml, Pendulum-v1 (n_envs 4, n_steps 1024, lr 1e-3, gSDE) with
    # zoo's usual `normalize: true`; gamma 0.99 instead of Pendulum's 0.9 because these
    # episodes are 120-150 steps and the termination penalty must be seen well ahead.
    "ppo": {
        "source": "rl-baselines3-zoo hyperparams/ppo.yml Pendulum-v1; changes: gamma 0.9 -> "
                  "0.99 (120-150 step episodes with a termination penalty), normalize: true "
                  "(obs and reward, as zoo's BipedalWalker/MuJoCo entries), angle cos/sin "
                  "features",
        "n_envs": 4,
        "norm_obs": True,
        "norm_reward": True,
        "n_steps": 1024,
        "batch_size": 64,
        "gae_lambda": 0.95,
        "gamma": 0.99,
        "n_epochs": 10,
        "ent_coef": 0.0,
        "learning_rate": 1e-3,
        "clip_range": 0.2,
        "use_sde": True,
        "sde_sample_freq": 4,
    },
}
"""Per-algorithm hyperparameters (SB3 constructor arguments plus env-side settings)."""

_ENV_SIDE = ("source", "n_envs", "norm_obs", "norm_reward")

CURVE_FIELDS = ("timesteps", "wall_time_s", "success_rate", "mean_return", "std_return",
                "mean_length")


class ProgressBar(BaseCallback):
    """tqdm progress bar over env steps (no dependency on ``rich``)."""

    def __init__(self, total: int, desc: str) -> None:
        super().__init__()
        self._total, self._desc = total, desc
        self._bar: tqdm | None = None

    def _on_training_start(self) -> None:
        self._bar = tqdm(total=self._total, desc=self._desc, unit="step", mininterval=2.0)

    def _on_step(self) -> bool:
        assert self._bar is not None
        self._bar.update(self.training_env.num_envs)
        return True

    def _on_training_end(self) -> None:
        if self._bar is not None:
            self._bar.close()


class LearningCurve(BaseCallback):
    """Every ``eval_freq`` env steps, run deterministic episodes on a separate plain env.

    Each row of ``csv_path`` (columns :data:`CURVE_FIELDS`) holds the env steps trained so far,
    wall-clock seconds since the start, the success rate and the mean/std return and mean length
    of ``n_episodes`` episodes (reset seeds ``EVAL_SEED0 + i``). The policy is evaluated through
    an :class:`RLAgent` with the current normalization statistics, i.e. exactly as it will act
    after loading. Rows are written at the start, every ``eval_freq`` steps and at the end.
    """

    def __init__(self, env_id: str, scenario: str, metadata: dict[str, Any], eval_freq: int,
                 n_episodes: int, csv_path: Path) -> None:
        super().__init__()
        self.eval_env = gym.make(env_id, scenario=scenario)
        self.metadata = metadata
        self.eval_freq, self.n_episodes, self.csv_path = eval_freq, n_episodes, csv_path
        self.rows: list[dict[str, float]] = []
        self._next = 0
        self._t0 = time.perf_counter()
        self._eval_time = 0.0

    def _evaluate(self) -> None:
        t = time.perf_counter()
        venv = self.model.get_vec_normalize_env()
        agent = RLAgent(self.model, self.metadata, venv)
        eps = [rollout(agent, self.eval_env, EVAL_SEED0 + i) for i in range(self.n_episodes)]
        rets = np.array([e["return"] for e in eps])
        row = {"timesteps": int(self.num_timesteps),
               "wall_time_s": round(time.perf_counter() - self._t0, 2),
               "success_rate": float(np.mean([e["success"] for e in eps])),
               "mean_return": float(rets.mean()), "std_return": float(rets.std()),
               "mean_length": float(np.mean([e["length"] for e in eps]))}
        self.rows.append(row)
        with open(self.csv_path, "w", newline="") as fh:
            writer = csv.DictWriter(fh, fieldnames=CURVE_FIELDS)
            writer.writeheader()
            writer.writerows(self.rows)
        self._eval_time += time.perf_counter() - t

    def _on_training_start(self) -> None:
        self._t0 = time.perf_counter()
        self._evaluate()
        self._next = self.eval_freq

    def _on_step(self) -> bool:
        if self.num_timesteps >= self._next:
            self._evaluate()
            self._next += self.eval_freq
        return True

    def _on_training_end(self) -> None:
        if not self.rows or self.rows[-1]["timesteps"] != self.num_timesteps:
            self._evaluate()
        self.eval_env.close()


def train(env: str, scenario: str, algo: str, steps: int, seed: int, out: Path,
          eval_freq: int = 5000, eval_episodes: int = 10, progress: bool = True,
          overrides: dict[str, Any] | None = None) -> RLAgent:
    """Train, save to ``out`` and return the agent.

    Args:
        env: short name (:data:`ENV_SHORT_NAMES`) or registered env id.
        scenario: the env's scenario.
        algo: ``"sac"`` or ``"ppo"``.
        steps: total env steps (summed over sub-envs).
        seed: seeds the model (torch, numpy) and the training envs' resets.
        out: output directory.
        eval_freq: env steps between learning-curve evaluations (0: only start and end).
        eval_episodes: episodes per evaluation (0: no learning curve).
        progress: show a tqdm bar.
        overrides: hyperparameter overrides (keys of :data:`HYPERPARAMETERS`).
    """
    torch.set_num_threads(1)
    env_id = ENV_SHORT_NAMES.get(env, env)
    if algo not in ALGORITHMS:
        raise ValueError(f"unknown algo {algo!r}; choose one of {sorted(ALGORITHMS)}")
    hp = copy.deepcopy(HYPERPARAMETERS[algo])
    hp.update(overrides or {})
    sb3_kwargs = {k: v for k, v in hp.items() if k not in _ENV_SIDE}
    venv = make_training_vec_env(env_id, scenario, seed, n_envs=hp["n_envs"],
                                 norm_obs=hp["norm_obs"], norm_reward=hp["norm_reward"],
                                 gamma=hp["gamma"])
    model = ALGORITHMS[algo]("MlpPolicy", venv, seed=seed, device="cpu", verbose=0, **sb3_kwargs)

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    probe = gym.make(env_id, scenario=scenario)
    metadata = RLAgent.metadata_for(probe, algo, seed=seed, hyperparameters=hp,
                                    training_steps=0)
    probe.close()
    callbacks: list[BaseCallback] = []
    if progress:
        callbacks.append(ProgressBar(steps, f"{algo} {env_id} {scenario}"))
    curve = None
    if eval_episodes > 0:
        curve = LearningCurve(env_id, scenario, metadata, eval_freq or steps, eval_episodes,
                              out / "learning_curve.csv")
        callbacks.append(curve)

    t0 = time.perf_counter()
    model.learn(total_timesteps=steps, callback=CallbackList(callbacks))
    wall = time.perf_counter() - t0
    eval_time = curve._eval_time if curve is not None else 0.0
    metadata.update(training_steps=int(model.num_timesteps), train_time_s=round(wall, 1),
                    train_time_excluding_eval_s=round(wall - eval_time, 1),
                    learning_curve_eval={"freq": eval_freq, "episodes": eval_episodes,
                                         "seeds": f"{EVAL_SEED0}..{EVAL_SEED0 + eval_episodes - 1}"}
                    if curve is not None else None,
                    command=f"python -m benchmarks.train_rl --env {env} --scenario {scenario} "
                            f"--algo {algo} --steps {steps} --seed {seed} "
                            f"--eval-freq {eval_freq} --eval-episodes {eval_episodes}")
    agent = RLAgent(model, metadata, venv)
    agent.save(out)
    venv.close()
    return agent


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point (see the module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--env", required=True,
                        help=f"short name {sorted(ENV_SHORT_NAMES)} or a registered env id")
    parser.add_argument("--scenario", default=None, help="env scenario (default: the env's own)")
    parser.add_argument("--algo", choices=sorted(ALGORITHMS), default="sac")
    parser.add_argument("--steps", type=int, default=100_000, help="total env steps")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None,
                        help="output dir (default benchmarks/models/<env>/<algo>)")
    parser.add_argument("--eval-freq", type=int, default=5000, help="env steps between evals")
    parser.add_argument("--eval-episodes", type=int, default=10, help="episodes per eval")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    args = parser.parse_args(argv)

    env_id = ENV_SHORT_NAMES.get(args.env, args.env)
    if env_id not in gp_envs.ENV_IDS:
        parser.error(f"unknown env {args.env!r}")
    scenario = args.scenario or gym.make(env_id).unwrapped.scenario
    short = {v: k for k, v in ENV_SHORT_NAMES.items()}[env_id]
    out = args.out or MODELS / short / args.algo
    agent = train(short, scenario, args.algo, args.steps, args.seed, out,
                  eval_freq=args.eval_freq, eval_episodes=args.eval_episodes,
                  progress=not args.no_progress)
    print(f"saved {agent} to {out} after {agent.train_time_s:.0f} s")


if __name__ == "__main__":
    main()
