"""Environment tests: physics against independent facts, API conventions, hiding, bad input."""

from __future__ import annotations

import copy
from typing import ClassVar

import casadi as ca
import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env

import gp_envs
from gp_envs.physics import cartpole, pendulum

ENV_IDS = list(gp_envs.ENV_IDS)


def make(env_id: str, **kwargs):
    return gym.make(env_id, disable_env_checker=True, **kwargs)


# ------------------------------------------------------------------------ cart-pole physics
def _cartpole_model(**params):
    env = make("gp_envs/CartPoleSwingUp-v0")
    return env.unwrapped.nominal_model.with_params(**params)


def _energy(x, model):
    return float(cartpole.mechanical_energy(x, model.param_vector))


@pytest.mark.parametrize("x0", [[0.0, 2.0, 0.5, 3.0], [0.3, 0.1, -1.0, 8.0]])
def test_cartpole_energy_conserved_without_damping(x0):
    model = _cartpole_model(b1=0.0, b2=0.0)
    x = np.array(x0)
    e0 = _energy(x, model)
    for _ in range(100):  # 5 s
        x = model.step(x, [0.0])
        assert abs(_energy(x, model) - e0) < 1e-6 * max(1.0, abs(e0))


def test_cartpole_damping_never_adds_energy():
    model = _cartpole_model(b1=0.3, b2=0.3)
    rng = np.random.default_rng(0)
    for _ in range(20):
        x = rng.uniform([-1, -np.pi, -3, -10], [1, np.pi, 3, 10])
        e = _energy(x, model)
        for _ in range(40):
            x = model.step(x, [0.0])
            e_new = _energy(x, model)
            assert e_new <= e + 1e-9
            e = e_new


# ------------------------------------------------------------------------ pendulum physics
def _pendulum_model(**params):
    return make("gp_envs/PendulumSwingUp-v0").unwrapped.nominal_model.with_params(**params)


def test_pendulum_energy_conserved_without_friction():
    model = _pendulum_model(b=0.0)
    x = np.array([0.5, 3.0])
    e0 = float(pendulum.mechanical_energy(x, model.param_vector))
    for _ in range(100):  # 5 s
        x = model.step(x, [0.0])
        assert float(pendulum.mechanical_energy(x, model.param_vector)) == pytest.approx(
            e0, abs=1e-6 * max(1.0, abs(e0)))


def test_pendulum_power_balance_is_torque_minus_friction():
    """dE/dt = thd (tau - b thd), from the energy and the ODE by differentiation."""
    model = _pendulum_model(b=0.3)
    x, u = ca.SX.sym("x", 2), ca.SX.sym("u", 1)
    e = pendulum.mechanical_energy(x, model.param_vector)
    fn = ca.Function("edot", [x, u], [ca.jtimes(e, x, model.f(x, u))])
    rng = np.random.default_rng(2)
    for _ in range(10):
        s, tau = rng.uniform(-4, 4, size=2), rng.uniform(-2, 2)
        assert float(fn(s, tau)) == pytest.approx(s[1] * (tau - 0.3 * s[1]), abs=1e-9)


def test_pendulum_small_oscillation_period():
    """Undamped, unforced, small amplitude: period 2 pi sqrt(l / g)."""
    model = _pendulum_model(b=0.0)
    x, t, crossings = np.array([0.01, 0.0]), 0.0, []
    while len(crossings) < 3:
        x_new = model.step(x, [0.0])
        if x[1] > 0 >= x_new[1]:  # a maximum of theta, interpolated
            crossings.append(t + model.dt * x[1] / (x[1] - x_new[1]))
        x, t = x_new, t + model.dt
    p = model.params
    assert np.diff(crossings).mean() == pytest.approx(2 * np.pi * np.sqrt(p["l"] / p["g"]),
                                                      rel=2e-3)


