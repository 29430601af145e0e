"""PILCO's cart pole (gp_envs/PilcoCartPole-v0): its physics against PILCO's printed equations,
its numbers against their sources, the tip-distance success criterion, data and a nominal MPC."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env

import gp_agents
import gp_envs
from gp_agents.agent import rollout
from gp_envs.physics import pilco_cartpole
from gp_envs.pilco_cartpole import PilcoCartPoleEnv, TipTask, pilco_loss

ENV_ID = "gp_envs/PilcoCartPole-v0"


def make(**kwargs) -> gym.Env:
    return gym.make(ENV_ID, disable_env_checker=True, **kwargs)


# ------------------------------------------------------------------------ PILCO's equations
def _dynamics_cp(z: np.ndarray, f: float, M: float = 0.5, m: float = 0.5, l: float = 0.5,
                 b: float = 0.1, g: float = 9.82) -> np.ndarray:
    """``dynamics_cp.m`` (pilco-matlab V0.9, scenarios/cartPole) transcribed: state
    ``[x, v, dtheta, theta]``; the independent reference the rod model is checked against."""
    _, v, dth, th = z
    s, c = np.sin(th), np.cos(th)
    dv = (2 * m * l * dth**2 * s + 3 * m * g * s * c + 4 * f - 4 * b * v) / (
        4 * (M + m) - 3 * m * c**2)
    ddth = (-3 * m * l * dth**2 * s * c - 6 * (M + m) * g * s - 6 * (f - b * v) * c) / (
        4 * l * (m + M) - 3 * m * l * c**2)
    return np.array([v, dv, ddth, dth])


def _energy_cp(z: np.ndarray, M: float = 0.5, m: float = 0.5, l: float = 0.5,
               g: float = 9.82) -> float:
    """``dynamics_cp.m`` called with two arguments: the total mechanical energy (J)."""
    _, v, dth, th = z
    return (M + m) * v**2 / 2 + m * l**2 * dth**2 / 6 + m * l * (v * dth - g) * np.cos(th) / 2


PILCO_ORDER = [0, 2, 3, 1]
"""Our ``[x, theta, xdot, thetadot]`` in PILCO's order ``[x, v, dtheta, theta]``."""


