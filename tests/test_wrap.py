"""Any Gymnasium env with a nominal model (gp_envs.wrap): checked against Gymnasium's own env
(Pendulum-v1: its internal state and reward formula are the independent reference) and a tiny
integrator env whose success time is known in closed form."""

from __future__ import annotations

import casadi as ca
import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

import gp_envs
from gp_agents import collect_initial_data, make_mpc, rollout
from gp_envs import ControlModel, Task


def pendulum_ode(x, u, p):
    """Pendulum-v1, theta = 0 upright: thetaddot = 3 g / (2 l) sin(theta) + 3 u / (m l^2)."""
    m, length, g = p[0], p[1], p[2]
    return ca.vertcat(x[1], 3 * g / (2 * length) * ca.sin(x[0]) + 3 / (m * length**2) * u[0])


def pendulum_model(mass: float = 1.0, **changes) -> ControlModel:
    task = Task(goal=np.zeros(2), Q=np.diag([1.0, 0.1]), R=[[0.001]], Qf=np.diag([10.0, 1.0]),
                goal_tolerance=[0.1, np.inf], hold_time=1.0, duration=10.0,
                periodic_indices=(0,))
    fields = dict(name="pendulum_v1", ode=pendulum_ode,
                  params={"m": mass, "l": 1.0, "g": 10.0}, state_names=("theta", "thetadot"),
                  control_names=("torque",), dt=0.05, u_lb=[-2.0], u_ub=[2.0], task=task,
                  x_lb=[-np.inf, -8.0], x_ub=[np.inf, 8.0], substeps=4, angle_indices=(0,),
                  dynamic_indices=(1,))
    return ControlModel(**{**fields, **changes})


def angle(obs: np.ndarray) -> np.ndarray:
    return np.array([np.arctan2(obs[1], obs[0]), obs[2]])


def wrapped(mass: float = 1.0, **kwargs) -> gp_envs.ModelWrapper:
    return gp_envs.wrap(gym.make("Pendulum-v1"), pendulum_model(mass), state=angle, **kwargs)