def test_cartpole_paper_sign_of_b2_would_add_energy():
    """The errata's point, checked independently: the printed b2 sign is an energy source.

    dE/dt for f = 0 from the dissipative model equals -b1 xd^2 - b2 thd^2 (power of friction).
    """
    model = _cartpole_model(b1=0.2, b2=0.3)
    x = ca.SX.sym("x", 4)
    e = cartpole.mechanical_energy(x, model.param_vector)
    edot = ca.jtimes(e, x, model.f(x, ca.DM([0.0])))
    fn = ca.Function("edot", [x], [edot])
    rng = np.random.default_rng(1)
    for _ in range(10):
        s = rng.uniform(-3, 3, size=4)
        expected = -0.2 * s[2] ** 2 - 0.3 * s[3] ** 2
        assert float(fn(s)) == pytest.approx(expected, abs=1e-9)


def _linearization_eigs(model, x_eq):
    x = ca.SX.sym("x", 4)
    jac = ca.Function("A", [x], [ca.jacobian(model.f(x, ca.DM([0.0])), x)])
    return np.linalg.eigvals(np.asarray(jac(x_eq)))


def test_cartpole_hanging_is_stable_upright_is_unstable():
    model = _cartpole_model(b1=0.3, b2=0.3)
    hanging = _linearization_eigs(model, [0, 0, 0, 0])
    upright = _linearization_eigs(model, [0, np.pi, 0, 0])
    assert np.all(hanging.real <= 1e-9)
    assert np.max(upright.real) > 1.0  # sqrt(g/l)-like growth rate
    # and in simulation: a small push from hanging stays small, from upright grows
    x = np.array([0.0, 0.05, 0.0, 0.0])
    for _ in range(60):
        x = model.step(x, [0.0])
    assert abs(x[1]) < 0.05
    x = np.array([0.0, np.pi + 0.01, 0.0, 0.0])
    for _ in range(40):
        x = model.step(x, [0.0])
    assert abs(x[1] - np.pi) > 0.5


# ------------------------------------------------------------------------ quadrotor physics
def _quad_model():
    return make("gp_envs/Quadrotor-v0", scenario="gp").unwrapped.nominal_model


def test_quadrotor_hover_holds_still():
    model = _quad_model()
    m, g = model.params["m"], model.params["g"]
    x0 = np.zeros(12)
    x0[:3] = [0.3, -0.2, 1.0]
    x = x0.copy()
    for _ in range(100):
        x = model.step(x, np.full(4, m * g / 4))
    np.testing.assert_allclose(x, x0, atol=1e-12)


def test_quadrotor_pure_roll_torque_changes_only_roll():
    model = _quad_model()
    m, g, arm, jx = (model.params[k] for k in ("m", "g", "L", "Jx"))
    h, d = m * g / 4, 0.01
    u = np.array([h, h - d, h, h + d])  # F4 - F2 = 2d, F1 = F3, yaw torque zero
    x = np.zeros(12)
    t = 0.0
    for _ in range(4):
        x = model.step(x, u)
        t += model.dt
    alpha = arm * 2 * d / jx
    assert x[3] == pytest.approx(0.5 * alpha * t**2, rel=1e-9)
    assert x[9] == pytest.approx(alpha * t, rel=1e-9)
    np.testing.assert_allclose(x[[4, 5, 10, 11]], 0.0, atol=1e-14)


# ------------------------------------------------------------------------ Dubins physics
def _dubins_model():
    return make("gp_envs/DubinsObstacle-v0").unwrapped.nominal_model.with_params(b1=0.3, b2=0.2)


def test_dubins_straight_line_closed_form():
    model = _dubins_model()
    x0 = np.array([1.0, -2.0, 0.7])
    x = x0.copy()
    for _ in range(30):
        x = model.step(x, [1.5, 0.0])
    t = 30 * model.dt
    v = 0.7 * 1.5
    np.testing.assert_allclose(x, [1 + v * t * np.cos(0.7), -2 + v * t * np.sin(0.7), 0.7],
                               atol=1e-12)


def test_dubins_circle_closed_form():
    model = _dubins_model()
    u1, u2 = 1.2, 0.8
    v, w = 0.7 * u1, 0.8 * u2
    x = np.array([0.0, 0.0, 0.0])
    for _ in range(50):
        x = model.step(x, [u1, u2])
    t = 50 * model.dt
    radius = v / w
    expected = [radius * np.sin(w * t), radius * (1 - np.cos(w * t)), w * t]
    np.testing.assert_allclose(x, expected, atol=1e-7)


