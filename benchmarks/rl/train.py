"""Train an SB3 baseline (SAC, PPO, TQC) on a registered ``gp_envs`` env or a benchmark's
outside env, resumably; save an RLAgent.

The env is made with ``gym.make`` (same reward, same time limit as every other controller); the
agent's preprocessing (:mod:`gp_agents.rl`: angle -> cos/sin, optional time feature,
VecNormalize, action rescaling to ``[-1, 1]``) is applied by wrappers around it and saved with
the model. Optional training-only reward wrappers (``--reward bounded-shift``, ``--goal-bonus``)
change what the learner is rewarded with, never what it is evaluated on; they are recorded in
the model's ``metadata.json`` under ``training_wrappers``.

Learning curve: every ``--eval-freq`` env steps the current policy runs ``--eval-episodes``
deterministic episodes on a separate, plain ``gym.make(id, scenario=...)`` env (reset seeds
1000, 1001, ...: disjoint from the final evaluation's 0..19); success rate, mean cost
(``-return`` on the plain env) and mean final distance go to ``learning_curve.csv`` in ``--out``.

Resumable: every ``--checkpoint-freq`` env steps (and at ``--stop-after`` and at the end) a
checkpoint is written atomically to ``<out>/checkpoints/``: the model with its optimizers, the
replay buffer (off-policy algorithms), the VecNormalize statistics, the training envs' state
(mid-episode), the RNG states (Python, NumPy, torch, the action space) and the progress (env
steps, learning-curve rows, wall time). Re-running the same command resumes from the last
checkpoint and trains to the same total ``--steps``; a larger ``--steps`` extends a finished
run. Training runs in chunks between evaluation and checkpoint points (``model.learn(...,
reset_num_timesteps=False)``), at whole rollouts (SAC: ``train_freq`` steps, PPO: ``n_steps *
n_envs``), so a resumed run continues the same sequence of samples and updates as an
uninterrupted one: same seed, same command -> the same learning curve and weights
(``tests/test_rl.py`` checks it). Learning-rate schedules must be constant for that (progress
is counted per chunk).

Hyperparameter presets (``--hyperparams``, recorded with the model) start from
rl-baselines3-zoo's tuned settings; deviations are listed in :data:`HYPERPARAMETERS`.

``--env`` takes every registered system (:data:`gp_envs.SYSTEMS`): the built-in ones and those
of installed packages that declare their system module in the entry-point group
``gp_envs.systems`` (``[project.entry-points."gp_envs.systems"]`` in the package's
``pyproject.toml``, e.g. ``mysystem = "mypkg.mysystem_env"``; ``docs/guide/own-system.md``).
Then ``gp-bench --envs mysystem --controllers nominal-mpc,sac`` runs the model this saved.

``--env`` also takes the benchmark's outside envs (:data:`benchmarks.outside_envs.OUTSIDE_ENVS`:
``pendulum-v1``, ``dmc-cartpole``): Gymnasium/DeepMind Control simulators seen through a nominal
model (:func:`gp_envs.wrap`), made by :func:`benchmarks.controllers.make_env` for training,
learning-curve evaluation and the benchmark alike. Their reward is the simulator's own (DMC: 0-1
per physics step, summed over the action repeat): ``--reward bounded-shift`` and ``--goal-bonus``
(which rewrite a ``gp_envs`` env's termination penalty and goal) are refused. The model's
metadata names the env by benchmark name (``env_id``) and scenario and records its
:func:`gp_agents.rl.env_fingerprint`. Their simulators' state is not saved in checkpoints (DMC's
does not pickle): a resumed run restarts the interrupted training episode (reset seed ``seed +
env steps``), so it is not bit-identical to an uninterrupted one as a ``gp_envs`` run is::

    python -m benchmarks.rl.train --env dmc-cartpole --scenario swingup --algo sac \\
        --steps 20000 --seed 0

Run (one core)::

    python -m benchmarks.rl.train --env cartpole --scenario online --algo sac \\
        --hyperparams sac-swingup --reward bounded-shift --time-feature \\
        --steps 300000 --seed 0 --out benchmarks/models/runs/cartpole_online_sac/seed0

Writes to ``--out`` (default ``./benchmarks/models/<env-short-name>/<algo>/`` under the current
directory, where ``gp-bench`` looks for RL models before the shipped ones): ``model.zip``,
``vecnormalize.pkl``, ``metadata.json`` (hyperparameters, wrappers, seed, steps, wall-clock time,
the command) and ``learning_curve.csv`` at the end, ``learning_curve.csv`` after every
evaluation, ``best/`` (the policy of the learning curve's best evaluation, :func:`better`, saved
as an agent with its row under ``best_of_learning_curve`` in its metadata: evaluate it on other
seeds) and ``checkpoints/`` (not for version control).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse
import copy
import csv
import datetime as dt
import json
import pickle
import random
import shlex
import shutil
import sys
import time
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.vec_env import VecNormalize

from benchmarks import USER_MODELS_DIR
from gp_agents.agent import rollout
from gp_agents.rl import (
    ALGORITHMS,
    METADATA_FILE,
    RLAgent,
    episode_limit,
    get_env_state,
    make_training_vec_env,
    set_env_state,
    training_wrappers_record,
)
from gp_envs.systems import SYSTEMS

REPO = Path(__file__).resolve().parents[2]


class _EnvIds(Mapping[str, str]):
    """The registered systems' env ids by system name (live, as :data:`gp_envs.SYSTEMS`)."""

    def __getitem__(self, name: str) -> str:
        return SYSTEMS[name].env_id

    def __iter__(self) -> Iterator[str]:
        return iter(SYSTEMS)

    def __len__(self) -> int:
        return len(SYSTEMS)