def test_the_rod_model_is_pilcos_dynamics_cp():
    truth = gp_envs.oracle_model(make())
    rng = np.random.default_rng(0)
    for _ in range(20):
        x = rng.uniform([-1, -np.pi, -3, -8], [1, np.pi, 3, 8])
        f = rng.uniform(-10, 10)
        ours = np.asarray(truth.f(x, [f]), float)
        theirs = _dynamics_cp(x[PILCO_ORDER], f)
        np.testing.assert_allclose(ours[PILCO_ORDER], theirs, rtol=1e-12, atol=1e-12)
        energy = float(pilco_cartpole.mechanical_energy(x, truth.param_vector))
        assert energy == pytest.approx(_energy_cp(x[PILCO_ORDER]), rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("x0", [[0.0, 2.0, 0.5, 3.0], [0.3, 0.1, -1.0, 8.0]])
def test_energy_is_conserved_without_friction_and_force(x0):
    model = gp_envs.oracle_model(make()).with_params(b=0.0)
    x = np.array(x0)
    e0 = float(pilco_cartpole.mechanical_energy(x, model.param_vector))
    for _ in range(50):  # 5 s
        x = model.step(x, [0.0])
    e1 = float(pilco_cartpole.mechanical_energy(x, model.param_vector))
    # RK4 with 0.01 s substeps (the other cart pole's 0.005 s reaches 1e-6)
    assert abs(e1 - e0) < 1e-5 * max(1.0, abs(e0))


def test_friction_dissipates():
    model = gp_envs.oracle_model(make())
    x = np.array([0.0, 2.0, 1.0, 3.0])
    e0 = float(pilco_cartpole.mechanical_energy(x, model.param_vector))
    for _ in range(20):
        x = model.step(x, [0.0])
    assert float(pilco_cartpole.mechanical_energy(x, model.param_vector)) < e0


# ------------------------------------------------------------------------ the numbers
SOURCES = {  # value: where it comes from (see the env module's docstring)
    "mc": (0.5, "dynamics_cp.m: M = 0.5"),
    "mp": (0.5, "dynamics_cp.m: m = 0.5"),
    "l": (0.5, "dynamics_cp.m: l = 0.5"),
    "b": (0.1, "dynamics_cp.m: b = 0.1"),
    "g": (9.82, "dynamics_cp.m: g = 9.82"),
}


def test_the_true_parameters_are_pilcos():
    truth = gp_envs.oracle_model(make())
    for name, (value, source) in SOURCES.items():
        assert truth.params[name] == value, source


def test_the_trial_is_pilcos():
    env = make()
    base = env.unwrapped
    task = base.nominal_model.task
    assert base.DT == 0.1  # settings_cp.m: dt = 0.10
    assert task.duration == 4.0 and env.spec.max_episode_steps == 40  # T = 4.0, H = 40
    np.testing.assert_array_equal(env.action_space.high, [10.0])  # policy.maxU = 10
    np.testing.assert_array_equal(env.action_space.low, [-10.0])
    np.testing.assert_array_equal(task.goal, [0.0, np.pi, 0.0, 0.0])  # cost.target, reordered
    assert isinstance(task, TipTask)
    assert task.pole_length == 0.5  # cost.p = 0.5
    assert task.tip_tolerance == 0.08  # GP-MPC: 8 cm
    assert round(task.hold_time / base.DT) == 10  # GP-MPC: 10 consecutive steps
    # settings_cp.m: mu0 = 0, S0 = diag(0.1^2): the start distribution over many resets
    starts = np.array([base._state for _ in range(400) if env.reset(seed=_) is not None])
    np.testing.assert_allclose(starts.mean(axis=0), 0.0, atol=0.02)
    np.testing.assert_allclose(starts.std(axis=0), 0.1, atol=0.015)


def test_the_nominal_model_is_wrong_as_declared():
    env = make()
    truth, nominal = gp_envs.oracle_model(env), env.unwrapped.nominal_model
    assert nominal.params["b"] == 0.0 < truth.params["b"]  # friction unmodelled
    for name in ("mc", "mp"):  # masses 10 % low
        assert nominal.params[name] == pytest.approx(0.9 * truth.params[name])
    for name in ("l", "g"):
        assert nominal.params[name] == truth.params[name]


def test_pilcos_loss_is_the_saturating_tip_cost():
    task = make().unwrapped.nominal_model.task
    assert pilco_loss(task, np.array([0.0, np.pi, 0.0, 0.0])) == pytest.approx(0.0, abs=1e-15)
    # tip 0.25 m (one cost width) off: 1 - exp(-1/2)
    assert pilco_loss(task, np.array([0.25, np.pi, 1.0, 1.0])) == pytest.approx(
        1 - np.exp(-0.5))
    # hanging at the centre: the tip 2 l = 1 m below its target
    assert pilco_loss(task, np.zeros(4)) == pytest.approx(1 - np.exp(-0.5 / 0.25**2))


# ------------------------------------------------------------------------ success
def _hold(offset: float) -> list[dict]:
    """Infos of 12 force-free steps from the upright pole at rest with the cart ``offset`` m
    from the centre (an equilibrium: the tip stays ``offset`` from its target)."""
    env = make()
    env.reset(seed=0, options={"state": np.array([offset, np.pi, 0.0, 0.0])})
    return [env.step(np.zeros(1, np.float32))[4] for _ in range(12)]


def test_success_is_the_tip_within_8_cm_for_10_steps():
    inside = _hold(0.07)
    assert all(i["at_goal"] for i in inside)
    assert [i["success"] for i in inside] == [False] * 9 + [True] * 3
    assert [i["at_goal_since"] for i in inside] == [pytest.approx(0.1)] * 12
    assert inside[-1]["distance_to_goal"] == pytest.approx(0.07, abs=1e-6)
    outside = _hold(0.09)
    assert not any(i["at_goal"] or i["success"] for i in outside)
    assert all(i["at_goal_since"] is None for i in outside)
    assert outside[-1]["distance_to_goal"] == pytest.approx(0.09, abs=1e-6)


def test_the_tip_criterion_judges_the_angle_too():
    task = make().unwrapped.nominal_model.task
    for dist, expected in ((0.07, True), (0.09, False)):
        # the tip on its circle, a chord of `dist` from the top: 2 l sin(d theta / 2) = dist
        dth = 2 * np.arcsin(dist / (2 * task.pole_length))
        for sign in (-1, 1):
            x = np.array([0.0, np.pi + sign * dth, 0.0, 0.0])
            assert task.tip_distance(x) == pytest.approx(dist)
            assert task.at_goal(x) is expected
            # the cart moved under the tip's target leaves only the tip's height deficit
            shifted = x + np.array([sign * task.pole_length * np.sin(dth), 0, 0, 0])
            assert task.tip_distance(shifted) == pytest.approx(
                task.pole_length * (1 - np.cos(dth)), rel=1e-9)


def test_the_final_stretch_start_after_leaving_the_goal():
    """Leaving the goal resets the stretch: at_goal_since is the start of the latest one."""
    env = make()
    env.reset(seed=0, options={"state": np.array([0.0, np.pi, 0.0, 0.0])})
    infos = [env.step(np.array([10.0], np.float32))[4] for _ in range(3)]
    assert infos[0]["at_goal_since"] == pytest.approx(0.1)
    left = next(k for k, i in enumerate(infos) if not i["at_goal"])
    assert infos[left]["at_goal_since"] is None


# ------------------------------------------------------------------------ API, data, MPC
def test_gymnasium_env_checker_passes():
    env = gym.make(ENV_ID)
    gym_check_env(env.unwrapped, skip_render_check=True)
    assert isinstance(env.unwrapped, PilcoCartPoleEnv)
    frame = make(render_mode="rgb_array")
    frame.reset(seed=0)
    assert frame.render().ndim == 3


def test_the_system_is_registered_with_its_controller_defaults():
    from gp_agents.defaults import system_defaults

    system = gp_envs.get_system("pilco_cartpole")
    assert system.env_id == ENV_ID and system.max_episode_steps == 40
    planning = system_defaults("pilco_cartpole").planning
    assert (planning.horizon, planning.n_nodes, planning.n_intervals,
            planning.nodes_per_period) == (2.5, 16, 1, 3)


def test_initial_data_is_pilcos_random_trial():
    env = make()
    data = gp_agents.collect_initial_data(env, 50, seed=0)
    assert data.X.shape == (50, 4) and data.U.shape == (50, 1)
    assert np.all(np.abs(data.U) <= 10.0)
    assert data.U.std() > 4.0  # uniform on [-10, 10]: standard deviation 5.8 N
    again = gp_agents.collect_initial_data(make(), 50, seed=0)
    np.testing.assert_array_equal(data.U, again.U)


def test_the_nominal_mpc_swings_up_within_the_trial():
    env = make()
    mpc = gp_agents.PseudospectralMPC.from_env(env)
    for seed in (0, 1):
        ep = rollout(env, mpc, seed)
        final = ep.infos[-1]
        assert len(ep.infos) == 40 and final["success"], seed
        # the held final stretch began well inside the trial (measured: 1.5 s, 1.4 s)
        assert final["at_goal_since"] <= 2.0, (seed, final["at_goal_since"])