# ------------------------------------------------------------------------ integration accuracy
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_halving_rk4_substeps_changes_trajectory_negligibly(env_id):
    env = make(env_id)
    model = env.unwrapped.nominal_model
    fine = gp_envs.ControlModel(**{**_fields(model), "substeps": 2 * model.substeps})
    rng = np.random.default_rng(0)
    obs, _ = env.reset(seed=0)
    x = x_fine = np.asarray(obs, float)
    mid = (model.u_lb + model.u_ub) / 2
    for _ in range(round(5.0 / model.dt)):
        u = mid + 0.3 * (model.u_ub - model.u_lb) * rng.uniform(-0.5, 0.5, model.n_controls)
        x, x_fine = model.step(x, u), fine.step(x_fine, u)
    scale = max(1.0, float(np.max(np.abs(x_fine))))
    assert np.max(np.abs(x - x_fine)) < 1e-5 * scale


def _fields(model):
    return {k: getattr(model, k) for k in (
        "name", "ode", "param_names", "params", "state_names", "control_names", "dt", "x_lb",
        "x_ub", "u_lb", "u_ub", "task", "substeps", "angle_indices", "dynamic_indices")}


# ------------------------------------------------------------------------ Gymnasium conventions
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_gymnasium_env_checker(env_id):
    gym_check_env(gym.make(env_id).unwrapped, skip_render_check=True)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_sb3_env_checker(env_id):
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    sb3_checker.check_env(gym.make(env_id).unwrapped, warn=True)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_string_entry_point_form_works(env_id):
    env = gym.make("gp_envs:" + env_id)
    assert env.observation_space.shape == (env.unwrapped.nominal_model.n_states,)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_step_types_and_copies(env_id):
    env = make(env_id)
    obs, info = env.reset(seed=3)
    assert obs.dtype == np.float32 and env.observation_space.contains(obs)
    obs2, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert type(reward) is float and type(terminated) is bool and type(truncated) is bool
    assert obs2.dtype == np.float32
    obs2[:] = 1e6  # mutating the returned array must not touch the env
    obs3, *_ = env.step(env.action_space.sample())
    assert np.all(np.abs(obs3) < 1e5)
    for key in ("success", "constraint_violation", "distance_to_goal"):
        assert key in info


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_seeding_reproducible_and_distinct(env_id):
    def rollout(seed):
        env = make(env_id)
        obs, _ = env.reset(seed=seed)
        env.action_space.seed(123)
        traj = [obs]
        for _ in range(20):
            obs, *_ = env.step(env.action_space.sample())
            traj.append(obs)
        return np.array(traj)

    np.testing.assert_array_equal(rollout(7), rollout(7))
    assert not np.array_equal(rollout(7), rollout(8))


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_reset_from_given_state(env_id):
    env = make(env_id)
    n = env.unwrapped.nominal_model.n_states
    state = np.zeros(n)
    state[0] = 0.5
    obs, _ = env.reset(seed=0, options={"state": state})
    assert obs[0] == pytest.approx(0.5)
    with pytest.raises(ValueError, match="shape"):
        env.reset(options={"state": np.zeros(n + 1)})
    with pytest.raises(ValueError, match="finite"):
        env.reset(options={"state": np.full(n, np.nan)})


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_render_rgb_array_shows_the_state(env_id):
    env = make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    first = env.render()
    assert first.ndim == 3 and first.shape[2] == 3 and first.dtype == np.uint8
    for _ in range(10):
        env.step(env.action_space.high)
    second = env.render()
    assert second.shape == first.shape
    assert np.mean(first != second) > 1e-3
    env.close()


# ------------------------------------------------------------------------ bad input
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_bad_actions_raise_and_out_of_bounds_clips(env_id):
    env = make(env_id)
    env.reset(seed=0)
    m = env.action_space.shape[0]
    with pytest.raises(ValueError, match="finite"):
        env.step(np.full(m, np.nan))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(m + 1))
    *_, info = env.step(env.action_space.high + 100.0)
    assert info["action_clipped"]


def test_unknown_scenario_and_parameter_raise():
    with pytest.raises(ValueError, match="unknown scenario"):
        gym.make("gp_envs/CartPoleSwingUp-v0", scenario="nope")
    with pytest.raises(ValueError, match="unknown parameter"):
        gym.make("gp_envs/Quadrotor-v0", true_params={"mass": 1.0})
    with pytest.raises(ValueError, match="randomize"):
        gym.make("gp_envs/Quadrotor-v0", randomize=-0.1)