ENV_SHORT_NAMES: Mapping[str, str] = _EnvIds()
"""``--env`` short names (the registered systems' names, also the model directory names) ->
registered env ids: every system of :data:`gp_envs.SYSTEMS`, plugins included."""

ENTRY_POINT_HELP = ('a system of your own: declare the module that calls '
                    'gp_envs.register_system under [project.entry-points."gp_envs.systems"] in '
                    'your package\'s pyproject.toml and install the package (see '
                    'docs/guide/own-system.md)')
"""How a user's system becomes an ``--env`` (for the help and the unknown-env message)."""


def outside_env_names() -> list[str]:
    """The benchmark's outside envs (:data:`benchmarks.outside_envs.OUTSIDE_ENVS`, live)."""
    from benchmarks.outside_envs import OUTSIDE_ENVS

    return list(OUTSIDE_ENVS)


def _is_outside(env_id: str) -> bool:
    return env_id not in ENV_SHORT_NAMES and env_id in outside_env_names()


def _env_maker(config: Mapping[str, Any]) -> Callable[[], gym.Env]:
    """Makes the run's env: ``gym.make(id, scenario=...)``, or for an outside env
    :func:`benchmarks.controllers.make_env` of its benchmark name and scenario."""
    env_id, scenario = config["env_id"], config["scenario"]
    if config.get("outside_env"):
        from benchmarks.controllers import make_env

        return lambda: make_env(env_id, scenario)
    return lambda: gym.make(env_id, scenario=scenario)


EVAL_SEED0 = 1000
"""First reset seed of the learning-curve evaluation episodes (final evaluation: 0..19)."""

REWARDS = ("task", "bounded-shift")
"""``--reward`` choices: the env's own reward, or :class:`gp_agents.rl.BoundedShiftReward`."""

