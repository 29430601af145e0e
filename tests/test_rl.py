"""Tests of the RL baseline (gp_agents.rl, benchmarks.train_rl): load, act, checks, wrappers."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

import gymnasium as gym
import numpy as np

import gp_envs  # noqa: F401  (registers the envs)
from benchmarks.train_rl import train
from gp_agents.rl import AngleFeatures, NormalizedAction, RLAgent, angle_features, wrap_env

MODELS = Path(__file__).resolve().parents[1] / "benchmarks" / "models"
SHIPPED = {
    "cartpole/sac": ("gp_envs/CartPoleSwingUp-v0", "online"),
    "quadrotor/ppo": ("gp_envs/Quadrotor-v0", "online"),
    "dubins/ppo": ("gp_envs/DubinsObstacle-v0", "paper"),
}


@pytest.fixture(scope="module")
def tiny_agent(tmp_path_factory: pytest.TempPathFactory) -> tuple[RLAgent, Path]:
    """PPO trained for 256 steps on the cart pole and saved (seconds)."""
    out = tmp_path_factory.mktemp("ppo_tiny")
    agent = train("cartpole", "online", "ppo", steps=256, seed=3, out=out, eval_freq=0,
                  eval_episodes=1, progress=False,
                  overrides={"n_envs": 2, "n_steps": 64, "batch_size": 64, "n_epochs": 2})
    return agent, out


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_shipped_model_runs_plain_loop(name: str) -> None:
    env_id, scenario = SHIPPED[name]
    path = MODELS / name
    if not (path / "metadata.json").is_file():
        pytest.fail(f"shipped model {path} is missing")
    env = gym.make(env_id, scenario=scenario)
    agent = RLAgent.load(path, env)
    assert agent.env_id == env_id and agent.scenario == scenario
    assert agent.training_steps > 0 and agent.hyperparameters and agent.seed is not None
    obs, _ = env.reset(seed=0)
    agent.reset()
    for _ in range(5):
        a = agent.act(obs)
        assert a.dtype == np.float32 and a.shape == env.action_space.shape
        assert env.action_space.contains(a)
        nobs, _r, te, tr, _info = env.step(a)
        agent.observe(obs, a, nobs)
        obs = nobs
        if te or tr:
            break
    assert (path / "learning_curve.csv").is_file()


def test_load_into_mismatched_env_raises() -> None:
    path = MODELS / "cartpole" / "sac"
    with pytest.raises(ValueError, match="scenario"):
        RLAgent.load(path, gym.make("gp_envs/CartPoleSwingUp-v0", scenario="gp"))
    with pytest.raises(ValueError, match="env id"):
        RLAgent.load(path, gym.make("gp_envs/Quadrotor-v0", scenario="online"))


def test_round_trip_gives_identical_actions(tiny_agent: tuple[RLAgent, Path]) -> None:
    agent, out = tiny_agent
    env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online")
    loaded = RLAgent.load(out, env)
    assert loaded.algo == "ppo" and loaded.seed == 3
    assert loaded.training_steps == agent.training_steps == 256
    assert loaded.hyperparameters == agent.hyperparameters
    rng = np.random.default_rng(0)
    obs, _ = env.reset(seed=1)
    for _ in range(20):
        np.testing.assert_array_equal(agent.act(obs), loaded.act(obs))
        obs, _r, te, tr, _ = env.step(rng.uniform(-35, 35, size=1))
        if te or tr:
            obs, _ = env.reset()
    stochastic = loaded.act(obs, deterministic=False)
    assert stochastic.dtype == np.float32 and env.action_space.contains(stochastic)
    with pytest.raises(ValueError, match="scenario"):
        RLAgent.load(out, gym.make("gp_envs/CartPoleSwingUp-v0", scenario="gp"))


def test_bad_observations_raise(tiny_agent: tuple[RLAgent, Path]) -> None:
    agent, _ = tiny_agent
    with pytest.raises(ValueError, match="finite"):
        agent.act(np.array([0.0, np.nan, 0.0, 0.0]))
    with pytest.raises(ValueError, match="shape"):
        agent.act(np.zeros(3))


def test_normalized_action_inverts() -> None:
    env = NormalizedAction(gym.make("gp_envs/Quadrotor-v0"))
    rng = np.random.default_rng(1)
    a = rng.uniform(-1, 1, size=(50, 4)).astype(np.float32)
    for ai in a:
        u = env.action(ai)
        assert u.dtype == np.float32 and env.env.action_space.contains(u)
        np.testing.assert_allclose(env.reverse_action(u), ai, atol=1e-6)
    np.testing.assert_allclose(env.action(-np.ones(4)), np.zeros(4))
    np.testing.assert_allclose(env.action(np.ones(4)), np.full(4, 5.0))
    u = rng.uniform(0, 5, size=4)
    np.testing.assert_allclose(env.action(env.reverse_action(u)), u, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(env.action(np.full(4, 3.0)), np.full(4, 5.0))  # clipped


def test_angle_features() -> None:
    base = gym.make("gp_envs/CartPoleSwingUp-v0")
    idx = base.unwrapped.nominal_model.angle_indices
    env = AngleFeatures(base, idx)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (5,) and env.observation_space.contains(obs)
    raw = np.array([0.3, 2.5, -1.0, 4.0])
    f = angle_features(raw, idx)
    np.testing.assert_allclose(f, [0.3, -1.0, 4.0, np.cos(2.5), np.sin(2.5)], rtol=1e-6)
    # (cos, sin) recovers the angle and is continuous across the wrap at 0 / 2 pi
    np.testing.assert_allclose(np.arctan2(f[4], f[3]), 2.5, rtol=1e-6)
    np.testing.assert_allclose(angle_features(np.array([0, 1e-4, 0, 0]), idx),
                               angle_features(np.array([0, 2 * np.pi + 1e-4, 0, 0]), idx),
                               atol=1e-6)
    quad = gym.make("gp_envs/Quadrotor-v0")
    q = angle_features(np.arange(12.0) / 10, quad.unwrapped.nominal_model.angle_indices)
    assert q.shape == (15,)
    np.testing.assert_allclose(q[9:12] ** 2 + q[12:15] ** 2, 1.0, rtol=1e-6)


def test_wrapped_env_steps_in_unit_box() -> None:
    env = wrap_env(gym.make("gp_envs/DubinsObstacle-v0"),
                   gym.make("gp_envs/DubinsObstacle-v0").unwrapped.nominal_model.angle_indices)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (4,)
    obs, _r, _te, _tr, info = env.step(np.ones(2, np.float32))
    assert not info["action_clipped"] and env.observation_space.contains(obs)