# ------------------------------------------------------------------------ hidden truth
_SECRET = {
    "gp_envs/CartPoleSwingUp-v0": {"mc": 1.2345671, "mp": 0.4567891, "l": 0.5432167,
                                   "b1": 0.2718281, "b2": 0.3141592},
    "gp_envs/Quadrotor-v0": {"m": 1.0123457, "L": 0.2412345},
    "gp_envs/DubinsObstacle-v0": {"b1": 0.2987651, "b2": 0.3123457},
    "gp_envs/PendulumSwingUp-v0": {"m": 1.0234567, "l": 0.5123457, "b": 0.2876543},
}


def _public_values(obj, depth=0, seen=None):
    """Every number reachable from ``obj`` through public attributes, mappings and sequences."""
    seen = set() if seen is None else seen
    if id(obj) in seen or depth > 6:
        return
    seen.add(id(obj))
    if isinstance(obj, (int, float, np.floating, np.integer)):
        yield float(obj)
    elif isinstance(obj, np.ndarray):
        if obj.dtype.kind in "fiu":
            yield from obj.astype(float).ravel().tolist()
    elif isinstance(obj, dict) or (hasattr(obj, "items") and hasattr(obj, "keys")):
        for v in obj.values():
            yield from _public_values(v, depth + 1, seen)
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            yield from _public_values(v, depth + 1, seen)
    elif hasattr(obj, "__dict__") and not isinstance(obj, type) and not callable(obj):
        for k, v in vars(obj).items():
            if not k.startswith("_"):
                yield from _public_values(v, depth + 1, seen)


def _visible_values(env, skip_spec, seed=0):
    obs, info = env.reset(seed=seed)
    values = list(_public_values(obs)) + list(_public_values(info))
    for _ in range(5):
        obs, r, _te, _tr, info = env.step(env.action_space.sample())
        values += list(_public_values(obs)) + list(_public_values(info)) + [r]
    public = {k: v for k, v in vars(env.unwrapped).items()
              if not k.startswith("_") and not (skip_spec and k == "spec")}
    values += list(_public_values(public))
    values += list(_public_values(env.unwrapped.nominal_model))
    return values


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_true_parameters_are_hidden(env_id):
    secret = _SECRET[env_id]
    env = gym.make(env_id, true_params=secret)
    # Gymnasium records make()'s own arguments in env.spec.kwargs: the caller's overrides are
    # the caller's to see; everything else must not show them.
    values = _visible_values(env, skip_spec=True)
    for name, v in secret.items():
        assert not np.any(np.isclose(values, v, rtol=1e-6, atol=0)), name
    # ... while the oracle, asked for explicitly, has them
    oracle = gp_envs.oracle_model(env)
    for name, v in secret.items():
        assert oracle.params[name] == pytest.approx(v)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_randomized_truth_is_hidden_everywhere(env_id):
    env = gym.make(env_id, randomize=0.1)
    values = _visible_values(env, skip_spec=False)
    truth = gp_envs.oracle_model(env).params
    for name in secret_names(env_id):
        assert not np.any(np.isclose(values, truth[name], rtol=1e-9, atol=0)), name


