"""Tests of the RL baseline (gp_agents.rl, benchmarks.rl.train): load, act, checks, wrappers,
training reward wrappers, resumable training."""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("stable_baselines3")

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.monitor import Monitor

import gp_envs  # registers the envs
from benchmarks.rl.train import CURVE_FIELDS, latest_checkpoint, train
from gp_agents.agent import rollout
from gp_agents.rl import (
    AngleFeatures,
    BoundedShiftReward,
    GoalBonusReward,
    NormalizedAction,
    RLAgent,
    TimeFeature,
    angle_features,
    get_env_state,
    set_env_state,
    termination_terms,
    wrap_env,
)

REPO = Path(__file__).resolve().parents[1]

MODELS = Path(__file__).resolve().parents[1] / "benchmarks" / "models"
SHIPPED = {
    "cartpole/sac": ("gp_envs/CartPoleSwingUp-v0", "online"),
    "cartpole/tqc": ("gp_envs/CartPoleSwingUp-v0", "online"),
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


# --------------------------------------------------------------------------- training wrappers
def _episode(env: gym.Env, actions: np.ndarray, seed: int) -> tuple[float, int, bool]:
    env.reset(seed=seed)
    ret = 0.0
    for k, a in enumerate(actions, start=1):
        _obs, r, te, tr, _info = env.step(a)
        ret += r
        if te or tr:
            return ret, k, te
    raise AssertionError("episode did not end")


@pytest.mark.parametrize("env_id", gp_envs.ENV_IDS)
def test_bounded_shift_changes_every_return_by_the_same_constant(env_id: str) -> None:
    plain = gym.make(env_id)
    shifted = BoundedShiftReward(gym.make(env_id))
    dt, t_max, bound = termination_terms(plain)
    assert shifted.return_offset == pytest.approx(t_max * dt * bound)
    m = plain.action_space.shape[0]
    lo, hi = plain.action_space.low, plain.action_space.high
    rng = np.random.default_rng(0)
    # full force leaves the box early (Dubins: straight at the obstacle); the cost's reference
    # control (cart at rest, hover thrust, standing still) runs to the time limit
    u_ref = plain.unwrapped.nominal_model.task.u_ref
    plans = [np.tile(hi, (t_max, 1)), np.tile(lo, (t_max, 1)), np.tile(u_ref, (t_max, 1)),
             np.tile(np.where(lo < 0, 0.0, hi), (t_max, 1)), rng.uniform(lo, hi, size=(t_max, m))]
    ends = set()
    for actions in plans:
        r_plain, k, term = _episode(plain, actions, seed=3)
        r_shift, k2, term2 = _episode(shifted, actions, seed=3)
        assert (k, term) == (k2, term2)
        ends.add(term)
        # the same constant for trajectories that terminate early and ones that do not
        assert r_shift - r_plain == pytest.approx(shifted.return_offset, rel=1e-9, abs=1e-6)
        if term:  # shifting the terminating step too would be off by one step's bound
            naive = r_plain + (t_max - k + 1) * dt * bound + k * dt * bound
            assert naive - r_plain != pytest.approx(shifted.return_offset)
    # the pendulum's torque (2.5 N m, under m g l) cannot reach its 20 rad/s guard: it never
    # terminates, so only the other systems exercise the early-termination branch
    assert ends == ({False} if env_id == "gp_envs/PendulumSwingUp-v0" else {True, False})


def test_shifted_rewards_are_bounded() -> None:
    env = BoundedShiftReward(gym.make("gp_envs/CartPoleSwingUp-v0"))
    env.reset(seed=0)
    step = env.dt * env.bound
    for _ in range(200):
        _o, r, te, tr, _ = env.step(np.array([35.0], np.float32))
        assert (-step - 1e-9 <= r <= 0.0) if te else (0.0 <= r <= step + 1e-9)
        if te or tr:
            env.reset()


def test_goal_bonus_only_at_goal() -> None:
    base = gym.make("gp_envs/CartPoleSwingUp-v0")
    env = GoalBonusReward(gym.make("gp_envs/CartPoleSwingUp-v0"), bonus=2.0)
    for e in (base, env):
        e.reset(seed=0, options={"state": np.array([0.0, np.pi, 0.0, 0.0])})
    _, r0, *_ = base.step(np.zeros(1))
    _, r1, _, _, info = env.step(np.zeros(1))
    assert info["at_goal"] and r1 == pytest.approx(r0 + 2.0 * 0.05)
    for e in (base, env):
        e.reset(seed=0)
    _, r0, *_ = base.step(np.zeros(1))
    _, r1, _, _, info = env.step(np.zeros(1))
    assert not info["at_goal"] and r1 == r0
    with pytest.raises(ValueError):
        GoalBonusReward(base, bonus=0.0)


def test_time_feature() -> None:
    env = TimeFeature(gym.make("gp_envs/CartPoleSwingUp-v0"))
    obs, _ = env.reset(seed=0)
    assert obs.shape == (5,) and obs[-1] == 1.0 and env.observation_space.contains(obs)
    for k in range(1, 121):
        obs, _r, te, tr, _ = env.step(np.zeros(1))
        assert obs[-1] == pytest.approx(1 - k / 120)
        if te or tr:
            break
    assert tr and obs[-1] == pytest.approx(0.0)
    assert env.reset()[0][-1] == 1.0


@pytest.mark.parametrize("env_id", gp_envs.ENV_IDS)
def test_env_state_round_trip(env_id: str) -> None:
    def make() -> gym.Env:
        e = BoundedShiftReward(gym.make(env_id))
        return Monitor(wrap_env(e, e.unwrapped.nominal_model.angle_indices, 120))

    rng = np.random.default_rng(1)
    a_env, b_env = make(), make()
    a_env.reset(seed=5)
    acts = rng.uniform(-0.3, 0.3, size=(400, a_env.action_space.shape[0])).astype(np.float32)
    for a in acts[:37]:
        *_, te, tr, _ = a_env.step(a)
        if te or tr:
            a_env.reset()
    b_env.reset(seed=99)  # another episode, then overwritten
    set_env_state(b_env, get_env_state(a_env))
    assert (b_env.unwrapped.nominal_model.params == a_env.unwrapped.nominal_model.params)
    for a in acts[37:]:  # across episode ends and seedless resets (same RNG stream)
        oa, ra, tea, tra, _ = a_env.step(a)
        ob, rb, teb, trb, _ = b_env.step(a)
        np.testing.assert_array_equal(oa, ob)
        assert (ra, tea, tra) == (rb, teb, trb)
        if tea or tra:
            np.testing.assert_array_equal(a_env.reset()[0], b_env.reset()[0])
            assert (b_env.unwrapped.nominal_model.params
                    == a_env.unwrapped.nominal_model.params)


# --------------------------------------------------------------------------- resumable training
TINY_SAC = {"learning_starts": 64, "buffer_size": 5000}


def _tiny_sac(out: Path, steps: int, stop_after: int | None = None, **kw: object) -> RLAgent:
    return train("cartpole", "online", "sac", steps, seed=5, out=out, eval_freq=160,
                 eval_episodes=1, checkpoint_freq=160, stop_after=stop_after,
                 hyperparams="sac-swingup", reward="bounded-shift", time_feature=True,
                 overrides=TINY_SAC, progress=False, echo=lambda _m: None, **kw)


def _curve(path: Path) -> list[dict[str, str]]:
    with open(path / "learning_curve.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _without_wall(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    return [{k: v for k, v in r.items() if k != "wall_time_s"} for r in rows]


@pytest.fixture(scope="module")
def sac_runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """A tiny SAC run (gSDE, bounded shift, time feature) to 480 steps in one go, and the same
    command interrupted at 240 and resumed."""
    root = tmp_path_factory.mktemp("sac_resume")
    whole = _tiny_sac(root / "whole", 480)
    half = _tiny_sac(root / "resumed", 480, stop_after=240)
    half_curve = _curve(root / "resumed")
    assert not (root / "resumed" / "metadata.json").exists()
    resumed = _tiny_sac(root / "resumed", 480)
    return {"root": root, "whole": whole, "half": half, "half_curve": half_curve,
            "resumed": resumed}


def test_resumed_sac_is_bit_identical(sac_runs: dict) -> None:
    root = sac_runs["root"]
    whole, resumed = _curve(root / "whole"), _curve(root / "resumed")
    assert list(whole[0]) == list(CURVE_FIELDS)
    assert [int(r["timesteps"]) for r in whole] == [0, 160, 320, 480]
    # the rows up to the interruption, and (SB3 permitting, which it does) all rows after it
    assert [int(r["timesteps"]) for r in sac_runs["half_curve"]] == [0, 160]
    assert _without_wall(sac_runs["half_curve"]) == _without_wall(whole[:2])
    assert _without_wall(resumed) == _without_wall(whole)
    pa = sac_runs["whole"].model.policy.state_dict()
    pb = sac_runs["resumed"].model.policy.state_dict()
    assert all(torch.equal(pa[k], pb[k]) for k in pa)
    meta = json.loads((root / "resumed" / "metadata.json").read_text())
    assert meta["training_steps"] == 480 and len(meta["sessions"]) == 2
    assert meta["time_feature_max_steps"] == 120
    assert [w["name"] for w in meta["training_wrappers"]] == ["BoundedShiftReward", "TimeFeature"]
    assert "--reward bounded-shift" in meta["command"] and "--time-feature" in meta["command"]
    assert latest_checkpoint(root / "resumed" / "checkpoints").name == "ckpt_0000000480"
    assert len(list((root / "resumed" / "checkpoints").glob("ckpt_*"))) == 1


def test_best_policy_is_the_curves_best_row_and_acts_as_evaluated(sac_runs: dict) -> None:
    root = sac_runs["root"]
    rows = _curve(root / "whole")
    # the first row with the highest success rate, among those the lowest mean cost
    want = min(rows, key=lambda r: (-float(r["success_rate"]), float(r["mean_cost"])))
    metas = [json.loads((root / run / "best" / "metadata.json").read_text())
             for run in ("whole", "resumed")]
    for meta in metas:
        best = meta["best_of_learning_curve"]
        assert best["timesteps"] == int(want["timesteps"]) == meta["training_steps"]
        assert best["mean_cost"] == pytest.approx(float(want["mean_cost"]))
    env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online")
    agent = RLAgent.load(root / "whole" / "best", env)  # one curve episode: reset seed 1000
    assert -rollout(env, agent, 1000).summary()["return"] == pytest.approx(
        float(want["mean_cost"]), rel=1e-9)


def test_saved_time_feature_agent_acts_like_training_policy(sac_runs: dict) -> None:
    root = sac_runs["root"]
    env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online")
    agent = RLAgent.load(root / "whole", env)
    trained = sac_runs["whole"]
    assert agent.time_feature_max_steps == 120
    wrapped = TimeFeature(AngleFeatures(gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online"),
                                        (1,)))
    obs, _ = env.reset(seed=4)
    feats, _ = wrapped.reset(seed=4)
    agent.reset()
    for _ in range(30):
        np.testing.assert_allclose(agent.preprocess(obs),
                                   trained.obs_normalizer.normalize_obs(feats[None])[0],
                                   rtol=1e-6)
        a = agent.act(obs)
        obs, *_ = env.step(a)
        feats, *_ = wrapped.step(a)
    agent.reset()
    assert agent.steps_since_reset == 0


def test_finished_run_is_not_retrained_and_config_is_checked(sac_runs: dict) -> None:
    root = sac_runs["root"]
    again = _tiny_sac(root / "whole", 480)
    assert again.training_steps == 480
    with pytest.raises(ValueError, match="another configuration"):
        train("cartpole", "online", "sac", 480, seed=6, out=root / "whole", eval_freq=160,
              eval_episodes=1, checkpoint_freq=160, hyperparams="sac-swingup",
              reward="bounded-shift", time_feature=True, overrides=TINY_SAC, progress=False,
              echo=lambda _m: None)


def test_finished_run_extends_from_its_checkpoint(sac_runs: dict) -> None:
    root = sac_runs["root"]
    longer = _tiny_sac(root / "resumed", 640)
    rows = _curve(root / "resumed")
    assert longer.training_steps == 640 and int(rows[-1]["timesteps"]) == 640
    assert _without_wall(rows[:4]) == _without_wall(_curve(root / "whole"))


def test_resumed_ppo_is_bit_identical(tmp_path: Path) -> None:
    kw = {"eval_freq": 256, "eval_episodes": 1, "checkpoint_freq": 256, "progress": False,
          "echo": lambda _m: None,
          "overrides": {"n_envs": 2, "n_steps": 64, "batch_size": 64, "n_epochs": 2}}
    whole = train("cartpole", "online", "ppo", 768, seed=2, out=tmp_path / "a", **kw)
    train("cartpole", "online", "ppo", 768, seed=2, out=tmp_path / "b", stop_after=256, **kw)
    resumed = train("cartpole", "online", "ppo", 768, seed=2, out=tmp_path / "b", **kw)
    assert _without_wall(_curve(tmp_path / "a")) == _without_wall(_curve(tmp_path / "b"))
    pa, pb = whole.model.policy.state_dict(), resumed.model.policy.state_dict()
    assert all(torch.equal(pa[k], pb[k]) for k in pa)
    np.testing.assert_array_equal(whole.obs_normalizer.ret_rms.var,
                                  resumed.obs_normalizer.ret_rms.var)


def test_resumed_tqc_is_bit_identical_and_loads(tmp_path: Path) -> None:
    """sb3-contrib's TQC (preset tqc-swingup) through the same resumable training and loading
    as SAC: interrupted and resumed equals one go, and the saved agent acts as its policy."""
    kw = {"eval_freq": 128, "eval_episodes": 1, "checkpoint_freq": 128, "progress": False,
          "echo": lambda _m: None, "hyperparams": "tqc-swingup", "reward": "bounded-shift",
          "time_feature": True,
          "overrides": {"learning_starts": 64, "buffer_size": 5000, "train_freq": 16,
                        "gradient_steps": 4}}
    whole = train("cartpole", "online", "tqc", 384, seed=3, out=tmp_path / "a", **kw)
    train("cartpole", "online", "tqc", 384, seed=3, out=tmp_path / "b", stop_after=128, **kw)
    resumed = train("cartpole", "online", "tqc", 384, seed=3, out=tmp_path / "b", **kw)
    assert _without_wall(_curve(tmp_path / "a")) == _without_wall(_curve(tmp_path / "b"))
    pa, pb = whole.model.policy.state_dict(), resumed.model.policy.state_dict()
    assert all(torch.equal(pa[k], pb[k]) for k in pa)
    env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online")
    agent = RLAgent.load(tmp_path / "a", env)
    assert agent.algo == "tqc" and type(agent.model).__name__ == "TQC"
    obs, _ = env.reset(seed=0)
    np.testing.assert_array_equal(agent.act(obs), whole.act(obs))


def test_killed_cli_run_resumes_to_the_total(tmp_path: Path) -> None:
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "benchmarks.rl.train", "--env", "cartpole", "--scenario",
           "online", "--algo", "sac", "--steps", "200", "--seed", "1", "--eval-freq", "100",
           "--eval-episodes", "1", "--checkpoint-freq", "50", "--out", str(out)]
    env = dict(os.environ, PYTHONPATH=str(REPO), OMP_NUM_THREADS="1")
    proc = subprocess.Popen(cmd, cwd=REPO, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 45
        while latest_checkpoint(out / "checkpoints") is None:
            assert proc.poll() is None, "training exited before its first checkpoint"
            assert time.monotonic() < deadline, "no checkpoint written"
            time.sleep(0.2)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    assert not (out / "metadata.json").exists()
    done = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "resuming" in done.stdout
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["training_steps"] == 200
    rows = _curve(out)
    assert [int(r["timesteps"]) for r in rows] == [0, 100, 200]
    RLAgent.load(out, gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online"))


# --------------------------------------------------------------------------- multi-seed summary
def test_median_iqr_ci() -> None:
    from benchmarks.rl.summary import median_iqr_ci

    st = median_iqr_ci([5.0, 1.0, 3.0, 2.0, 4.0])
    assert (st["median"], st["q25"], st["q75"], st["n"]) == (3.0, 2.0, 4.0, 5)
    assert 1.0 <= st["ci_lo"] <= st["median"] <= st["ci_hi"] <= 5.0
    assert st == median_iqr_ci([1.0, 2.0, 3.0, 4.0, 5.0])  # fixed bootstrap generator
    one = median_iqr_ci([0.5])
    assert one["median"] == 0.5 and np.isnan(one["ci_lo"]) and np.isnan(one["ci_hi"])


_PRESET_COLUMNS = ("experiment", "env", "scenario", "cell", "n_init", "controller", "label",
                   "status", "episodes", "success_rate", "cost_mean", "interaction_mean_s",
                   "interaction_ci_low", "interaction_ci_high", "trials_success_rate",
                   "interaction_trials_mean_s", "interaction_trials_ci_low",
                   "interaction_trials_ci_high")


def _preset_row(controller: str, n_init: int, success: float, cost: float,
                interaction: tuple[float, float, float], trials: float = float("nan"),
                trials_interaction: tuple[float, float, float] = (float("nan"),) * 3,
                env: str = "cartpole", cell: str = "fixed truth", episodes: int = 10
                ) -> dict[str, object]:
    return dict(zip(_PRESET_COLUMNS, ("data-efficiency", env, "online", cell, n_init, controller,
                                      controller.replace("-mpc", " MPC"), "ok", episodes,
                                      success, cost, *interaction, trials,
                                      *trials_interaction), strict=True))


@pytest.fixture
def preset_dir(tmp_path: Path) -> Path:
    """A synthetic data-efficiency ``summary.csv`` (cart pole ``online``): the robust recipe
    meets success 0.8 first at 5 samples (exactly the bar; 10 samples dips below), within the
    trials at 0, the cost bound 1.1 x 10 = 11 first at 10; the black-box never reaches 0.8 in
    trial 1; rows of another cell, another env and a cell with no episode must be ignored."""
    nan = float("nan")
    rows = [_preset_row("oracle-mpc", 0, 1.0, 10.0, (1.5, 1.4, 1.6)),
            _preset_row("robust-mpc", 0, 0.5, 30.0, (3.0, nan, nan), 0.9, (6.0, 5.0, 7.0)),
            _preset_row("robust-mpc", 5, 0.8, 11.5, (2.0, 1.5, 2.5), 1.0, (2.2, 1.6, 2.6)),
            _preset_row("robust-mpc", 10, 0.7, 10.9, (2.4, 2.0, 2.8), 1.0, (2.5, 2.1, 2.9)),
            _preset_row("robust-mpc", 20, 1.0, 10.5, (2.6, 2.5, 2.7), 1.0, (2.6, 2.5, 2.7)),
            _preset_row("blackbox-mpc", 0, 0.1, 90.0, (4.5, nan, nan), 0.7, (12.0, 9.0, 15.0)),
            _preset_row("blackbox-mpc", 20, 0.6, 40.0, (5.0, 4.0, 6.0), 1.0, (8.0, 7.0, 9.0)),
            # ignored: another cell, another env, no episodes
            _preset_row("robust-mpc", 0, 1.0, 10.0, (0.1, 0.1, 0.1), cell="randomize 0.1"),
            _preset_row("robust-mpc", 0, 1.0, 10.0, (0.1, 0.1, 0.1), env="dubins"),
            _preset_row("blackbox-mpc", 1, 1.0, 10.0, (0.1, 0.1, 0.1), episodes=0)]
    with open(tmp_path / "summary.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=_PRESET_COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    return tmp_path


def test_the_preset_cell_of_each_criterion_is_the_fewest_samples_meeting_it(
        preset_dir: Path) -> None:
    from benchmarks.presets import data_efficiency
    from benchmarks.rl.summary import (
        PLAIN_CELL,
        anchor_cell,
        mpc_cost_bound,
        read_data_efficiency,
    )

    # the cell the preset runs is the one read: the scenario as registered
    assert {s.cell.describe() for s in data_efficiency(seeds=(0,)).specs} == {PLAIN_CELL}
    rows = read_data_efficiency("cartpole", "online", preset_dir)
    assert sorted((r["controller"], r["n_init"]) for r in rows) == [
        ("blackbox-mpc", 0), ("blackbox-mpc", 20), ("oracle-mpc", 0), ("robust-mpc", 0),
        ("robust-mpc", 5), ("robust-mpc", 10), ("robust-mpc", 20)]
    assert mpc_cost_bound(rows) == pytest.approx(11.0)
    success = anchor_cell(rows, "robust-mpc", "success")
    assert (success.n_init, success.seeds, success.cost) == (5, 8, 11.5)
    assert success.interaction_s == 2.0 and (success.ci_low, success.ci_high) == (1.5, 2.5)
    np.testing.assert_allclose(success.steps(0.05), (40.0, 30.0, 50.0))
    trials = anchor_cell(rows, "robust-mpc", "trials")  # the failed trials' interaction
    assert (trials.n_init, trials.interaction_s, trials.seeds) == (0, 6.0, 9)
    assert anchor_cell(rows, "robust-mpc", "cost").n_init == 10  # 11.5 > 11 >= 10.9
    assert anchor_cell(rows, "blackbox-mpc", "success") == "not met at 0-20 initial samples"
    assert anchor_cell(rows, "blackbox-mpc", "trials").n_init == 20
    assert anchor_cell(rows, "paper-mpc", "success") == "not in the preset"
    no_oracle = [r for r in rows if r["controller"] != "oracle-mpc"]
    assert anchor_cell(no_oracle, "robust-mpc", "cost") == "not measured"
    assert anchor_cell(no_oracle, "robust-mpc", "success") == success
    with pytest.raises(ValueError, match="criterion"):
        anchor_cell(rows, "robust-mpc", "speed")
    assert read_data_efficiency("cartpole", "online", preset_dir / "missing") == []


def _curve_run(seed: int, success: list[float], cost: list[float]) -> object:
    from benchmarks.rl.summary import SeedRun

    curve = [{"timesteps": 100.0 * i, "success_rate": s, "mean_cost": c}
             for i, (s, c) in enumerate(zip(success, cost, strict=True))]
    return SeedRun(seed, Path("."), curve, None)


def _table(lines: list[str], first_header: str) -> list[list[str]]:
    """The cells of the Markdown table whose header starts with ``first_header``."""
    start = next(i for i, ln in enumerate(lines) if ln.startswith(f"| {first_header} |"))
    rows = []
    for ln in lines[start + 2:]:
        if not ln.startswith("|"):
            break
        rows.append([c.strip() for c in ln.strip("|").split("|")])
    return rows


def test_sample_efficiency_against_the_preset_in_seconds_and_steps(preset_dir: Path) -> None:
    """RL: first evaluation meeting each criterion per seed, censored beyond the budget, in
    steps and steps x dt; MPC: the chosen cell's interaction in s and s / dt; the ratio of
    the two step counts, censored with ">" when RL's median is."""
    from benchmarks.rl.summary import EnvAnchors, read_data_efficiency, sample_efficiency_lines

    anchors = EnvAnchors("cartpole", "online", {"mean_cost": 10.0, "episodes": 20},
                         read_data_efficiency("cartpole", "online", preset_dir), [500, 501],
                         0.05)
    runs = [_curve_run(0, [0, 0.9, 1], [30, 12, 10.5]), _curve_run(1, [0, 0, 0.8], [30, 20, 11]),
            _curve_run(2, [0, 0, 0], [30, 30, 30])]
    lines = sample_efficiency_lines(runs, anchors, 200)
    rl = _table(lines, "criterion")
    assert rl[0][1:] == ["2/3", "200 [100, > 200]", "10 [5, > 10]"]  # steps 100, 200, never
    assert rl[1][1:] == ["2/3", "200 [200, > 200]", "10 [10, > 10]"]  # cost <= 11 at 200
    mpc = {(r[0], r[1]): r[2:] for r in _table(lines[lines.index(next(
        ln for ln in lines if "MPC recipe" in ln)):], "criterion")}
    assert mpc["success rate >= 0.8", "`robust-mpc`"] == [
        "5 (0.25 s)", "0.80 / 1.00, 11.50", "2.00 [1.50, 2.50] (8)", "40 [30, 50]", "5x"]
    assert mpc["success rate >= 0.8", "`blackbox-mpc`"] == [
        "not met at 0-20 initial samples", "", "", "", "n/a"]
    # no interval from the preset: the mean alone
    assert mpc["success rate >= 0.8 (MPC: within 5 trials)", "`robust-mpc`"][2:] == [
        "6.00 [5.00, 7.00] (9)", "120 [100, 140]", "2x"]
    assert mpc["mean cost <= 1.1x the oracle MPC's", "`robust-mpc`"][0] == "10 (0.5 s)"
    assert mpc["mean cost <= 1.1x the oracle MPC's", "`robust-mpc`"][-1] == "4x"  # 200 / 48
    text = "\n".join(lines)
    assert "seeds 500-501" in text and "(10.00: <= 11.00)" in text
    # the reference without learning quoted from the preset (no nominal row here)
    assert ("in the same preset: oracle MPC (`oracle-mpc`) success 1.00, cost 10.00, "
            "interaction before success 1.50 s.") in text
    never = [_curve_run(k, [0, 0, 0], [30, 30, 30]) for k in range(3)]
    success = next(ln for ln in sample_efficiency_lines(never, anchors, 200)
                   if ln.startswith("| success rate >= 0.8 | `robust-mpc`"))
    assert success.endswith("| > 5x |")  # the budget, 200, over 40 steps


def test_sample_efficiency_without_a_preset_cell_says_so_in_one_line() -> None:
    from benchmarks.rl.summary import EnvAnchors, sample_efficiency_lines

    anchors = EnvAnchors("cartpole", "nowhere", {"mean_cost": 10.0, "episodes": 20}, [], [],
                         0.05)
    lines = sample_efficiency_lines([_curve_run(0, [0, 1], [30, 10])], anchors, 200)
    said = [ln for ln in lines if "no cell for `cartpole` `nowhere`" in ln]
    assert len(said) == 1 and "no ratio" in said[0]
    assert not any("MPC recipe" in ln or ln.endswith("x |") for ln in lines)
    assert "| success rate >= 0.8 | 1/1 | 100 | 5 |" in lines


def test_the_anchor_is_the_first_trials_interaction_of_the_committed_episodes() -> None:
    """Against the preset's per-episode file: the chosen cart-pole cell's mean interaction
    and success count are those of its episodes in ``metrics.csv``, and no cell with fewer
    initial samples succeeded on at least 0.8 of its episodes."""
    from benchmarks.rl.summary import (
        DATA_EFFICIENCY,
        SUCCESS_BAR,
        anchor_cell,
        read_data_efficiency,
    )

    if not (DATA_EFFICIENCY / "metrics.csv").is_file():
        pytest.skip("no committed data-efficiency results")
    cell = anchor_cell(read_data_efficiency("cartpole", "online"), "robust-mpc", "success")
    with open(DATA_EFFICIENCY / "metrics.csv", newline="") as fh:
        episodes = [r for r in csv.DictReader(fh)
                    if (r["env"], r["scenario"], r["controller"]) ==
                    ("cartpole", "online", "robust-mpc") and r["status"] == "ok"]
    by_n: dict[int, list[dict[str, str]]] = {}
    for e in episodes:
        by_n.setdefault(int(e["n_init"]), []).append(e)
    rate = {n: np.mean([e["success"] == "True" for e in es]) for n, es in by_n.items()}
    assert cell.n_init == min(n for n, r in rate.items() if r >= SUCCESS_BAR)
    won = [float(e["interaction_s"]) for e in by_n[cell.n_init] if e["success"] == "True"]
    assert cell.seeds == len(won) and cell.episodes == len(by_n[cell.n_init])
    assert cell.interaction_s == pytest.approx(np.mean(won))
    assert cell.ci_low <= cell.interaction_s <= cell.ci_high


def test_env_dt_is_the_time_one_env_step_advances() -> None:
    from benchmarks.rl.summary import env_dt

    for env_id, short, scenario in (("gp_envs/CartPoleSwingUp-v0", "cartpole", "online"),
                                    ("gp_envs/DubinsObstacle-v0", "dubins", "paper")):
        env = gym.make(env_id, scenario=scenario)
        env.reset(seed=0)
        times = [env.step(env.action_space.sample() * 0)[-1]["time"] for _ in range(3)]
        env.close()
        assert env_dt(short, scenario) == pytest.approx(np.diff(times).mean())
        assert env_dt(env_id, scenario) == env_dt(short, scenario)


def test_summary_from_tiny_runs(sac_runs: dict, tmp_path: Path,
                                monkeypatch: pytest.MonkeyPatch) -> None:
    import shutil

    import benchmarks.rl.summary as summary
    from benchmarks.rl.runs import Plan

    root = tmp_path / "runs"
    for seed in (0, 1):
        shutil.copytree(sac_runs["root"] / "whole", root / f"seed{seed}",
                        ignore=shutil.ignore_patterns("checkpoints"))
    plan = Plan(env="cartpole", scenario="online", algo="sac", hyperparams="sac-swingup",
                steps=480, seeds=(0, 1, 2), reward="bounded-shift", time_feature=True,
                eval_freq=160, eval_episodes=1, checkpoint_freq=160, root=root,
                description="tiny")
    monkeypatch.setitem(summary.PLANS, "tiny", plan)
    oracle = {"success_rate": 1.0, "mean_cost": 13.0, "episodes": 20}
    monkeypatch.setattr(summary, "oracle_reference", lambda env, scenario: oracle)  # MPC: slow
    path = summary.write_summary(["tiny"], out=tmp_path / "out")
    text = path.read_text()
    assert "**2 finished**" in text and "1 not started" in text
    assert "| success rate |" in text and "BoundedShiftReward" in text
    assert "### Sample efficiency" in text and "| success rate >= 0.8 | 0/2 | > 480 " in text
    # the MPC side from the committed data-efficiency results of the cart pole (online)
    assert "| success rate >= 0.8 | `robust-mpc` |" in text
    assert "| success rate >= 0.8 | `blackbox-mpc` |" in text
    with open(tmp_path / "out" / "tiny_final_eval.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 40 and sorted({int(r["episode_seed"]) for r in rows}) == list(range(20))
    # the two copies are the same policy: the same episodes
    assert [r["cost"] for r in rows[:20]] == [r["cost"] for r in rows[20:]]
    assert (tmp_path / "out" / "tiny_curves.png").stat().st_size > 10_000
    assert "## Sample efficiency: gp_envs/CartPoleSwingUp-v0 (online)" in text
    assert (tmp_path / "out" / "cartpole_online_sample_efficiency.png").stat().st_size > 10_000


def test_the_summary_tabulates_the_first_evaluation_at_each_multiple() -> None:
    from benchmarks.rl.summary import table_steps

    assert table_steps(np.array([0, 25_000, 50_000, 60_000])) == [0, 1, 2, 3]
    tqc = np.array([0, 5056, 24_960, 25_024, 49_984, 50_048, 51_000])
    assert table_steps(tqc) == [0, 3, 5, 6]  # 25_024 and 50_048 stand for 25k and 50k


def test_curve_percentiles_are_over_the_seeds_at_each_step() -> None:
    """Percentiles at a step are NumPy's over the seeds evaluated there; a step fewer than
    ``min_seeds`` seeds reached is left out; the median curve is the 50th percentile."""
    from benchmarks.rl.summary import SeedRun, curve_percentiles, median_curve

    runs = [SeedRun(k, Path("."), [{"timesteps": float(t), "mean_cost": c}
                                   for t, c in zip(steps, costs, strict=True)], None)
            for k, (steps, costs) in enumerate((([0, 10, 20], [9, 5, 1]),
                                                ([0, 10, 20], [8, 6, 2]),
                                                ([0, 10], [7, 1])))]
    steps, (lo, med, hi) = curve_percentiles(runs, "mean_cost")
    assert steps.tolist() == [0, 10, 20]
    np.testing.assert_allclose(med, [8, 5, 1.5])
    np.testing.assert_allclose(lo, [7.5, 3.0, 1.25])  # linear interpolation between ranks
    np.testing.assert_allclose(hi, [8.5, 5.5, 1.75])
    steps3, _ = curve_percentiles(runs, "mean_cost", min_seeds=3)
    assert steps3.tolist() == [0, 10]
    np.testing.assert_array_equal(median_curve(runs, "mean_cost")[1], med)


def test_ship_copies_the_seed_with_the_lowest_last_training_cost(tmp_path: Path) -> None:
    """``benchmarks.rl.ship``: of a finished plan, the seed whose *last* training evaluation
    is cheapest (not its best one) is copied, files byte for byte, with ``shipped_from`` in its
    metadata; a plan with an unfinished seed is refused."""
    from benchmarks.rl.runs import Plan
    from benchmarks.rl.ship import select_seed, ship

    plan = Plan(env="cartpole", scenario="online", algo="sac", hyperparams="sac-swingup",
                steps=100, seeds=(0, 1, 2), root=tmp_path / "runs")
    costs = {0: [50.0, 12.0, 30.0], 1: [40.0, 20.0], 2: [60.0, 25.0]}  # last: 30, 20, 25
    for seed, curve in costs.items():
        d = plan.run_dir("p", seed)
        d.mkdir(parents=True)
        (d / "metadata.json").write_text(json.dumps({"training_steps": 100, "seed": seed}))
        with open(d / "learning_curve.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["timesteps", "mean_cost"])
            w.writerows([[10 * i, c] for i, c in enumerate(curve)])
        (d / "model.zip").write_bytes(bytes([seed]) * 7)
        (d / "vecnormalize.pkl").write_bytes(bytes([seed + 10]) * 5)
    assert select_seed({0: 30.0, 1: 20.0, 2: 20.0}) == 1
    with pytest.raises(ValueError):
        select_seed({})
    record = ship("p", plan, models=tmp_path / "models")
    dest = tmp_path / "models" / "cartpole" / "sac"
    assert record["seed"] == 1 and record["last_training_eval_cost"] == {
        "0": 30.0, "1": 20.0, "2": 25.0}
    assert (dest / "model.zip").read_bytes() == bytes([1]) * 7
    assert (dest / "vecnormalize.pkl").read_bytes() == bytes([11]) * 5
    meta = json.loads((dest / "metadata.json").read_text())
    assert meta["seed"] == 1 and meta["shipped_from"]["plan"] == "p"
    (plan.run_dir("p", 2) / "metadata.json").unlink()
    with pytest.raises(ValueError, match="unfinished seeds \\[2\\]"):
        ship("p", plan, models=tmp_path / "models2")


def test_eval_rl_rows_carry_intervals_over_the_episodes() -> None:
    """``benchmarks.rl.evaluate.evaluate``: the Wilson interval of the success rate and the
    bootstrap interval of the mean return contain their estimates (the shipped cart-pole SAC,
    5 episodes)."""
    from benchmarks.rl.evaluate import evaluate

    row, episodes = evaluate(MODELS / "cartpole" / "sac", seeds=range(5))
    assert len(episodes) == 5 and row["episodes"] == 5
    assert 0.0 <= row["success_ci_low"] <= row["success_rate"] <= row["success_ci_high"] <= 1.0
    assert row["return_ci_low"] <= row["mean_return"] <= row["return_ci_high"]


def test_ship_best_ships_the_best_policy_of_a_rerun_of_the_plans_best_seed(
        sac_runs: dict, tmp_path: Path) -> None:
    """``ship --best``: the plan's best learning-curve row (highest success, then lowest cost)
    picks the seed; a run with that seed's configuration ships its ``best/`` policy, byte for
    byte; a run with another configuration, or without a best policy, is refused."""
    from benchmarks.rl.runs import Plan
    from benchmarks.rl.ship import best_policy, ship_best

    root = sac_runs["root"]
    plan = Plan(env="cartpole", scenario="online", algo="sac", hyperparams="sac-swingup",
                steps=480, seeds=(5,), reward="bounded-shift", time_feature=True,
                eval_freq=160, eval_episodes=1, checkpoint_freq=160, root=root / "whole",
                seed_dirs=False)
    rows = _curve(root / "whole")
    want = min(rows, key=lambda r: (-float(r["success_rate"]), float(r["mean_cost"])))
    seed, row = best_policy("p", plan)
    assert seed == 5 and row["timesteps"] == int(want["timesteps"])
    rerun = root / "resumed"  # the same configuration (interrupted and resumed)
    record = ship_best("p", plan, rerun, models=tmp_path / "models")
    dest = tmp_path / "models" / "cartpole" / "sac"
    assert (dest / "model.zip").read_bytes() == (rerun / "best" / "model.zip").read_bytes()
    best = json.loads((rerun / "best" / "metadata.json").read_text())["best_of_learning_curve"]
    assert record["training_eval"]["timesteps"] == best["timesteps"]
    assert json.loads((dest / "metadata.json").read_text())["shipped_from"]["seed"] == 5
    other = tmp_path / "other"
    shutil.copytree(rerun, other, ignore=shutil.ignore_patterns("checkpoints"))
    meta = json.loads((other / "best" / "metadata.json").read_text())
    meta["run_config"]["seed"] = 6
    (other / "best" / "metadata.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="another configuration"):
        ship_best("p", plan, other, models=tmp_path / "models")
    shutil.rmtree(other / "best")
    with pytest.raises(ValueError, match="not a finished run with a best/ policy"):
        ship_best("p", plan, other, models=tmp_path / "models")


def test_ship_run_ships_one_saved_policy_with_its_reason(sac_runs: dict, tmp_path: Path) -> None:
    from benchmarks.rl.ship import ship_run

    source = sac_runs["root"] / "whole" / "best"
    record = ship_run(source, "a study's rule", models=tmp_path / "models")
    dest = tmp_path / "models" / "cartpole" / "sac"
    assert (dest / "model.zip").read_bytes() == (source / "model.zip").read_bytes()
    assert (dest / "vecnormalize.pkl").read_bytes() == (source / "vecnormalize.pkl").read_bytes()
    meta = json.loads((dest / "metadata.json").read_text())
    assert meta["shipped_from"] == record and record["rule"] == "a study's rule"
    env = gym.make("gp_envs/CartPoleSwingUp-v0", scenario="online")
    assert RLAgent.load(dest, env).training_steps == meta["training_steps"]
    run_curve = _curve(source.parent)
    assert _curve(dest) == [r for r in run_curve
                            if int(r["timesteps"]) <= meta["training_steps"]] != run_curve
    with pytest.raises(ValueError, match="say why"):
        ship_run(source, " ", models=tmp_path / "models")
    with pytest.raises(ValueError, match="not a saved agent"):
        ship_run(tmp_path, "why", models=tmp_path / "models")