HYPERPARAMETERS: dict[str, dict[str, Any]] = {
    # rl-baselines3-zoo sac.yml, Pendulum-v1: learning_rate 1e-3, everything else SB3 defaults
    # (written out here so the record is complete), except the network: [64, 64] as in zoo's
    # MountainCarContinuous-v0 entry instead of [256, 256], ~2x more steps per CPU second.
    # (The shipped benchmarks/models/<env>/sac models were trained with it.)
    "sac": {
        "algo": "sac",
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
    # rl-baselines3-zoo sac.yml, InvertedPendulumSwingupBulletEnv-v0 (the pybullet-defaults
    # anchor, n_timesteps 3e5): the zoo's tuned entry closest to this cart-pole swing-up.
    # Deviation: net_arch [64, 64] instead of [400, 300]; measured on this machine (2 cores,
    # contended) 60 vs 25 steps/s, i.e. 2.4x faster, which decides whether 5 seeds x 3e5 steps
    # fit. Addition: observation normalization (the zoo entry has none; the cart pole's
    # velocities reach 10 m/s and 25 rad/s).
    "sac-swingup": {
        "algo": "sac",
        "source": "rl-baselines3-zoo hyperparams/sac.yml InvertedPendulumSwingupBulletEnv-v0 "
                  "(pybullet-defaults: lr 7.3e-4, buffer 3e5, batch 256, ent_coef auto, gamma "
                  "0.98, tau 0.02, train_freq 8, gradient_steps 8, learning_starts 1e4, gSDE, "
                  "log_std_init -3, net_arch [400, 300]; n_timesteps 3e5); changes: net_arch "
                  "[64, 64] (2.4x faster on this CPU); additions: obs normalization "
                  "(VecNormalize), angle cos/sin features",
        "n_envs": 1,
        "norm_obs": True,
        "norm_reward": False,
        "learning_rate": 7.3e-4,
        "buffer_size": 300_000,
        "learning_starts": 10_000,
        "batch_size": 256,
        "tau": 0.02,
        "gamma": 0.98,
        "train_freq": 8,
        "gradient_steps": 8,
        "ent_coef": "auto",
        "use_sde": True,
        "policy_kwargs": {"log_std_init": -3, "net_arch": [64, 64]},
    },
    # rl-baselines3-zoo ppo.yml, Pendulum-v1 (n_envs 4, n_steps 1024, lr 1e-3, gSDE) with
    # zoo's usual `normalize: true`; gamma 0.99 instead of Pendulum's 0.9 because these
    # episodes are 120-150 steps and the termination penalty must be seen well ahead.
    "ppo": {
        "algo": "ppo",
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
"""Hyperparameter presets: SB3 constructor arguments plus env-side settings (:data:`_ENV_SIDE`)."""

# the same zoo entry with its own network, [400, 300]: the sweep's check that the [64, 64]
# deviation does not cripple the baseline (plan sweep_cartpole_zoo_net)
HYPERPARAMETERS["sac-swingup-zoo-net"] = {
    **HYPERPARAMETERS["sac-swingup"],
    "source": "rl-baselines3-zoo hyperparams/sac.yml InvertedPendulumSwingupBulletEnv-v0 as "
              "sac-swingup, with the entry's own net_arch [400, 300]; additions: obs "
              "normalization (VecNormalize), angle cos/sin features",
    "policy_kwargs": {"log_std_init": -3, "net_arch": [400, 300]},
}

# rl-baselines3-zoo tqc.yml, InvertedPendulumSwingupBulletEnv-v0 (n_timesteps 3e5; TQC's
# defaults: 2 critics of 25 quantiles, the top 2 per net dropped), with sac-swingup's declared
# deviation (net_arch [64, 64] instead of [400, 300]) and additions; the zoo's TQC entry
# differs from its SAC one in train_freq and gradient_steps (64 against 8).
HYPERPARAMETERS["tqc-swingup"] = {
    **HYPERPARAMETERS["sac-swingup"],
    "algo": "tqc",
    "source": "rl-baselines3-zoo hyperparams/tqc.yml InvertedPendulumSwingupBulletEnv-v0 "
              "(lr 7.3e-4, buffer 3e5, batch 256, ent_coef auto, gamma 0.98, tau 0.02, "
              "train_freq 64, gradient_steps 64, learning_starts 1e4, gSDE, log_std_init -3, "
              "net_arch [400, 300]; n_timesteps 3e5; TQC defaults otherwise); changes: "
              "net_arch [64, 64] (as sac-swingup); additions: obs normalization "
              "(VecNormalize), angle cos/sin features",
    "train_freq": 64,
    "gradient_steps": 64,
}

_ENV_SIDE = ("algo", "source", "n_envs", "norm_obs", "norm_reward")

CURVE_FIELDS = ("timesteps", "wall_time_s", "success_rate", "mean_cost", "std_cost",
                "mean_final_distance", "success_any_rate", "terminated_rate", "mean_length",
                "mean_return", "std_return")
"""Columns of ``learning_curve.csv``: env steps trained, training wall time so far (s, summed
over sessions, evaluations included, work lost to interruptions not counted), success rate,
mean/std cost (``-return`` on the plain env), mean final ``info["distance_to_goal"]``, the
fraction with success at some step, the fraction terminated early, mean episode length (steps)
and mean/std return (``= -cost``, kept for older readers)."""

CHECKPOINTS = "checkpoints"
LATEST = "LATEST"
CURVE_FILE = "learning_curve.csv"
BEST = "best"
"""Subdirectory of a run with its best learning-curve policy (:func:`better`), saved as an
agent at the evaluation that found it (SB3's ``EvalCallback(best_model_save_path=...)``)."""


def better(stats: Mapping[str, float], best: Mapping[str, float] | None) -> bool:
    """True: learning-curve ``stats`` beat ``best`` (None: nothing yet): a higher success rate,
    or the same and a lower mean cost. The evaluation's reset seeds choose the policy, so a
    best policy is judged on other seeds (the benchmark's, a study's final seeds)."""
    if best is None:
        return True
    if stats["success_rate"] != best["success_rate"]:
        return stats["success_rate"] > best["success_rate"]
    return stats["mean_cost"] < best["mean_cost"]


BEST_RULE = "highest success rate, then lowest mean cost"


def best_record(out: Path) -> dict[str, Any] | None:
    """The learning-curve row (with its seeds and :data:`BEST_RULE`) of the best policy saved in
    ``out``/:data:`BEST`, or None. A resumed run compares with it: a ``gp_envs`` run redoes the
    evaluations after its checkpoint identically, so the policy on disk is the one it finds
    again; an outside env's is the best one seen."""
    meta = out / BEST / METADATA_FILE
    if not meta.is_file():
        return None
    return json.loads(meta.read_text()).get("best_of_learning_curve")


def log(msg: str) -> None:
    """Print ``msg`` with a UTC time stamp (flushed: logs are read while training runs)."""
    print(f"[{dt.datetime.now(dt.UTC):%Y-%m-%d %H:%M:%S}Z] {msg}", flush=True)


# --------------------------------------------------------------------------- evaluation
def evaluate_policy(agent: RLAgent, env: gym.Env, seeds: range) -> dict[str, float]:
    """Deterministic episodes of ``agent`` on the plain ``env``, one per reset seed.

    Returns:
        The :data:`CURVE_FIELDS` statistics except ``timesteps`` and ``wall_time_s``.
    """
    eps = [rollout(env, agent, s).summary() for s in seeds]
    rets = np.array([e["return"] for e in eps])
    return {"success_rate": float(np.mean([e["success"] for e in eps])),
            "mean_cost": float(-rets.mean()), "std_cost": float(rets.std()),
            "mean_final_distance": float(np.mean([e["final_distance"] for e in eps])),
            "success_any_rate": float(np.mean([e["success_any"] for e in eps])),
            "terminated_rate": float(np.mean([e["end"] != "time limit" for e in eps])),
            "mean_length": float(np.mean([e["length"] for e in eps])),
            "mean_return": float(rets.mean()), "std_return": float(rets.std())}


def write_curve(path: Path, rows: list[dict[str, float]]) -> None:
    """Write ``rows`` (:data:`CURVE_FIELDS`) to ``path`` atomically (temp file + rename)."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=CURVE_FIELDS)
        writer.writeheader()
        writer.writerows(rows)
    tmp.replace(path)


def quiet_logger(model: BaseAlgorithm) -> BaseAlgorithm:
    """Give ``model`` a logger without outputs; returns ``model``.

    Without a logger of its own, every ``model.learn`` call configures SB3's default one, which
    creates an empty folder ``SB3-<date-time>`` in the system temp directory even when it writes
    nothing (``verbose=0``): one per training chunk. The learning curve is this script's own
    (``learning_curve.csv``). A loaded model needs it again (SB3 does not save the logger).
    """
    model.set_logger(Logger(folder=None, output_formats=[]))
    return model


# --------------------------------------------------------------------------- checkpoints
def rollout_unit(model: BaseAlgorithm) -> int:
    """Env steps one ``learn`` iteration advances by (training runs in whole units)."""
    n_envs = model.n_envs
    if isinstance(model, OffPolicyAlgorithm):
        return int(model.train_freq.frequency) * n_envs  # TrainFreq in steps (checked below)
    return int(model.n_steps) * n_envs


def _rng_state(model: BaseAlgorithm) -> dict[str, Any]:
    return {"python": random.getstate(), "numpy": np.random.get_state(),
            "torch": torch.get_rng_state(),
            "action_space": copy.deepcopy(model.action_space.np_random)}


def _set_rng_state(model: BaseAlgorithm, state: dict[str, Any]) -> None:
    random.setstate(state["python"])
    np.random.set_state(state["numpy"])
    torch.set_rng_state(state["torch"])
    model.action_space._np_random = copy.deepcopy(state["action_space"])


def save_checkpoint(ckpt_root: Path, model: BaseAlgorithm, venv: VecNormalize,
                    progress: dict[str, Any]) -> Path:
    """Write a checkpoint of the running training atomically; returns its directory.

    The checkpoint is assembled in ``ckpt_<steps>.tmp``, renamed to ``ckpt_<steps>``, then
    ``LATEST`` is replaced (temp file + rename) to name it, and older checkpoints are removed.
    A process killed at any point leaves ``LATEST`` naming a complete checkpoint (or none yet).
    """
    ckpt_root.mkdir(parents=True, exist_ok=True)
    name = f"ckpt_{model.num_timesteps:010d}"
    tmp = ckpt_root / f"{name}.tmp"
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir()
    model.save(tmp / "model.zip")  # SB3 excludes the replay buffer from it
    if isinstance(model, OffPolicyAlgorithm):
        model.save_replay_buffer(tmp / "replay_buffer.pkl")
    venv.save(str(tmp / "vecnormalize.pkl"))
    outside = progress["config"].get("outside_env", False)  # its simulator does not pickle
    state = {"rng": _rng_state(model), "vecnorm_returns": np.array(venv.returns, copy=True),
             "env_states": None if outside else [get_env_state(e) for e in venv.venv.envs]}
    with open(tmp / "state.pkl", "wb") as fh:
        pickle.dump(state, fh)
    (tmp / "progress.json").write_text(json.dumps(progress, indent=1) + "\n")
    for f in tmp.iterdir():
        with open(f, "rb") as fh:
            os.fsync(fh.fileno())
    final = ckpt_root / name
    if final.exists():
        shutil.rmtree(final)
    tmp.rename(final)
    pointer = ckpt_root / f"{LATEST}.tmp"
    pointer.write_text(name + "\n")
    pointer.replace(ckpt_root / LATEST)
    for old in ckpt_root.glob("ckpt_*"):
        if old.name != name:
            shutil.rmtree(old, ignore_errors=True)
    return final


def latest_checkpoint(ckpt_root: Path) -> Path | None:
    """The checkpoint ``LATEST`` names, or None if there is none."""
    pointer = ckpt_root / LATEST
    if not pointer.is_file():
        return None
    path = ckpt_root / pointer.read_text().strip()
    return path if (path / "progress.json").is_file() else None


def restore_checkpoint(path: Path, config: dict[str, Any]) -> tuple[BaseAlgorithm, VecNormalize]:
    """Rebuild model and training env from checkpoint ``path`` (see :func:`save_checkpoint`)."""
    venv_fresh = _make_venv(config)
    inner = venv_fresh.venv
    venv = VecNormalize.load(str(path / "vecnormalize.pkl"), inner)
    with open(path / "state.pkl", "rb") as fh:
        state = pickle.load(fh)
    outside = state["env_states"] is None  # an outside env: its episode restarts
    if not outside:
        for env, st in zip(inner.envs, state["env_states"], strict=True):
            set_env_state(env, st)
    venv.returns = np.array(state["vecnorm_returns"], copy=True)
    # force_reset=False keeps the saved mid-episode observation (SB3 resets by default)
    model = ALGORITHMS[config["algo"]].load(path / "model.zip", env=venv, device="cpu",
                                            force_reset=outside)
    if isinstance(model, OffPolicyAlgorithm):
        model.load_replay_buffer(path / "replay_buffer.pkl")
    if outside:  # the restarted episode: a reset seed of its own, not the run's first one
        inner.seed(int(config["seed"]) + int(model.num_timesteps))
    else:
        inner._reset_seeds()  # load() re-seeded the VecEnv's next reset; it must not apply
    _set_rng_state(model, state["rng"])
    return quiet_logger(model), venv


# --------------------------------------------------------------------------- training
def _make_venv(config: dict[str, Any]) -> VecNormalize:
    hp = config["hyperparameters"]
    return make_training_vec_env(config["env_id"], config["scenario"], config["seed"],
                                 n_envs=hp["n_envs"], norm_obs=hp["norm_obs"],
                                 norm_reward=hp["norm_reward"], gamma=hp["gamma"],
                                 reward_shift=config["reward"] == "bounded-shift",
                                 goal_bonus=config["goal_bonus"],
                                 time_feature_on=config["time_feature"],
                                 make_env=_env_maker(config) if config.get("outside_env")
                                 else None)


def _normalized(x: Any) -> Any:
    return json.loads(json.dumps(x))


def _command(config: dict[str, Any], steps: int, out: Path) -> str:
    short = {v: k for k, v in ENV_SHORT_NAMES.items()}.get(config["env_id"], config["env_id"])
    try:
        where = out.resolve().relative_to(REPO)
    except ValueError:
        where = out
    parts = ["python", "-m", "benchmarks.rl.train", "--env", short, "--scenario",
             config["scenario"], "--algo", config["algo"], "--hyperparams", config["hp_name"],
             "--reward", config["reward"], "--steps", str(steps), "--seed", str(config["seed"]),
             "--eval-freq", str(config["eval_freq"]), "--eval-episodes",
             str(config["eval_episodes"]), "--checkpoint-freq", str(config["checkpoint_freq"])]
    if config["goal_bonus"]:
        parts += ["--goal-bonus", f"{config['goal_bonus']:g}"]
    if config["time_feature"]:
        parts.append("--time-feature")
    parts += ["--out", str(where)]
    return shlex.join(parts)


def train(env: str, scenario: str, algo: str, steps: int, seed: int, out: Path,
          eval_freq: int = 5000, eval_episodes: int = 20, progress: bool = True,
          overrides: dict[str, Any] | None = None, checkpoint_freq: int = 10_000,
          stop_after: int | None = None, hyperparams: str | None = None, reward: str = "task",
          goal_bonus: float = 0.0, time_feature: bool = False, fresh: bool = False,
          echo: Callable[[str], None] = log) -> RLAgent:
    """Train (or resume, or extend) a run to ``steps`` env steps; save it to ``out``.

    Args:
        env: short name (:data:`ENV_SHORT_NAMES`) or registered env id, or the name of a
            benchmark's outside env (:func:`outside_env_names`; trained through
            :func:`benchmarks.controllers.make_env`, with its own reward).
        scenario: the env's scenario.
        algo: a key of :data:`gp_agents.rl.ALGORITHMS` (``"sac"``, ``"ppo"``, ``"tqc"``).
        steps: total env steps (summed over sub-envs; rounded up to whole rollouts).
        seed: seeds the model (torch, numpy) and the training envs' resets.
        out: run directory (model, metadata, learning curve, ``checkpoints/``).
        eval_freq: env steps between learning-curve evaluations (0: only start and end).
        eval_episodes: episodes per evaluation (reset seeds ``EVAL_SEED0..``; 0: no curve).
        progress: log a line per training chunk.
        overrides: hyperparameter overrides (keys of the preset).
        checkpoint_freq: env steps between checkpoints (0: only at stop and end).
        stop_after: write a checkpoint and return once this many env steps are trained, before
            ``steps`` (an interruption on purpose; the run is not finalized).
        hyperparams: preset name in :data:`HYPERPARAMETERS` (default: ``algo``).
        reward: ``"task"`` or ``"bounded-shift"`` (training reward; see :data:`REWARDS`;
            an outside env: ``"task"`` only, its own reward).
        goal_bonus: training-only bonus per second inside the goal tolerance (0: none; an
            outside env: 0 only).
        time_feature: append the time feature to the policy's input.
        fresh: discard ``out``'s checkpoints and start over.
        echo: where progress messages go.

    Returns:
        The agent (the final one, saved to ``out``, or the running one at ``stop_after``).

    Raises:
        ValueError: bad arguments (also a training reward wrapper for an outside env), or a
            checkpoint / saved run in ``out`` with another configuration or past ``steps``.
    """
    torch.set_num_threads(1)
    env_id = ENV_SHORT_NAMES.get(env, env)
    if algo not in ALGORITHMS:
        raise ValueError(f"unknown algo {algo!r}; choose one of {sorted(ALGORITHMS)}")
    hp_name = hyperparams or algo
    if hp_name not in HYPERPARAMETERS:
        raise ValueError(f"unknown hyperparameter preset {hp_name!r}; known: "
                         f"{sorted(HYPERPARAMETERS)}")
    hp = copy.deepcopy(HYPERPARAMETERS[hp_name])
    if hp["algo"] != algo:
        raise ValueError(f"preset {hp_name!r} is for {hp['algo']}, not {algo}")
    hp.update(overrides or {})
    if reward not in REWARDS:
        raise ValueError(f"reward must be one of {REWARDS}, got {reward!r}")
    if steps <= 0 or eval_freq < 0 or eval_episodes < 0 or checkpoint_freq < 0:
        raise ValueError("steps must be > 0 and the frequencies/episodes >= 0")
    if not isinstance(hp["learning_rate"], float | int):
        raise ValueError("chunked training needs a constant learning rate")
    outside = _is_outside(env_id)
    if outside and (reward != "task" or goal_bonus):
        raise ValueError(f"env {env_id} is an outside simulator: its reward is its own (no "
                         f"termination penalty to replace, no goal bonus); --reward "
                         f"bounded-shift and --goal-bonus apply to gp_envs systems only, "
                         f"train it with --reward task")
    config = _normalized({
        "env_id": env_id, "scenario": scenario, "algo": algo, "hp_name": hp_name,
        "hyperparameters": hp, "seed": seed, "reward": reward, "goal_bonus": float(goal_bonus),
        "time_feature": bool(time_feature), "eval_freq": eval_freq,
        "eval_episodes": eval_episodes, "checkpoint_freq": checkpoint_freq,
        "eval_seeds": f"{EVAL_SEED0}..{EVAL_SEED0 + eval_episodes - 1}",
        **({"outside_env": True} if outside else {})})
    make = _env_maker(config)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ckpt_root = out / CHECKPOINTS
    if fresh:
        shutil.rmtree(ckpt_root, ignore_errors=True)
        shutil.rmtree(out / BEST, ignore_errors=True)
        for f in ("model.zip", "vecnormalize.pkl", METADATA_FILE, CURVE_FILE):
            (out / f).unlink(missing_ok=True)
    probe = make()

    # a finished run with this configuration?
    meta_file = out / METADATA_FILE
    if meta_file.is_file():
        meta = json.loads(meta_file.read_text())
        if meta.get("run_config") != config:
            raise ValueError(f"{out} holds a model trained with another configuration "
                             f"(or an older script); use another --out or --fresh")
        if meta["training_steps"] >= steps:
            echo(f"{out}: already trained to {meta['training_steps']} >= {steps} steps")
            agent = RLAgent.load(out, probe)
            probe.close()
            return agent

    ckpt = latest_checkpoint(ckpt_root)
    if ckpt is not None:
        prog = json.loads((ckpt / "progress.json").read_text())
        if prog["config"] != config:
            raise ValueError(f"checkpoint {ckpt} was written with another configuration; "
                             "run the same command (or --fresh)")
        if prog["timesteps"] > steps:
            raise ValueError(f"checkpoint {ckpt} is at {prog['timesteps']} > --steps {steps}")
        model, venv = restore_checkpoint(ckpt, config)
        rows, elapsed, eval_time = prog["rows"], prog["elapsed_s"], prog["eval_time_s"]
        best = best_record(out)
        sessions = [*prog["sessions"], {"start_utc": f"{dt.datetime.now(dt.UTC):%FT%TZ}",
                                        "from_steps": model.num_timesteps}]
        echo(f"resuming {ckpt} at {model.num_timesteps} env steps")
    else:
        if meta_file.is_file():
            raise ValueError(f"{out} has a finished model but no checkpoint to extend it from")
        venv = _make_venv(config)
        sb3_kwargs = {k: v for k, v in copy.deepcopy(hp).items() if k not in _ENV_SIDE}
        model = quiet_logger(ALGORITHMS[algo]("MlpPolicy", venv, seed=seed, device="cpu",
                                              verbose=0, **sb3_kwargs))
        rows, elapsed, eval_time, best = [], 0.0, 0.0, None
        shutil.rmtree(out / BEST, ignore_errors=True)
        sessions = [{"start_utc": f"{dt.datetime.now(dt.UTC):%FT%TZ}", "from_steps": 0}]
    if isinstance(model, OffPolicyAlgorithm) and model.train_freq.unit.value != "step":
        raise ValueError("train_freq must count steps")

    wrappers = training_wrappers_record(probe, reward == "bounded-shift", goal_bonus,
                                        time_feature)
    metadata = RLAgent.metadata_for(
        probe, algo, outside_env=(env_id, scenario) if outside else None, seed=seed,
        hyperparameters=hp, hyperparameter_preset=hp_name,
        training_steps=int(model.num_timesteps), training_wrappers=wrappers,
        time_feature_max_steps=episode_limit(probe) if time_feature else None,
        run_config=config)
    eval_env = make()
    eval_seeds = range(EVAL_SEED0, EVAL_SEED0 + eval_episodes)
    curve_path = out / CURVE_FILE
    unit = rollout_unit(model)
    t_session = time.perf_counter()

    def wall() -> float:
        return elapsed + time.perf_counter() - t_session

    def evaluate() -> None:
        nonlocal eval_time, best
        if eval_episodes == 0:
            return
        t = time.perf_counter()
        agent = RLAgent(model, metadata, model.get_vec_normalize_env())
        stats = evaluate_policy(agent, eval_env, eval_seeds)
        rows.append({"timesteps": int(model.num_timesteps), "wall_time_s": round(wall(), 2),
                     **stats})
        write_curve(curve_path, rows)
        if better(stats, best):
            best = {"seeds": config["eval_seeds"], **rows[-1], "rule": BEST_RULE}
            RLAgent(model, dict(metadata, training_steps=int(model.num_timesteps),
                                train_time_s=rows[-1]["wall_time_s"],
                                best_of_learning_curve=best),
                    model.get_vec_normalize_env()).save(out / BEST)
        eval_time += time.perf_counter() - t
        if progress:
            echo(f"  eval @ {model.num_timesteps}: success {stats['success_rate']:.2f}  cost "
                 f"{stats['mean_cost']:.2f}  final distance {stats['mean_final_distance']:.3f}"
                 f"  terminated {stats['terminated_rate']:.2f}")

    def next_multiple(freq: int) -> int:
        return (model.num_timesteps // freq + 1) * freq if freq > 0 else steps

    def checkpoint() -> None:
        save_checkpoint(ckpt_root, model, venv, {
            "config": config, "timesteps": int(model.num_timesteps), "rows": rows,
            "elapsed_s": wall(), "eval_time_s": eval_time, "sessions": sessions})

    if model.num_timesteps == 0 and not rows:
        evaluate()
    else:  # the curve file as of the checkpoint (rows written after it are redone)
        write_curve(curve_path, rows)
    next_eval, next_ckpt = next_multiple(eval_freq), next_multiple(checkpoint_freq)
    stop = steps if stop_after is None else min(stop_after, steps)
    while model.num_timesteps < stop:
        target = min(next_eval, next_ckpt, steps, stop)
        t0, n0 = time.perf_counter(), model.num_timesteps
        model.learn(total_timesteps=max(target - model.num_timesteps, 1),
                    reset_num_timesteps=False)
        if progress:
            rate = (model.num_timesteps - n0) / max(time.perf_counter() - t0, 1e-9)
            echo(f"{model.num_timesteps}/{steps} env steps ({rate:.0f} steps/s, unit {unit})")
        if model.num_timesteps >= next_eval or model.num_timesteps >= steps:
            if not rows or rows[-1]["timesteps"] != model.num_timesteps:
                evaluate()
            next_eval = next_multiple(eval_freq)
        if model.num_timesteps >= next_ckpt or model.num_timesteps >= stop:
            checkpoint()
            next_ckpt = next_multiple(checkpoint_freq)
            if progress:
                echo(f"  checkpoint @ {model.num_timesteps}")

    done = model.num_timesteps >= steps
    wall_total = wall()
    metadata.update(
        training_steps=int(model.num_timesteps), train_time_s=round(wall_total, 1),
        train_time_excluding_eval_s=round(wall_total - eval_time, 1),
        learning_curve_eval={"freq": eval_freq, "episodes": eval_episodes,
                             "seeds": config["eval_seeds"]} if eval_episodes else None,
        sessions=sessions, command=_command(config, steps, out))
    agent = RLAgent(model, metadata, venv)
    if done:
        agent.save(out)
        echo(f"saved {agent} to {out} after {wall_total:.0f} s")
    else:
        echo(f"stopped at {model.num_timesteps} env steps (checkpoint in {ckpt_root})")
    eval_env.close()
    probe.close()
    return agent


def main(argv: list[str] | None = None) -> None:
    """Command-line entry point (see the module docstring)."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog=f"--env: every registered system; {ENTRY_POINT_HELP}; or an outside env "
               f"({', '.join(outside_env_names())}; its own reward). Then gp-bench --envs NAME "
               "--controllers nominal-mpc,ALGO runs the saved model (it looks in "
               f"./{USER_MODELS_DIR} before the shipped models).")
    parser.add_argument("--env", required=True,
                        help=f"a registered system's name {sorted(ENV_SHORT_NAMES)} or its env "
                             "id (see below for your own system), or an outside env "
                             f"{outside_env_names()}")
    parser.add_argument("--scenario", default=None, help="env scenario (default: the env's own)")
    parser.add_argument("--algo", choices=sorted(ALGORITHMS), default="sac")
    parser.add_argument("--hyperparams", choices=sorted(HYPERPARAMETERS), default=None,
                        help="hyperparameter preset (default: the algo's name)")
    parser.add_argument("--steps", type=int, default=100_000, help="total env steps")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None,
                        help=f"run dir (default ./{USER_MODELS_DIR}/<env>/<algo> under the "
                             "current directory, where gp-bench finds it)")
    parser.add_argument("--eval-freq", type=int, default=5000, help="env steps between evals")
    parser.add_argument("--eval-episodes", type=int, default=20, help="episodes per eval")
    parser.add_argument("--checkpoint-freq", type=int, default=10_000,
                        help="env steps between checkpoints")
    parser.add_argument("--stop-after", type=int, default=None,
                        help="checkpoint and exit after this many env steps (resume later)")
    parser.add_argument("--reward", choices=REWARDS, default="task",
                        help="training reward: the task's, or the bounded shift")
    parser.add_argument("--goal-bonus", type=float, default=0.0,
                        help="training-only bonus per second inside the goal tolerance")
    parser.add_argument("--time-feature", action="store_true",
                        help="append the time feature (1 - t/T) to the policy input")
    parser.add_argument("--fresh", action="store_true", help="discard checkpoints, start over")
    parser.add_argument("--no-progress", action="store_true", help="no per-chunk log lines")
    args = parser.parse_args(argv)

    env_id = ENV_SHORT_NAMES.get(args.env, args.env)
    short = {v: k for k, v in ENV_SHORT_NAMES.items()}.get(env_id)
    if short is None and _is_outside(args.env):
        from benchmarks.outside_envs import OUTSIDE_ENVS

        short = args.env
        scenario = args.scenario or OUTSIDE_ENVS[short].default_scenario
        if scenario not in OUTSIDE_ENVS[short].scenarios:
            parser.error(f"unknown scenario {scenario!r} of env {short}; valid scenarios: "
                         f"{', '.join(OUTSIDE_ENVS[short].scenarios)}")
        if args.reward != "task" or args.goal_bonus:
            parser.error(f"env {short} is an outside simulator: its reward is its own; "
                         f"--reward bounded-shift and --goal-bonus apply to gp_envs systems "
                         f"only")
    elif short is None:
        parser.error(f"unknown env {args.env!r}; registered systems: "
                     f"{', '.join(ENV_SHORT_NAMES)} ({ENTRY_POINT_HELP}); outside envs: "
                     f"{', '.join(outside_env_names())}")
    else:
        scenario = args.scenario or gym.make(env_id).unwrapped.scenario
    out = args.out or USER_MODELS_DIR / short / args.algo
    log(f"pid {os.getpid()}: {shlex.join(sys.argv)}")
    train(short, scenario, args.algo, args.steps, args.seed, out, eval_freq=args.eval_freq,
          eval_episodes=args.eval_episodes, progress=not args.no_progress,
          checkpoint_freq=args.checkpoint_freq, stop_after=args.stop_after,
          hyperparams=args.hyperparams, reward=args.reward, goal_bonus=args.goal_bonus,
          time_feature=args.time_feature, fresh=args.fresh)


if __name__ == "__main__":
    main()