def secret_names(env_id):
    return list(_SECRET[env_id])


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_overridden_and_randomized_truth_never_reaches_the_controller_api(env_id):
    """With ``true_params`` and ``randomize`` together, over several episodes: no true value of
    the episode is in an observation, ``info``, a reward, a public attribute (``spec`` and the
    class's public scenario table included: the randomized truth is in neither), and the nominal
    model is not the truth."""
    env = gym.make(env_id, true_params=_SECRET[env_id], randomize=0.05)
    table = list(_public_values(type(env.unwrapped).SCENARIOS))
    for seed in range(3):
        values = _visible_values(env, skip_spec=False, seed=seed) + table
        truth = gp_envs.oracle_model(env)
        nominal = env.unwrapped.nominal_model
        assert nominal is not truth
        for name, v in truth.params.items():
            if name == "g":  # never randomized, and the same in the nominal model by design
                continue
            assert not np.any(np.isclose(values, v, rtol=1e-9, atol=0)), (seed, name)
            assert nominal.params[name] != v, (seed, name)
        # the episode's truth really is drawn around the overrides
        for name, v in _SECRET[env_id].items():
            assert truth.params[name] != v and abs(truth.params[name] / v - 1) <= 0.05


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_what_the_controller_gets_does_not_depend_on_the_truth(env_id):
    """Two envs that differ only in their true parameters, from the same state: the same nominal
    model, spaces, ``info``, frame and reward; only the next state shows the different truth."""
    kwargs = dict(randomize=0.1, render_mode="rgb_array")  # same RNG use for the nominal draws
    envs = [gym.make(env_id, **kwargs), gym.make(env_id, true_params=_SECRET[env_id], **kwargs)]
    state = np.asarray(envs[0].reset(seed=0)[0], float)
    resets = [env.reset(seed=4, options={"state": state}) for env in envs]
    a, b = (env.unwrapped for env in envs)
    assert dict(gp_envs.oracle_model(envs[0]).params) != dict(gp_envs.oracle_model(envs[1]).params)
    assert dict(a.nominal_model.params) == dict(b.nominal_model.params)
    for key in ("goal", "Q", "R", "Qf", "u_ref", "goal_tolerance"):
        np.testing.assert_array_equal(getattr(a.nominal_model.task, key),
                                      getattr(b.nominal_model.task, key))
    assert a.action_space == b.action_space and a.observation_space == b.observation_space
    np.testing.assert_array_equal(resets[0][0], resets[1][0])
    assert resets[0][1] == resets[1][1]
    np.testing.assert_array_equal(envs[0].render(), envs[1].render())
    action = ((a.action_space.low + a.action_space.high) / 2).astype(np.float32)
    steps = [env.step(action) for env in envs]
    assert steps[0][1] == steps[1][1]  # reward: from the observed state, the nominal task, u
    assert not np.array_equal(steps[0][0], steps[1][0])  # the dynamics are the true ones
    for env in envs:
        env.close()


def test_oracle_model_rejects_other_envs():
    with pytest.raises(TypeError):
        gp_envs.oracle_model(gym.make("CartPole-v1"))


def test_randomized_truth_differs_per_reset_but_is_seeded():
    env = gym.make("gp_envs/CartPoleSwingUp-v0", randomize=0.2)
    env.reset(seed=1)
    a = gp_envs.oracle_model(env).params["mc"]
    env.reset(seed=2)
    b = gp_envs.oracle_model(env).params["mc"]
    env.reset(seed=1)
    c = gp_envs.oracle_model(env).params["mc"]
    assert a != b and a == c and 0.8 <= a <= 1.2


def test_dubins_nominal_drawn_per_episode_from_the_papers_distribution():
    env = gym.make("gp_envs/DubinsObstacle-v0")
    draws = []
    for seed in range(400):
        env.reset(seed=seed)
        draws.append(env.unwrapped.nominal_model.params["b1"])
    draws = np.array(draws)
    assert draws.max() <= 0.9
    assert abs(np.median(draws) - 0.3) < 0.06
    assert 0.22 < np.std(draws) < 0.34
    assert gp_envs.oracle_model(env).params["b1"] == 0.3


# ------------------------------------------------------------------------ model API
@pytest.mark.parametrize("env_id", ENV_IDS)
def test_nominal_model_numeric_symbolic_and_batch_agree(env_id):
    model = make(env_id).unwrapped.nominal_model
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (7, model.n_states))
    U = rng.uniform(model.u_lb, model.u_ub, (7, model.n_controls))
    batch = model.f(X, U)
    xs, us = ca.SX.sym("x", model.n_states), ca.SX.sym("u", model.n_controls)
    sym = ca.Function("f", [xs, us], [model.f(xs, us)])
    for i in range(7):
        np.testing.assert_allclose(batch[i], model.f(X[i], U[i]), rtol=1e-12)
        np.testing.assert_allclose(np.asarray(sym(X[i], U[i])).ravel(), batch[i], rtol=1e-12)
    with pytest.raises(ValueError):
        model.f(X[:, :-1], U)