class Integrator(gym.Env):
    """x' = u with dt = 0.1 s, started at x = 0; no notion of a goal."""

    dt = 0.1
    observation_space = spaces.Box(-np.inf, np.inf, (1,), np.float32)
    action_space = spaces.Box(-1.0, 1.0, (1,), np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.x = 0.0
        return np.array([self.x], np.float32), {}

    def step(self, action):
        self.x += self.dt * float(action[0])
        return np.array([self.x], np.float32), -abs(self.x), False, False, {"env_key": 1}


def integrator_model(**changes) -> ControlModel:
    task = Task(goal=[0.5], Q=[[1.0]], R=[[0.0]], goal_tolerance=[0.05], hold_time=0.3,
                duration=2.0)
    fields = dict(name="integrator", ode=lambda x, u, p: u[0], params={},
                  state_names=("x",), control_names=("v",), dt=0.1, u_lb=[-1.0], u_ub=[1.0],
                  task=task)
    return ControlModel(**{**fields, **changes})


# ------------------------------------------------------------------ the wrapped env
def test_a_wrapped_gymnasium_env_passes_the_env_checker_and_keeps_its_reward():
    env = wrapped()
    check_env(env, skip_render_check=True)
    obs, info = env.reset(seed=3)
    base = env.unwrapped
    theta, thetadot = base.state
    np.testing.assert_allclose(obs, [np.arctan2(np.sin(theta), np.cos(theta)), thetadot],
                               atol=1e-6)
    assert info["at_goal"] is False and info["success"] is False
    for u in (-2.0, 0.7, 5.0):
        theta, thetadot = base.state
        norm = np.mod(theta + np.pi, 2 * np.pi) - np.pi
        expected = -(norm**2 + 0.1 * thetadot**2 + 0.001 * min(u, 2.0) ** 2)
        obs, reward, *_, info = env.step(np.array([u], np.float32))
        assert reward == pytest.approx(expected, rel=1e-5)  # Pendulum-v1's own formula
        assert info["action_clipped"] is (u > 2.0)
        np.testing.assert_allclose(obs, angle(base._get_obs()), atol=1e-6)
    assert env.observation_space.shape == (2,) and env.action_space.shape == (1,)


def test_success_is_the_tasks_hold_rule_and_the_envs_own_info_stays():
    env = gp_envs.wrap(Integrator(), integrator_model())
    env.reset(seed=0)
    infos = [env.step(np.array([1.0], np.float32))[-1] for _ in range(5)]  # x = 0.1 ... 0.5
    assert [i["at_goal"] for i in infos] == [False, False, False, False, True]
    infos += [env.step(np.zeros(1, np.float32))[-1] for _ in range(3)]  # held at 0.5
    # success after the hold time of 0.3 s = 3 periods at the goal
    assert [i["success"] for i in infos] == [False] * 6 + [True] * 2
    assert infos[-1]["at_goal_since"] == pytest.approx(0.5) and infos[-1]["env_key"] == 1
    assert infos[-1]["time"] == pytest.approx(0.8)


def test_the_model_is_found_through_the_wrapper_chain():
    env = gym.wrappers.RecordEpisodeStatistics(wrapped(0.4))
    assert gp_envs.nominal_model(env).params["m"] == 0.4
    agent = make_mpc(env, "nominal", horizon=1.0)
    assert agent.model.params["m"] == 0.4
    with pytest.raises(TypeError, match=r"no nominal model.*gp_envs\.wrap"):
        gp_envs.nominal_model(gym.make("Pendulum-v1"))


@pytest.mark.parametrize("bad, error, match", [
    (dict(env=gym.make("CartPole-v1")), TypeError, "Box action space"),
    (dict(model="pendulum"), TypeError, "ControlModel"),
    (dict(state=None), ValueError, r"pass state="),
    (dict(state="angle"), TypeError, "state must be a function"),
    (dict(action=lambda u: np.concatenate([u, u])), ValueError, r"action shape \(1,\)"),
    (dict(model=pendulum_model(u_lb=[-3.0], u_ub=[3.0])), ValueError, "contradict"),
    (dict(model=pendulum_model(u_lb=[-np.inf], u_ub=[2.0])), ValueError, "finite control"),
    (dict(model=pendulum_model(dt=0.1)), ValueError, r"0\.05 s per step.*dt 0\.1"),
    (dict(true_model=pendulum_model(dt=0.1)), ValueError, "true_model must have"),
    (dict(true_model=object()), TypeError, "true_model"),
])
def test_bad_inputs_to_wrap_raise(bad, error, match):
    kwargs = {"env": gym.make("Pendulum-v1"), "model": pendulum_model(), "state": angle, **bad}
    with pytest.raises(error, match=match):
        gp_envs.wrap(kwargs.pop("env"), kwargs.pop("model"), **kwargs)


@pytest.mark.parametrize("state, match", [
    (lambda o: np.zeros(3), r"shape \(2,\), got \(3,\)"),
    (lambda o: np.array([np.nan, 0.0]), "non-finite"),
    (lambda o: "x", "numbers"),
])
def test_a_bad_state_map_raises_at_reset(state, match):
    env = gp_envs.wrap(gym.make("Pendulum-v1"), pendulum_model(), state=state)
    with pytest.raises(ValueError, match=match):
        env.reset(seed=0)


@pytest.mark.parametrize("action", [np.zeros(2), np.array([np.nan]), np.zeros((1, 1)), "a"])
def test_a_bad_control_raises(action):
    env = wrapped()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="action"):
        env.step(action)


def test_the_oracle_needs_a_true_model():
    with pytest.raises(ValueError, match=r"no true model.*true_model="):
        make_mpc(wrapped(0.4), "oracle", horizon=1.0).act(np.zeros(2))
    env = wrapped(0.4, true_model=pendulum_model(1.0))
    oracle = make_mpc(env, "oracle", horizon=1.0)
    env.reset(seed=0)
    assert gp_envs.oracle_model(env).params["m"] == 1.0
    assert oracle._model_source().params["m"] == 1.0


# ------------------------------------------------------------------ data and closed loop
def test_initial_data_default_to_uniform_controls_and_take_a_policy():
    env = wrapped()
    data = collect_initial_data(env, 250, seed=4)  # two episodes (200 steps each)
    again = collect_initial_data(wrapped(), 250, seed=4)
    np.testing.assert_array_equal(data.X, again.X)
    np.testing.assert_array_equal(data.U, again.U)
    assert data.U.min() >= -2.0 and data.U.max() <= 2.0 and data.U.std() > 0.9  # U(-2, 2)
    # within an episode the next state is the next observation
    np.testing.assert_array_equal(data.X[1:200], data.X_next[:199])
    const = collect_initial_data(env, 30, seed=4, action_noise=0.0,
                                 policy=lambda obs, t: np.array([0.5 + t]))
    np.testing.assert_allclose(const.U[:, 0], 0.5 + 0.05 * np.arange(30), rtol=1e-6)
    with pytest.raises(TypeError, match="policy"):
        collect_initial_data(env, 10, policy="pd")
    with pytest.raises(ValueError, match="data policy must return"):
        collect_initial_data(env, 10, policy=lambda obs, t: np.zeros(3))


