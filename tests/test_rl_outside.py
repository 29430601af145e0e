"""The RL baseline on the benchmark's outside envs (:mod:`benchmarks.outside_envs`): trained
through :func:`benchmarks.controllers.make_env` with the simulator's own reward, saved under its
benchmark name and scenario, run by the benchmark's RL controllers, and refused on another env."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

import gymnasium as gym
import numpy as np

import gp_envs
from benchmarks.controllers import make_env
from benchmarks.outside_envs import pendulum_v1_model, pendulum_v1_state
from benchmarks.rl.train import latest_checkpoint, main, train
from benchmarks.trial import TrialSpec, execute
from gp_agents.rl import RLAgent, env_fingerprint

FAST = {"eval_freq": 0, "eval_episodes": 1, "progress": False, "checkpoint_freq": 0,
        "overrides": {"learning_starts": 50, "batch_size": 32, "buffer_size": 2000}}
"""A few hundred SAC steps in seconds (the learning curve: the first and last evaluation)."""


@pytest.fixture(scope="module")
def models(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A models directory with SAC trained 300 steps on pendulum-v1/light (seconds)."""
    root = tmp_path_factory.mktemp("outside_models")
    train("pendulum-v1", "light", "sac", steps=300, seed=0, out=root / "pendulum-v1" / "sac",
          **FAST)
    return root


def test_metadata_names_the_benchmark_env_and_its_own_reward(models: Path) -> None:
    meta = json.loads((models / "pendulum-v1" / "sac" / "metadata.json").read_text())
    assert meta["env_id"] == "pendulum-v1" and meta["scenario"] == "light"
    assert meta["outside_env"]["name"] == "pendulum-v1"
    assert meta["outside_env"]["fingerprint"] == env_fingerprint(make_env("pendulum-v1", "light"))
    assert meta["training_wrappers"] == [] and meta["run_config"]["reward"] == "task"
    assert meta["angle_indices"] == [0] and meta["obs_shape"] == [2]
    assert meta["training_steps"] == 300
    assert "--env pendulum-v1 --scenario light" in meta["command"]


def test_benchmark_sac_controller_runs_the_model(models: Path) -> None:
    out = execute(TrialSpec("episode", "pendulum-v1", "light", "sac", 0, max_steps=5,
                            models=str(models)))
    assert out["status"] == "ok", out["message"]
    assert out["metrics"]["steps"] == 5


def test_loaded_agent_acts_in_the_plain_env(models: Path) -> None:
    env = make_env("pendulum-v1", "light")
    agent = RLAgent.load(models / "pendulum-v1" / "sac", env)
    obs, _ = env.reset(seed=0)
    agent.reset()
    a = agent.act(obs)
    assert a.shape == (1,) and env.action_space.contains(a)


def test_loading_onto_another_model_of_the_simulator_fails(models: Path) -> None:
    # Pendulum-v1 with the correct mass as its nominal model: another "scenario"
    other = gp_envs.wrap(gym.make("Pendulum-v1"), pendulum_v1_model(1.0),
                         state=pendulum_v1_state)
    with pytest.raises(ValueError, match=r"benchmark env 'pendulum-v1' scenario 'light'.*"
                                         r"model\.params"):
        RLAgent.load(models / "pendulum-v1" / "sac", other)


def test_loading_onto_dmc_cartpole_fails(models: Path, tmp_path: Path) -> None:
    pytest.importorskip("dm_control")
    env = make_env("dmc-cartpole", "swingup")
    with pytest.raises(ValueError, match=r"trained on the benchmark env 'pendulum-v1'.*"
                                         r"simulator\.class"):
        RLAgent.load(models / "pendulum-v1" / "sac", env)
    # through the benchmark: the pendulum model placed where dmc-cartpole's is looked for
    (tmp_path / "dmc-cartpole").mkdir()
    (tmp_path / "dmc-cartpole" / "sac").symlink_to(models / "pendulum-v1" / "sac")
    out = execute(TrialSpec("episode", "dmc-cartpole", "swingup", "sac", 0, max_steps=5,
                            models=str(tmp_path)))
    assert out["status"] == "unavailable" and "does not fit this env" in out["message"]


def test_missing_model_names_the_train_command(tmp_path: Path) -> None:
    out = execute(TrialSpec("episode", "pendulum-v1", "light", "ppo", 0, max_steps=5,
                            models=str(tmp_path)))
    assert out["status"] == "unavailable"
    assert "python -m benchmarks.rl.train --env pendulum-v1 --algo ppo" in out["message"]


@pytest.mark.parametrize("shaping", [{"reward": "bounded-shift"}, {"goal_bonus": 1.0}])
def test_training_reward_wrappers_are_refused(shaping: dict, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="outside simulator: its reward is its own"):
        train("pendulum-v1", "light", "sac", steps=10, seed=0, out=tmp_path, **FAST, **shaping)
    with pytest.raises(SystemExit):
        flag = (["--reward", "bounded-shift"] if "reward" in shaping
                else ["--goal-bonus", "1"])
        main(["--env", "pendulum-v1", "--steps", "10", "--out", str(tmp_path), *flag])


def test_interrupted_run_resumes_to_the_total(tmp_path: Path) -> None:
    kw = {**FAST, "checkpoint_freq": 100}
    train("pendulum-v1", "light", "sac", steps=250, seed=1, out=tmp_path, stop_after=150, **kw)
    ckpt = latest_checkpoint(tmp_path / "checkpoints")
    assert ckpt is not None and not (tmp_path / "metadata.json").exists()
    agent = train("pendulum-v1", "light", "sac", steps=250, seed=1, out=tmp_path, **kw)
    assert agent.training_steps == 250
    meta = json.loads((tmp_path / "metadata.json").read_text())
    assert [s["from_steps"] for s in meta["sessions"]] == [0, 150]
    obs = np.zeros(2, np.float32)
    loaded = RLAgent.load(tmp_path, make_env("pendulum-v1", "light"))
    np.testing.assert_array_equal(loaded.act(obs), agent.act(obs))


def test_the_shipped_dmc_baseline_runs_on_its_env_only() -> None:
    """The own-env preset's SAC (benchmarks/models/dmc-cartpole/sac) loads onto the wrapped DMC
    cart-pole at action repeat 5 and refuses the friction scenario (another simulator)."""
    pytest.importorskip("dm_control")
    ok = execute(TrialSpec("episode", "dmc-cartpole", "swingup", "sac", 2000, max_steps=5))
    assert ok["status"] == "ok", ok.get("message")
    other = execute(TrialSpec("episode", "dmc-cartpole", "swingup-friction", "sac", 2000,
                              max_steps=5))
    assert other["status"] == "unavailable" and "dof_frictionloss" in other["message"]