# ------------------------------------------------------------------------ task semantics
def test_leaving_the_track_never_pays():
    env = gym.make("gp_envs/CartPoleSwingUp-v0")
    env.reset(seed=0)
    ret_crash, done = 0.0, False
    while not done:
        _, r, te, tr, info = env.step(np.array([35.0], np.float32))
        ret_crash += r
        done = te or tr
    assert te and info["termination_reason"].startswith("left the state box")
    env.reset(seed=0)
    ret_idle, done = 0.0, False
    while not done:
        _, r, te, tr, _ = env.step(np.array([0.0], np.float32))
        ret_idle += r
        done = te or tr
    assert tr and not te
    assert ret_crash < ret_idle


def test_dubins_obstacle_contact_terminates_as_violation():
    env = gym.make("gp_envs/DubinsObstacle-v0")
    env.reset(seed=0)
    done, info = False, {}
    while not done:  # straight at the goal goes through the obstacle
        _, _, te, tr, info = env.step(np.array([2.0, 0.0], np.float32))
        done = te or tr
    assert te and info["constraint_violation"] and info["violation"] == "obstacle contact"
    assert info["clearance"] < 0


def test_success_requires_holding_the_goal():
    env = gym.make("gp_envs/Quadrotor-v0")
    model = env.unwrapped.nominal_model
    goal = model.task.goal.copy()
    env.reset(seed=0, options={"state": goal})
    hover = np.full(4, gp_envs.oracle_model(env).params["m"] * 9.81 / 4, np.float32)
    successes = []
    for _ in range(25):
        *_, info = env.step(hover)
        successes.append(info["success"])
    hold = round(model.task.hold_time / model.dt)
    assert not any(successes[: hold - 1]) and all(successes[hold:])


# ------------------------------------------------------------------ time-varying truth, noise
TIME_VARYING = [("gp_envs/CartPoleSwingUp-v0", "online-wear"),
                ("gp_envs/Quadrotor-v0", "online-payload"),
                ("gp_envs/DubinsObstacle-v0", "paper-wear")]


def _hold_action(env):
    """A constant action that keeps each system inside its box for a while (hover thrust for
    the quadrotor, slow straight driving away from the obstacle for the Dubins vehicle)."""
    model = env.unwrapped.nominal_model
    return np.asarray(model.task.u_ref if model.name != "dubins" else [0.2, 0.0], np.float32)


@pytest.mark.parametrize(("env_id", "scenario"), TIME_VARYING)
def test_time_varying_truth_changes_at_its_time_relative_to_the_episode_draw(env_id, scenario):
    """The plant is the episode's (randomized) truth until the change time and the truth times
    the change's factors from the period starting at that time: checked against a piecewise
    simulation with the oracle's models, step by step."""
    env = gym.make(env_id, scenario=scenario, randomize=0.1)
    env.reset(seed=3, options={"state": env.unwrapped.nominal_model.task.goal})
    base = env.unwrapped
    initial = dict(gp_envs.oracle_model(env).params)
    changes = base.SCENARIOS[scenario].changes
    x, u = base._state.copy(), _hold_action(env)
    for k in range(round(changes[-1].time / base.DT) + 2):
        t = k * base.DT
        expected = dict(initial)
        for change in changes:
            if change.time <= t + 1e-9:
                expected.update({n: initial[n] * f for n, f in change.factors.items()})
        truth = gp_envs.oracle_model(env)
        assert dict(truth.params) == pytest.approx(expected), t
        x = truth.step(x, u.astype(float))
        env.step(u)
        np.testing.assert_allclose(base._state, x, rtol=0, atol=1e-12)


@pytest.mark.parametrize(("env_id", "scenario"), TIME_VARYING)
def test_time_varying_truth_is_hidden(env_id, scenario):
    env = gym.make(env_id, scenario=scenario, randomize=0.1)  # no round values to collide
    obs, info = env.reset(seed=0)
    values = list(_public_values(obs)) + list(_public_values(info))
    for _ in range(round(env.unwrapped.SCENARIOS[scenario].changes[-1].time
                         / env.unwrapped.DT) + 3):
        obs, r, term, trunc, info = env.step(_hold_action(env))
        values += list(_public_values(obs)) + list(_public_values(info)) + [r]
        if term or trunc:
            break
    values += list(_public_values(env.unwrapped.nominal_model))
    changed = {k: v for k, v in gp_envs.oracle_model(env).params.items()
               if k != "g"}
    assert changed  # the truth did change
    for name, v in changed.items():
        assert not np.any(np.isclose(values, v, rtol=1e-9, atol=0)), name