def test_the_nominal_mpc_swings_pendulum_v1_up():
    """The correct model swings Gymnasium's own pendulum up from near hanging (seed 10 starts
    at 2.87 rad) and holds it: the wrapped env's success, judged by the model's task."""
    env = wrapped()
    agent = make_mpc(env, "nominal", horizon=2.5)
    episode = rollout(env, agent, seed=10)
    assert abs(episode.observations[0, 0]) > 2.8  # it started near hanging down
    assert episode.steps == 200 and episode.success
    assert np.all(np.abs(episode.observations[-20:, 0]) < 0.1)


def test_a_systems_planning_box_may_differ_from_its_termination_box():
    """GPEnv.PLAN_X_LB/UB: the nominal model's box; the episode still ends at X_LB/X_UB."""
    from gp_envs.cartpole_swingup import CartPoleSwingUpEnv

    class Narrow(CartPoleSwingUpEnv):
        PLAN_X_LB = np.array([-1.0, -np.inf, -10.0, -25.0])
        PLAN_X_UB = np.array([1.0, np.inf, 10.0, 25.0])

    env = Narrow()
    np.testing.assert_array_equal(env.nominal_model.x_ub, Narrow.PLAN_X_UB)
    env.reset(seed=0, options={"state": np.array([1.5, 0.0, 0.0, 0.0])})  # outside the plan box
    *_, terminated, _, info = env.step(np.zeros(1, np.float32))
    assert not terminated and info["termination_reason"] is None  # inside the track
    assert gp_envs.oracle_model(env).x_ub[0] == 1.0  # the truth's model, the same box


@pytest.mark.parametrize("option", [{"keep_system": True}, {"state": np.zeros(2)}])
def test_gp_envs_own_reset_options_are_refused_for_another_env(option):
    env = wrapped()
    with pytest.raises(ValueError, match="gp_envs envs' own"):
        env.reset(seed=0, options=option)
    env.reset(seed=0, options={"x_init": 1.0, "y_init": 0.5})  # Pendulum-v1's own pass


# ------------------------------------------------------------------ outside truths
def test_outside_truth_tells_a_wrapped_env_from_a_package_ode():
    assert gp_envs.outside_truth(gym.wrappers.RecordEpisodeStatistics(wrapped()))
    assert not gp_envs.outside_truth(gym.make("gp_envs/CartPoleSwingUp-v0"))
    with pytest.raises(TypeError, match=r"outside_truth needs.*gp_envs\.wrap"):
        gp_envs.outside_truth(gym.make("Pendulum-v1"))


@pytest.mark.parametrize("recipe", ["robust", "parametric", "blackbox"])
def test_learning_recipes_plan_with_the_learner_itself_on_an_outside_truth(recipe):
    """Converged: the learner itself in the NLP on a wrapped env, its expansion about the
    previous plan on a package system (whose truth is the model's ODE); the RTI keeps the
    system's tuned term, and term= overrides the rule."""
    outside, own = wrapped(0.4), gym.make("gp_envs/CartPoleSwingUp-v0")
    assert make_mpc(outside, recipe).config.term.name == "exact"
    assert make_mpc(own, recipe).config.term.name == "linearized"
    assert make_mpc(outside, recipe, scheme="rti").config.term.name == "linearized"
    assert make_mpc(outside, recipe, scheme="sqp").config.term.name == "linearized"
    assert make_mpc(outside, recipe, term="linearized").config.term.name == "linearized"


def test_the_nominal_guard_on_an_outside_truth_asks_for_the_linearized_term():
    from gp_agents.mpc import Converged

    env = wrapped(0.4)
    with pytest.raises(ValueError, match=r"outside truth: pass\s+term='linearized'"):
        make_mpc(env, scheme=Converged(nominal_above=1.0))
    agent = make_mpc(env, scheme=Converged(nominal_above=1.0), term="linearized")
    assert agent.config.term.name == "linearized"