def test_a_change_outside_the_valid_range_fails_at_construction():
    from gp_envs.base import ParamChange, Scenario
    from gp_envs.dubins_obstacle import DubinsObstacleEnv

    paper = DubinsObstacleEnv.SCENARIOS["paper"]

    def env_with(*changes):
        class Custom(DubinsObstacleEnv):
            SCENARIOS: ClassVar[dict[str, Scenario]] = {"x": Scenario(
                "custom", paper.true, paper.nominal, paper.u_lb, paper.u_ub,
                changes=changes)}
            DEFAULT_SCENARIO = "x"
        return Custom()

    with pytest.raises(ValueError, match=r"after the scenario's change at 5.0 s.*b1"):
        env_with(ParamChange(5.0, {"b1": 4.0}))  # b1 = 1.2: the vehicle would drive backwards
    with pytest.raises(ValueError, match="time order within"):
        env_with(ParamChange(20.0, {"b1": 1.1}))
    with pytest.raises(ValueError, match="time order within"):
        env_with(ParamChange(6.0, {"b1": 1.1}), ParamChange(5.0, {"b1": 1.2}))
    with pytest.raises(ValueError, match="unknown parameter"):
        env_with(ParamChange(5.0, {"mass": 1.1}))
    # paper-wear doubles b = 0.3; with randomize 0.7 a draw of 0.51 would double to 1.02
    with pytest.raises(ValueError, match=r"randomize=0\.7"):
        gym.make("gp_envs/DubinsObstacle-v0", scenario="paper-wear", randomize=0.7)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_observation_noise_is_seeded_zero_mean_with_the_stated_spread(env_id):
    sd = 0.01
    noisy = gym.make(env_id, observation_noise=sd)
    exact = gym.make(env_id)
    obs_n, _ = noisy.reset(seed=5)
    exact.reset(seed=5)
    # the noise has its own stream: the initial (true) state of a seed is the same
    np.testing.assert_array_equal(noisy.unwrapped._state, exact.unwrapped._state)
    errors, rewards_n, rewards_e = [], [], []
    u = _hold_action(exact)
    for _ in range(40):
        truth = exact.unwrapped._observe(exact.unwrapped._state)
        e = obs_n.astype(float) - truth
        angles = list(exact.unwrapped.ANGLE_INDICES)
        e[angles] = np.arctan2(np.sin(e[angles]), np.cos(e[angles]))
        errors.append(e)
        obs_n, r_n, _, _, info_n = noisy.step(u)
        _, r_e, term_e, _, info_e = exact.step(u)
        rewards_n.append(r_n)
        rewards_e.append(r_e)
        assert info_n == info_e  # info and reward are about the true state
        if term_e:
            break
    assert rewards_n == rewards_e
    errors = np.array(errors)
    n = errors.size
    assert abs(errors.mean()) < 4 * sd / np.sqrt(n)
    assert errors.std() == pytest.approx(sd, rel=6 / np.sqrt(n) + 0.05)
    again = gym.make(env_id, observation_noise=sd)
    assert np.array_equal(again.reset(seed=5)[0], noisy.reset(seed=5)[0])
    assert not np.array_equal(again.reset(seed=6)[0], noisy.reset(seed=5)[0])


@pytest.mark.parametrize("noise", [-0.1, np.nan, np.inf, "0.1", [0.1, 0.2, 0.3, 0.4, 0.5]])
def test_invalid_observation_noise_is_refused(noise):
    with pytest.raises(ValueError, match="observation_noise"):
        gym.make("gp_envs/CartPoleSwingUp-v0", observation_noise=noise)


def test_noisy_env_copies_continue_the_same_noise_stream():
    env = gym.make("gp_envs/Quadrotor-v0", observation_noise=[0.01] * 12)
    env.reset(seed=1)
    twin = copy.deepcopy(env)
    u = _hold_action(env)
    np.testing.assert_array_equal(env.step(u)[0], twin.step(u)[0])
